#version 450 core
// Routing, apply: routed texels give up their excess (to the void: lost),
// terminals receive the scattered sums. Mirrors reference::Stabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;
layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_arrive;  // r: scattered sums

layout(location = 0) out vec2 o_depth;
// Active tiles: the tile of a texel that changed is stamped with u_pass.
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform writeonly iimage2D u_changed;
uniform int u_pass;  // index stamped on changed tiles
uniform int u_tile;  // texels per tile side

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  uint p = texelFetch(u_pointer, t, 0).r;
  vec2 d = texelFetch(u_depth, t, 0).rg;
  float s = d.r;
  float lost = d.g;
  if (p != texel_index(c, u_layer)) {
    float e = (texelFetch(u_cells, t, 0).x + s) - texelFetch(u_stable, t, 0).r;
    if (p == kPointerVoid) lost = lost + e;
    s = s - e;
  }
  vec2 o = vec2(s + texelFetch(u_arrive, t, 0).r, lost);
  if (any(notEqual(floatBitsToUint(o), floatBitsToUint(d)))) {
    imageStore(u_changed, c / u_tile, ivec4(u_pass));
  }
  o_depth = o;
}
