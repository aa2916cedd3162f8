#version 450 core
// Stabilizer active tiles: lists the tiles (u_tile x u_tile columns, all
// layers) the next pass must compute, for an instanced indirect draw of tile
// quads (stabilize_tile.vert). A tile is active when any tile within u_reach
// tiles changed (u_changed >= u_since: a pass at or after the last pass whose
// results the skipped tiles would repeat), or with u_all. The list order
// varies (atomics); each fragment writes only its own texel, so it does not
// matter. See "Active tiles" in src/snow/stabilize.cpp.
#include "bindings.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform readonly iimage2D u_changed;
layout(std430, binding = SNOW_STABILIZE_TILE_LIST) buffer TileList {
  uint command[4];  // glDrawArraysIndirect: count (6), instance count, first, base instance
  uint tiles[];     // x | y << 16
};

uniform ivec2 u_tiles;  // tiles per row, per column
uniform int u_reach;    // tiles
uniform int u_since;    // pass index
uniform int u_all;      // 1: every tile

void main() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(t, u_tiles))) return;
  bool on = u_all != 0;
  ivec2 lo = max(t - u_reach, ivec2(0)), hi = min(t + u_reach, u_tiles - 1);
  for (int y = lo.y; y <= hi.y && !on; ++y) {
    for (int x = lo.x; x <= hi.x; ++x) {
      if (imageLoad(u_changed, ivec2(x, y)).r >= u_since) {
        on = true;
        break;
      }
    }
  }
  if (on) tiles[atomicAdd(command[1], 1u)] = uint(t.x) | (uint(t.y) << 16);
}
