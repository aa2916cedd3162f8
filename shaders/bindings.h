// Binding slots and vertex attribute locations shared by C++ and GLSL.
// Included by C++ as "shaders/bindings.h" and by shaders as
// `#include "bindings.h"` (spliced in by snow::gl::Program after #version).
// Plain #defines so that both languages read the same numbers and GLSL 4.30
// can use them in layout() qualifiers. One block per pass; slots only need
// to be unique within a pass.
#ifndef SNOW_SHADERS_BINDINGS_H
#define SNOW_SHADERS_BINDINGS_H

// --- Vertex attributes (every pass drawing scene triangles) ---------------
#define SNOW_ATTR_POSITION 0  // vec3, metres, world space
#define SNOW_ATTR_NORMAL 1    // vec3, world space
#define SNOW_ATTR_UV 2        // vec2, glTF TEXCOORD_0

// --- Preview renderer (preview.vert/.frag) --------------------------------
#define SNOW_PREVIEW_BASE_COLOR_TEXTURE 0  // sampler2D, sRGB baseColor

// --- Depth peeling (peel.vert/.frag, src/snow/peel/gpu.cpp) ----------------
#define SNOW_PEEL_PREV_TEXTURE 0  // usampler2D RG32UI: previous layer (height bits, triangle)

// --- Shadow maps (shadow.vert, shadow_snow.vert, depth_only.frag, coverage/gpu.cpp)
#define SNOW_SHADOW_SNOW_TEXTURE 0  // sampler2DArray RG32F per layer: (ground + depth, depth)

// --- Coverage counting (coverage_*.comp/.glsl, src/snow/coverage/gpu.cpp) --
#define SNOW_COVERAGE_SHADOW_TEXTURE 0  // sampler2DArray DEPTH32F: the batch's shadow maps
#define SNOW_COVERAGE_SNOW_TEXTURE 1    // sampler2DArray RG32F: as SNOW_SHADOW_SNOW_TEXTURE
#define SNOW_COVERAGE_RECEIVERS 0       // SSBO uvec4 per receiver (texel, height, normal)
#define SNOW_COVERAGE_COUNTS 1          // SSBO uint per receiver: lit directions so far
#define SNOW_COVERAGE_QUEUE 2           // SSBO: count, then uvec2 (receiver, uncertain mask)
#define SNOW_COVERAGE_DISPATCH 3        // SSBO uvec4: indirect dispatch size of the exact pass
#define SNOW_COVERAGE_BVH_NODES 4       // SSBO snow::Bvh::Node (32 B) per node
#define SNOW_COVERAGE_BVH_TRIANGLES 5   // SSBO float[9] per triangle, BVH leaf order

// --- Stabilizer (stabilize_*.vert/.geom/.frag, src/snow/stabilize/gpu.cpp) --
// Texture arrays with one layer per map layer, texel (i, j) at (x, y).
#define SNOW_STABILIZE_CELLS 0       // sampler2DArray RGBA32F: ground, ceiling, tan(repose), flags
#define SNOW_STABILIZE_DEPTH 1       // sampler2DArray RG32F: snow depth (m), lost (m)
#define SNOW_STABILIZE_OUT_A 2       // sampler2DArray RGBA32F: outflow (m) to directions 0..3
#define SNOW_STABILIZE_OUT_B 3       // sampler2DArray RGBA32F: outflow (m) to directions 4..7
#define SNOW_STABILIZE_CODE 4        // usampler2DArray RG32UI: landing codes, 8 bits per direction
#define SNOW_STABILIZE_POINTER 5     // usampler2DArray R32UI: routing receiver (texel index)
#define SNOW_STABILIZE_ADD 6         // sampler2DArray RGBA32F: snow to add (m) in r
#define SNOW_STABILIZE_STABLE 7      // sampler2DArray: highest snow surface a texel keeps (m) in r
#define SNOW_STABILIZE_STABLE_OLD 8  // sampler2DArray: the same from the previous erosion pass
// Active tiles (stabilize_tiles.comp, stabilize_tile.vert): image unit and SSBO slots.
#define SNOW_STABILIZE_TILE_CHANGED 0  // iimage2D R32I per tile: last pass that changed it
// image2DArray RG32F: the depth a column pass writes (stabilize_gather.frag).
#define SNOW_STABILIZE_DEPTH_OUT 1
// uimage2D R32UI per tile: the largest move of a checked pass (float bits).
#define SNOW_STABILIZE_TILE_MOVES 2
// iimage2D R32I per tile, read only: the routing's stamps (a tile with a routed texel has
// one >= u_since; stabilize_jump.frag, stabilize_apply.frag).
#define SNOW_STABILIZE_TILE_ROUTED 3
// uimage2D R32UI per tile: the largest sum a texel sent into the void in a checked pass.
#define SNOW_STABILIZE_TILE_VOID 4
// uimage2D R32UI per tile: the largest move the convergence test sees (all but the snow
// squeezed into full gaps) in a checked pass.
#define SNOW_STABILIZE_TILE_SEEN 6
// SSBO: per layer and for the column passes a draw-indirect command (uint[4]),
// then per layer and for the column passes its tiles.
#define SNOW_STABILIZE_TILE_LIST 0
// SSBO uint: set by a pointer-jumping pass that moved a pointer on (stabilize_jump.frag).
#define SNOW_STABILIZE_JUMP_CHANGED 1
// SSBO uint[2]: a checked pass's largest move and move into the void (stabilize_moves.comp).
#define SNOW_STABILIZE_MOVES 2
// usampler2DArray R32UI per tile and layer: 1 where the layer has a surface in the tile.
#define SNOW_STABILIZE_TILE_LAYERS 9
// usampler2D R8UI per column: its layers with a surface (they are packed from layer 0).
#define SNOW_STABILIZE_COLUMN 10
// sampler2DArray RG32F: per layer texel, the holding depth of its support (m; snow/cohesion.h)
// in r, the held cap (m; what cohesion may hold of the snow that fell there) in g.
#define SNOW_STABILIZE_HOLD 11
// image2DArray RG32F: the same, read and written by the snowfall (stabilize_add.frag).
#define SNOW_STABILIZE_HOLD_IMAGE 5

#endif  // SNOW_SHADERS_BINDINGS_H
