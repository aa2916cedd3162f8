#version 450 core
// Routing, erosion pass: the highest snow surface each texel can keep,
// H = max(ground + held, min(H, min over neighbours of H(landing) + distance *
// tan(repose))); the void as a neighbour keeps only what cohesion holds. H
// starts at min(ground + depth, ceiling, ground + holding depth)
// (kept_height with u_start, the first pass),
// and that first pass also stamps, one below u_pass, the tiles where the
// start is below ground + depth (snow pressed out under a ceiling, or deeper
// than its holding depth): with
// those, the stamps of the routing's passes cover every texel it moves (the
// receiver pass draws only their tiles).
// Mirrors the erosion loop of CpuStabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(location = 0) out float o_stable;
layout(location = 1) out float o_stable_copy;  // the first pass fills both ping-pong textures
// Active tiles: the tile of a texel that changed is stamped with u_pass (the
// largest stamp wins: pressed snow stamps one below).
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform iimage2D u_changed;
uniform int u_pass;  // index stamped on changed tiles
uniform int u_tile;  // texels per tile side

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  vec4 cell = texelFetch(u_cells, t, 0);
  float s = texelFetch(u_depth, t, 0).r;
  float he = free_top(cell, s);
  float before = kept_height(t, cell);
  float hs = before;
  // What cohesion holds is kept whatever the neighbours keep.
  float floor_h = cell.x + held(t, cell, s);
  if ((int(cell.w) & kCellSurface) != 0 && hs > floor_h) {
    for (int n = 0; n < 8; ++n) {
      vec4 land_cell;
      float land_top;
      int land_l = landing(c + kDir[n], he, cell.x, true, land_cell, land_top);
      if (land_l == kLandVoid) {
        hs = floor_h;
      } else if (land_l >= 0) {
        precise float reach = land_top + dir_distance(n) * cell.z;  // not fused, as the CPU
        hs = min(hs, reach);
      }
    }
    hs = max(hs, floor_h);
  }
  if (hs != before) {  // as stabilize_erode_check.frag compares
    imageAtomicMax(u_changed, c / u_tile, u_pass);
  } else if (u_start != 0 && cell.x + s > before) {
    imageAtomicMax(u_changed, c / u_tile, u_pass - 1);
  }
  o_stable = hs;
  o_stable_copy = hs;
}
