#version 450 core
// Routing, apply: routed texels give up their excess (to the void: lost),
// terminals receive the scattered sums. Mirrors CpuStabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;
// A texel without a surface, or in a tile with no routed texel, points at
// itself (the receiver pass may have left its pointer unwritten).
layout(binding = SNOW_STABILIZE_TILE_ROUTED, r32i) uniform readonly iimage2D u_routed;
uniform int u_since;  // stamp of the receiver pass
layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_arrive;  // r: scattered sums
// 0: the terminals' sums are poured as piles afterwards (snow/deposit.h).
uniform int u_add_arrive;

layout(location = 0) out vec2 o_depth;
// Active tiles: the tile of a texel that changed is stamped with u_pass.
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform writeonly iimage2D u_changed;
uniform int u_pass;  // index stamped on changed tiles
uniform int u_tile;  // texels per tile side

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  vec4 cell = texelFetch(u_cells, t, 0);
  uint self_index = texel_index(c, u_layer);
  uint p = (int(cell.w) & kCellSurface) != 0 && imageLoad(u_routed, c / u_tile).r >= u_since
               ? texelFetch(u_pointer, t, 0).r
               : self_index;
  vec2 d = texelFetch(u_depth, t, 0).rg;
  float s = d.r;
  float lost = d.g;
  if (p != self_index) {
    float e = min((cell.x + s) - texelFetch(u_stable, t, 0).r, s);  // never more than the snow
    if (p == kPointerVoid) lost = lost + e;
    s = s - e;
  }
  vec2 o = vec2(u_add_arrive != 0 ? s + texelFetch(u_arrive, t, 0).r : s, lost);
  if (any(notEqual(floatBitsToUint(o), floatBitsToUint(d)))) {
    imageStore(u_changed, c / u_tile, ivec4(u_pass));
  }
  o_depth = o;
}
