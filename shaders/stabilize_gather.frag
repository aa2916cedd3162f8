#version 450 core
// Stabilizer gather pass: depth minus what this texel sent, plus what its
// neighbours sent here, read from the outflow pass's own textures (the same
// float values leave and arrive). Lost snow is added up at its source.
// Mirrors reference::Stabilizer::gather_pass. Stamps the tiles that changed
// (active tiles, src/snow/stabilize.cpp).
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_out_a;
layout(binding = SNOW_STABILIZE_OUT_B) uniform sampler2DArray u_out_b;
layout(binding = SNOW_STABILIZE_CODE) uniform usampler2DArray u_code;
layout(binding = SNOW_STABILIZE_COLUMN) uniform usampler2D u_column;  // surfaces per column

layout(location = 0) out vec2 o_depth;  // depth (m), lost (m)
// Active tiles: the tile of a texel that changed is stamped with u_pass.
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform writeonly iimage2D u_changed;
uniform int u_pass;  // index stamped on changed tiles
uniform int u_tile;  // texels per tile side

uint code_of(uvec2 packed_codes, int n) { return (packed_codes[n >> 2] >> (8 * (n & 3))) & 0xffu; }

// s plus what the neighbour u_stride columns against direction n sent to this
// texel, layer by layer.
float inflow(ivec2 c, const int n, float s) {
  ivec2 m = c - u_stride * kDir[n];
  if (!in_map(m)) return s;
  int surfaces = int(texelFetch(u_column, m, 0).r);  // layers are packed
  for (int lm = 0; lm < surfaces; ++lm) {
    ivec3 t = ivec3(m, lm);
    uint code = (texelFetch(u_code, t, 0)[n >> 2] >> (8 * (n & 3))) & 0xffu;
    if (code == uint(u_layer)) {
      s += n < 4 ? texelFetch(u_out_a, t, 0)[n] : texelFetch(u_out_b, t, 0)[n - 4];
    }
  }
  return s;
}

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  vec2 d = texelFetch(u_depth, t, 0).rg;
  float s = d.r;
  float lost = d.g;
  if ((int(texelFetch(u_cells, t, 0).w) & kCellSurface) == 0) {
    o_depth = d;  // nothing lies or lands here
    return;
  }
  vec4 a = texelFetch(u_out_a, t, 0);
  vec4 b = texelFetch(u_out_b, t, 0);
  uvec2 own = texelFetch(u_code, t, 0).rg;
  for (int n = 0; n < 8; ++n) {
    float amount = n < 4 ? a[n] : b[n - 4];
    s -= amount;
    if (code_of(own, n) == kCodeVoid) lost += amount;
  }
  // Inflow, in direction order as the reference adds it.
  s = inflow(c, 0, s);
  s = inflow(c, 1, s);
  s = inflow(c, 2, s);
  s = inflow(c, 3, s);
  s = inflow(c, 4, s);
  s = inflow(c, 5, s);
  s = inflow(c, 6, s);
  s = inflow(c, 7, s);
  // Changed: it sent snow, or its depth or loss differs (bits) from before.
  if (any(notEqual(a, vec4(0.0))) || any(notEqual(b, vec4(0.0))) ||
      floatBitsToUint(s) != floatBitsToUint(d.r) || floatBitsToUint(lost) != floatBitsToUint(d.g)) {
    imageStore(u_changed, c / u_tile, ivec4(u_pass));
  }
  o_depth = vec2(s, lost);
}
