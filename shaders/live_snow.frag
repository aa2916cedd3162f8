// Live preview snow surface (src/live/snow_view.cpp): the preview's Lambert
// shading (sun plus sky, as preview.frag and snow::render::shade_linear) of
// white snow on the face normal, or a colour ramp of coverage or depth.
#version 430 core

in vec3 v_position;
in float v_snow;
in float v_value;

layout(location = 0) out vec4 o_color;

uniform vec3 u_eye;
uniform vec3 u_forward;
uniform int u_orthographic;
uniform vec3 u_sun_direction;  // unit, towards the sun
uniform vec3 u_sun_radiance;   // linear RGB
uniform vec3 u_sky_ambient;    // linear RGB on an upward surface
uniform vec3 u_snow_color;     // linear albedo
uniform int u_overlay;         // 0 snow, 1 coverage, 2 depth
uniform float u_overlay_max;   // value at the top of the ramp

vec3 srgb_encode(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  vec3 low = c * 12.92;
  vec3 high = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
  return mix(high, low, lessThanEqual(c, vec3(0.0031308)));
}

// Dark blue, cyan, yellow, red over [0, 1] (linear RGB).
vec3 ramp(float x) {
  x = clamp(x, 0.0, 1.0);
  vec3 a = vec3(0.02, 0.03, 0.30), b = vec3(0.0, 0.6, 0.8), c = vec3(0.95, 0.85, 0.1),
       d = vec3(0.8, 0.05, 0.02);
  if (x < 1.0 / 3.0) return mix(a, b, x * 3.0);
  if (x < 2.0 / 3.0) return mix(b, c, x * 3.0 - 1.0);
  return mix(c, d, x * 3.0 - 2.0);
}

void main() {
  if (v_snow < 0.5) discard;
  vec3 to_eye = u_orthographic != 0 ? -u_forward : normalize(u_eye - v_position);
  vec3 n = cross(dFdx(v_position), dFdy(v_position));
  if (dot(n, n) < 1e-20) n = vec3(0.0, 1.0, 0.0);
  n = normalize(n);
  if (dot(n, to_eye) < 0.0) n = -n;
  vec3 albedo = u_overlay == 0 ? u_snow_color : ramp(v_value / max(u_overlay_max, 1e-6));
  vec3 light = u_sun_radiance * max(dot(n, u_sun_direction), 0.0) +
               u_sky_ambient * (0.65 + 0.35 * n.y);
  o_color = vec4(srgb_encode(albedo * light), 1.0);
}
