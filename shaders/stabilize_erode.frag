#version 450 core
// Routing, erosion pass: the highest snow surface each texel can keep,
// H = max(ground, min(H, min over neighbours of H(landing) + distance *
// tan(repose))); the void as a neighbour keeps nothing. With u_init, writes
// the start value H = min(ground + depth, ceiling) instead, and stamps the
// tiles where that is below ground + depth (snow pressed out under a
// ceiling): with those, the stamps of the routing's passes cover every
// texel it moves (the receiver pass draws only their tiles).
// Mirrors the erosion loop of reference::Stabilizer::route.
#include "bindings.h"
#include "column.glsl"

uniform int u_init;

layout(location = 0) out float o_stable;
// Active tiles: the tile of a texel that changed is stamped with u_pass.
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform writeonly iimage2D u_changed;
uniform int u_pass;  // index stamped on changed tiles
uniform int u_tile;  // texels per tile side

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  vec4 cell = texelFetch(u_cells, t, 0);
  float s = texelFetch(u_depth, t, 0).r;
  float he = free_top(cell, s);
  if (u_init != 0) {
    if (cell.x + s > he) imageStore(u_changed, c / u_tile, ivec4(u_pass));
    o_stable = he;
    return;
  }
  float hs = texelFetch(u_stable, t, 0).r;
  if ((int(cell.w) & kCellSurface) != 0 && hs > cell.x) {
    for (int n = 0; n < 8; ++n) {
      ivec2 nc = c + kDir[n];
      int land_l = landing(nc, he, cell.x, true);
      if (land_l == kLandVoid) {
        hs = cell.x;
      } else if (land_l >= 0) {
        hs = min(hs, texelFetch(u_stable, ivec3(nc, land_l), 0).r + dir_distance(n) * cell.z);
      }
    }
    hs = max(hs, cell.x);
  }
  if (hs != texelFetch(u_stable, t, 0).r) {  // as stabilize_erode_check.frag compares
    imageStore(u_changed, c / u_tile, ivec4(u_pass));
  }
  o_stable = hs;
}
