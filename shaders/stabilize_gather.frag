#version 450 core
// Stabilizer gather pass, one fragment per column for all its layers: depth
// minus what each layer texel sent, plus what the neighbours sent to it, read
// from the outflow pass's own textures (the same float values leave and
// arrive). Each neighbour column's codes are read once for all the layers
// here. Lost snow is added up at its source. Mirrors
// CpuStabilizer::gather_column (per target layer: own outflow in
// direction order, then inflow in direction order, source layers upwards).
// Writes the new depth with imageStore and stamps the tiles that changed
// (active tiles, src/snow/stabilize/gpu.cpp). On convergence checks it also
// keeps, per tile, the largest move (sum of a texel's 8 amounts, summed in
// direction order as the CPU does), the largest sum sent into the void and
// the largest move less what went into full gaps (kCodeFull).
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_out_a;
layout(binding = SNOW_STABILIZE_OUT_B) uniform sampler2DArray u_out_b;
layout(binding = SNOW_STABILIZE_CODE) uniform usampler2DArray u_code;
layout(binding = SNOW_STABILIZE_COLUMN) uniform usampler2D u_column;  // surfaces per column

layout(binding = SNOW_STABILIZE_DEPTH_OUT, rg32f) uniform writeonly image2DArray u_depth_out;
// Active tiles: the tile of a column that changed is stamped with u_pass.
layout(binding = SNOW_STABILIZE_TILE_CHANGED, r32i) uniform writeonly iimage2D u_changed;
// Per tile, the largest move (float bits; moves are >= 0), with u_measure.
layout(binding = SNOW_STABILIZE_TILE_MOVES, r32ui) uniform uimage2D u_moves;
layout(binding = SNOW_STABILIZE_TILE_VOID, r32ui) uniform uimage2D u_void_moves;
layout(binding = SNOW_STABILIZE_TILE_SEEN, r32ui) uniform uimage2D u_seen_moves;
uniform int u_pass;     // index stamped on changed tiles
uniform int u_tile;     // texels per tile side
uniform int u_measure;  // 1: keep the largest move in u_moves

const int kMaxLayers = 64;

uint code_of(uvec2 packed_codes, int n) { return (packed_codes[n >> 2] >> (8 * (n & 3))) & 0xffu; }

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  int surfaces = int(texelFetch(u_column, c, 0).r);  // layers are packed
  if (surfaces == 0) return;  // nothing lies or lands here
  float s[kMaxLayers], lost[kMaxLayers];
  vec2 before[kMaxLayers];
  bool changed = false;
  float largest = 0.0, largest_void = 0.0, largest_seen = 0.0;
  for (int l = 0; l < surfaces; ++l) {
    ivec3 t = ivec3(c, l);
    before[l] = texelFetch(u_depth, t, 0).rg;
    vec4 a = texelFetch(u_out_a, t, 0);
    vec4 b = texelFetch(u_out_b, t, 0);
    uvec2 own = texelFetch(u_code, t, 0).rg;
    s[l] = before[l].r;
    lost[l] = before[l].g;
    for (int n = 0; n < 8; ++n) {
      float amount = n < 4 ? a[n] : b[n - 4];
      s[l] -= amount;
      if (code_of(own, n) == kCodeVoid) lost[l] += amount;
    }
    changed = changed || any(notEqual(a, vec4(0.0))) || any(notEqual(b, vec4(0.0)));
    if (u_measure != 0) {
      float move = 0.0, hidden = 0.0, to_void = 0.0;  // summed in direction order
      for (int n = 0; n < 8; ++n) {
        float amount = n < 4 ? a[n] : b[n - 4];
        move += amount;
        uint code = code_of(own, n);
        if (code == kCodeVoid) to_void += amount;
        if (code < kCodeNone && (code & kCodeFull) != 0u) hidden += amount;
      }
      largest = max(largest, move);
      largest_seen = max(largest_seen, move - hidden);
      largest_void = max(largest_void, to_void);
    }
  }
  // Inflow, in direction order as the CPU adds it.
  for (int n = 0; n < 8; ++n) {
    ivec2 m = c - u_stride * kDir[n];
    if (!in_map(m)) continue;
    int from = int(texelFetch(u_column, m, 0).r);
    for (int lm = 0; lm < from; ++lm) {
      ivec3 t = ivec3(m, lm);
      uint code = code_of(texelFetch(u_code, t, 0).rg, n);
      if (code < kCodeNone) code &= ~kCodeFull;
      if (code < uint(surfaces)) {
        s[code] += n < 4 ? texelFetch(u_out_a, t, 0)[n] : texelFetch(u_out_b, t, 0)[n - 4];
      }
    }
  }
  for (int l = 0; l < surfaces; ++l) {
    changed = changed || floatBitsToUint(s[l]) != floatBitsToUint(before[l].r) ||
              floatBitsToUint(lost[l]) != floatBitsToUint(before[l].g);
    imageStore(u_depth_out, ivec3(c, l), vec4(s[l], lost[l], 0.0, 0.0));
  }
  if (changed) imageStore(u_changed, c / u_tile, ivec4(u_pass));
  if (largest > 0.0) imageAtomicMax(u_moves, c / u_tile, floatBitsToUint(largest));
  if (largest_void > 0.0) imageAtomicMax(u_void_moves, c / u_tile, floatBitsToUint(largest_void));
  if (largest_seen > 0.0) imageAtomicMax(u_seen_moves, c / u_tile, floatBitsToUint(largest_seen));
}
