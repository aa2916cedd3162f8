// Live preview snow surface (src/live/snow_view.cpp): one vertex per map
// layer texel (gl_VertexID = the maps' index(l, i, j)), lifted to the snow
// surface ground + depth read from the stabilizer's depth texture; the index
// buffer joins texel centres of one layer into quads where all four have a
// surface at similar heights. Bare vertices sink a hair under their ground,
// so snow edges taper into it.
#version 430 core
#include "live_bindings.h"

layout(binding = SNOW_LIVE_GROUND) uniform sampler2DArray u_ground;
layout(binding = SNOW_LIVE_DEPTH) uniform sampler2DArray u_depth;
layout(binding = SNOW_LIVE_COVERAGE) uniform sampler2DArray u_coverage;

uniform mat4 u_view_projection;
uniform ivec2 u_size;     // map texels (width, height)
uniform vec2 u_origin;    // world (x, z) of texel (0, 0)'s corner, metres
uniform float u_texel;    // metres
uniform float u_min_depth;  // metres: thinner snow is bare
uniform float u_lift;     // metres drawn above (snow) or below (bare) the surface
uniform int u_overlay;    // 0 snow, 1 coverage, 2 depth

out vec3 v_position;
out float v_snow;   // 1 on snowy vertices (or every vertex with an overlay)
out float v_value;  // overlay value: coverage, or depth in metres

void main() {
  int per_layer = u_size.x * u_size.y;
  int l = gl_VertexID / per_layer;
  int r = gl_VertexID - l * per_layer;
  int j = r / u_size.x;
  int i = r - j * u_size.x;
  ivec3 t = ivec3(i, j, l);
  float ground = texelFetch(u_ground, t, 0).r;
  float depth = max(texelFetch(u_depth, t, 0).r, 0.0);
  float height;
  if (u_overlay != 0) {
    height = ground + depth + u_lift;
    v_snow = 1.0;
    v_value = u_overlay == 1 ? texelFetch(u_coverage, t, 0).r : depth;
  } else {
    bool snowy = depth > u_min_depth;
    height = snowy ? ground + depth + u_lift : ground - u_lift;
    v_snow = snowy ? 1.0 : 0.0;
    v_value = depth;
  }
  vec2 xz = u_origin + (vec2(i, j) + 0.5) * u_texel;
  v_position = vec3(xz.x, height, xz.y);
  gl_Position = u_view_projection * vec4(v_position, 1.0);
}
