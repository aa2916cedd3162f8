// Preview renderer (src/render/preview.cpp): Lambert with one sun plus sky
// ambient, base colour factor times the sRGB base colour texture, output
// sRGB-encoded. Keep in step with snow::render::shade_linear().
#version 430 core
#include "bindings.h"

in vec3 v_position;
in vec3 v_normal;
in vec2 v_uv;

layout(location = 0) out vec4 o_color;

layout(binding = SNOW_PREVIEW_BASE_COLOR_TEXTURE) uniform sampler2D u_base_color_texture;
uniform vec4 u_base_color;     // linear RGBA
uniform int u_has_texture;     // 1: multiply by the texture
uniform vec3 u_eye;            // camera position (perspective)
uniform vec3 u_forward;        // camera view direction (orthographic)
uniform int u_orthographic;
uniform vec3 u_sun_direction;  // unit, towards the sun
uniform vec3 u_sun_radiance;   // linear RGB
uniform vec3 u_sky_ambient;    // linear RGB on an upward surface

vec3 srgb_encode(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  vec3 low = c * 12.92;
  vec3 high = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
  return mix(high, low, lessThanEqual(c, vec3(0.0031308)));
}

void main() {
  vec3 to_eye = u_orthographic != 0 ? -u_forward : normalize(u_eye - v_position);
  // Face normal, turned towards the viewer: both sides of every triangle are
  // lit, and shading normals that disagree with it (flipped normals in the
  // asset, back faces) are turned round too.
  vec3 face = cross(dFdx(v_position), dFdy(v_position));
  if (dot(face, to_eye) < 0.0) face = -face;
  vec3 n = v_normal;
  if (dot(n, n) < 1e-12) n = face;
  n = normalize(n);
  if (dot(n, face) < 0.0) n = -n;

  vec3 albedo = u_base_color.rgb;
  if (u_has_texture != 0) albedo *= texture(u_base_color_texture, v_uv).rgb;
  vec3 light = u_sun_radiance * max(dot(n, u_sun_direction), 0.0) +
               u_sky_ambient * (0.65 + 0.35 * n.y);
  o_color = vec4(srgb_encode(albedo * light), 1.0);
}
