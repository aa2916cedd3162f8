// Live preview snow surface (src/live/snow_view.cpp): one vertex per map
// layer texel (gl_VertexID = the maps' index(l, i, j)), lifted to the snow
// surface ground + depth read from the stabilizer's depth texture; the index
// buffer joins texel centres of one layer into quads where all four have a
// surface at similar heights, at the level of detail of their chunk, whose
// border edges hang skirts (walls down to vertices with ids past the
// texels') over the cracks between levels. Bare vertices sink a hair under
// their ground, so snow edges taper into it.
#version 430 core
#include "live_bindings.h"

layout(binding = SNOW_LIVE_GROUND) uniform sampler2DArray u_ground;
layout(binding = SNOW_LIVE_DEPTH) uniform sampler2DArray u_depth;
layout(binding = SNOW_LIVE_COVERAGE) uniform sampler2DArray u_coverage;

uniform mat4 u_view_projection;
uniform ivec2 u_size;        // map texels (width, height)
uniform vec2 u_origin;       // world (x, z) of texel (0, 0)'s corner, metres
uniform float u_texel;       // metres
uniform float u_min_depth;   // metres: thinner snow is bare
uniform float u_lift;        // metres drawn above (snow) or below (bare) the surface
uniform int u_overlay;       // 0 snow, 1 coverage, 2 depth
uniform int u_texels;        // layer texels; an id of (level + 1) x u_texels + k is a skirt
                             // vertex of texel k at that level of detail
uniform float u_skirt_drop;  // metres a level-0 skirt vertex hangs below its texel's; x 2 per level

out vec3 v_position;
out float v_snow;   // 1 on snowy vertices (or every vertex with an overlay)
out float v_value;  // overlay value: coverage, or depth in metres

void main() {
  int per_layer = u_size.x * u_size.y;
  int id = gl_VertexID;
  float drop = 0.0;
  if (id >= u_texels) {
    int level = id / u_texels - 1;
    id -= (level + 1) * u_texels;
    drop = u_skirt_drop * float(1 << level);
  }
  int l = id / per_layer;
  int r = id - l * per_layer;
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
  v_position = vec3(xz.x, height - drop, xz.y);
  gl_Position = u_view_projection * vec4(v_position, 1.0);
}
