#version 450 core
// The stabilizer's tiled passes: one point of u_tile pixels per instance,
// covering active tile gl_InstanceID of layer u_layer's list
// (stabilize_tiles.comp). A square point, not two triangles: a rasterizer
// that shades 4x4 blocks would shade the blocks on a quad's diagonal twice.
// The viewport spans whole tiles (u_viewport), so the points of the tiles at
// the map's far edges keep their centres inside it; the scissor keeps the
// fragments on the map.
#include "bindings.h"

layout(std430, binding = SNOW_STABILIZE_TILE_LIST) readonly buffer TileList {
  uint data[];  // see stabilize_tiles.comp
};

uniform ivec2 u_viewport;  // texels, tiles per row and column times u_tile
uniform int u_tile;        // texels per tile side
uniform int u_layers;      // L
uniform int u_layer;       // the layer this draw writes

void main() {
  uint tile_count = uint(u_viewport.x / u_tile) * uint(u_viewport.y / u_tile);
  uint packed_tile =
      data[4u * uint(u_layers + 1) + uint(u_layer) * tile_count + uint(gl_InstanceID)];
  ivec2 t = ivec2(int(packed_tile & 0xffffu), int(packed_tile >> 16));
  vec2 centre = (vec2(t) + 0.5) * float(u_tile);
  gl_Position = vec4(centre / vec2(u_viewport) * 2.0 - 1.0, 0.0, 1.0);
  gl_PointSize = float(u_tile);
}
