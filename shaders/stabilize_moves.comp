#version 450 core
// The largest move of a checked relaxation pass, the largest sum sent into
// the void and the largest move seen, over the tiles that
// stabilize_gather.frag kept them for, as float bits (non-negative floats
// order as their bits) in three uints, which
// the live preview reads back a check later (Stabilizer::set_async_checks).
#include "bindings.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = SNOW_STABILIZE_TILE_MOVES, r32ui) uniform readonly uimage2D u_moves;
layout(binding = SNOW_STABILIZE_TILE_VOID, r32ui) uniform readonly uimage2D u_void;
layout(binding = SNOW_STABILIZE_TILE_SEEN, r32ui) uniform readonly uimage2D u_seen;
layout(std430, binding = SNOW_STABILIZE_MOVES) buffer Moves {
  uint largest[3];  // the move, the move into the void, the move seen; cleared to 0 before
};

uniform ivec2 u_tiles;  // tiles per row, per column

void main() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(t, u_tiles))) return;
  uint m = imageLoad(u_moves, t).r, v = imageLoad(u_void, t).r, s = imageLoad(u_seen, t).r;
  if (m > 0u) atomicMax(largest[0], m);
  if (v > 0u) atomicMax(largest[1], v);
  if (s > 0u) atomicMax(largest[2], s);
}
