#version 450 core
// Routing, receiver pass: a texel holding more than it can keep (ground +
// depth above its kept height H, by more than u_min_excess) points at the neighbour that limits it (the
// one with the smallest H(landing) + distance * tan(repose) among those with
// a lower H), or at the void when one neighbour is the void or that
// neighbour sheds into the void; others point at themselves. H falls
// strictly along pointers, so they form a forest.
// Stamps the tiles of the texels that point elsewhere (the routed ones), so
// the jump and scatter passes can leave out the others.
// Mirrors the receiver loop of CpuStabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(location = 0) out uint o_pointer;
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform writeonly iimage2D u_changed;
uniform int u_pass;  // index stamped on tiles with a routed texel
uniform int u_tile;  // texels per tile side
uniform float u_min_excess;  // metres: less above the kept height is not routed

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  vec4 cell = texelFetch(u_cells, t, 0);
  uint self_index = texel_index(c, u_layer);
  uint p = self_index;
  float s = texelFetch(u_depth, t, 0).r;
  float hs = texelFetch(u_stable, t, 0).r;
  if ((int(cell.w) & kCellSurface) != 0 && cell.x + s > hs + u_min_excess) {
    float he = free_top(cell, s);
    float best = hs;
    ivec3 receiver = t;
    for (int n = 0; n < 8; ++n) {
      ivec2 nc = c + kDir[n];
      int land_l = landing(nc, he, cell.x, true);
      if (land_l == kLandVoid) {
        p = kPointerVoid;
        break;
      }
      if (land_l < 0) continue;
      float hn = texelFetch(u_stable, ivec3(nc, land_l), 0).r;
      precise float via = hn + dir_distance(n) * cell.z;  // no fused multiply-add: as the CPU
      if (hn < hs && (p == self_index || via < best)) {
        best = via;
        p = texel_index(nc, land_l);
        receiver = ivec3(nc, land_l);
      }
    }
    if (p != self_index && p != kPointerVoid) {
      // A receiver that sheds into the void (a neighbour lands in it at the
      // receiver's free top) keeps nothing that arrives: the path ends in
      // the void here.
      vec4 rc = texelFetch(u_cells, receiver, 0);
      float rhe = free_top(rc, texelFetch(u_depth, receiver, 0).r);
      for (int n = 0; n < 8; ++n) {
        if (landing(receiver.xy + kDir[n], rhe, rc.x, true) == kLandVoid) {
          p = kPointerVoid;
          break;
        }
      }
    }
  }
  if (p != self_index) imageStore(u_changed, c / u_tile, ivec4(u_pass));
  o_pointer = p;
}
