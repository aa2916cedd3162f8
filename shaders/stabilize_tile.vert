#version 450 core
// The stabilizer's tiled passes: one quad (6 vertices) per instance over
// active tile tiles[gl_InstanceID] (stabilize_tiles.comp), clipped to the map.
#include "bindings.h"

layout(std430, binding = SNOW_STABILIZE_TILE_LIST) readonly buffer TileList {
  uint command[4];
  uint tiles[];  // x | y << 16
};

uniform ivec2 u_size;  // map width, height (texels)
uniform int u_tile;    // texels per tile side

const ivec2 kCorner[6] =
    ivec2[6](ivec2(0, 0), ivec2(1, 0), ivec2(0, 1), ivec2(0, 1), ivec2(1, 0), ivec2(1, 1));

void main() {
  uint packed_tile = tiles[gl_InstanceID];
  ivec2 t = ivec2(int(packed_tile & 0xffffu), int(packed_tile >> 16));
  vec2 p = vec2(min((t + kCorner[gl_VertexID]) * u_tile, u_size)) / vec2(u_size);
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
