#version 450 core
// Stabilizer active tiles: lists, per layer, the tiles (u_tile x u_tile
// columns) the next pass must compute, for one instanced indirect draw of
// tile quads per layer (stabilize_tile.vert). A tile is active when any tile
// within u_reach tiles changed (u_changed >= u_since: a pass at or after the
// last pass whose results the skipped tiles would repeat), or with u_all; an
// active tile is listed for the layers that have a surface in it, and in a
// last list (index u_layers) for the passes that draw each column once for
// all its layers when any has. The list order varies (atomics); each
// fragment writes only its own texel or column, so it does not matter. See
// "Active tiles" in src/snow/stabilize/gpu.cpp.
//
// One invocation per block of kBlock x kBlock tiles: a block with no change
// within reach of any of its tiles (most of them, late in a relaxation) ends
// after one look at that window. An invocation per tile would pay for itself
// and its (2 u_reach + 1)^2 loads on every tile of the map, however few are
// active.
#include "bindings.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform readonly iimage2D u_changed;
layout(binding = SNOW_STABILIZE_TILE_LAYERS) uniform usampler2DArray u_tile_layers;
layout(std430, binding = SNOW_STABILIZE_TILE_LIST) buffer TileList {
  uint data[];  // u_layers + 1 draw-indirect commands (count 1, instance count, first, base
                // instance), then u_layers + 1 lists of u_tiles.x * u_tiles.y tiles (x | y << 16)
};

uniform ivec2 u_tiles;  // tiles per row, per column
uniform int u_layers;   // L
uniform int u_reach;    // tiles
uniform int u_since;    // pass index
uniform int u_all;      // 1: every tile

const int kBlock = 8;  // tiles per block side

// Whether a tile in the rectangle lo..hi (inclusive, clamped to the map)
// changed since u_since.
bool changed_in(ivec2 lo, ivec2 hi) {
  lo = max(lo, ivec2(0));
  hi = min(hi, u_tiles - 1);
  for (int y = lo.y; y <= hi.y; ++y) {
    for (int x = lo.x; x <= hi.x; ++x) {
      if (imageLoad(u_changed, ivec2(x, y)).r >= u_since) return true;
    }
  }
  return false;
}

void list_tile(ivec2 t) {
  uint tile_count = uint(u_tiles.x * u_tiles.y);
  uint lists = uint(u_layers + 1);
  bool any_surface = false;
  for (int l = 0; l < u_layers; ++l) {
    if (texelFetch(u_tile_layers, ivec3(t, l), 0).r == 0u) continue;
    any_surface = true;
    uint slot = atomicAdd(data[4 * l + 1], 1u);
    data[4u * lists + uint(l) * tile_count + slot] = uint(t.x) | (uint(t.y) << 16);
  }
  if (any_surface) {  // the column passes' list
    uint slot = atomicAdd(data[4 * u_layers + 1], 1u);
    data[4u * lists + uint(u_layers) * tile_count + slot] = uint(t.x) | (uint(t.y) << 16);
  }
}

void main() {
  ivec2 b = ivec2(gl_GlobalInvocationID.xy) * kBlock;
  if (any(greaterThanEqual(b, u_tiles))) return;
  ivec2 b_hi = min(b + kBlock, u_tiles) - 1;
  bool all = u_all != 0;
  if (!all && !changed_in(b - u_reach, b_hi + u_reach)) return;
  for (int y = b.y; y <= b_hi.y; ++y) {
    for (int x = b.x; x <= b_hi.x; ++x) {
      ivec2 t = ivec2(x, y);
      if (all || changed_in(t - u_reach, t + u_reach)) list_tile(t);
    }
  }
}
