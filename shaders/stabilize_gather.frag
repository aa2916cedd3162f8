#version 450 core
// Stabilizer gather pass: depth minus what this texel sent, plus what its
// neighbours sent here, read from the outflow pass's own textures (the same
// float values leave and arrive). Lost snow is added up at its source.
// Mirrors reference::Stabilizer::gather_pass.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_out_a;
layout(binding = SNOW_STABILIZE_OUT_B) uniform sampler2DArray u_out_b;
layout(binding = SNOW_STABILIZE_CODE) uniform usampler2DArray u_code;

layout(location = 0) out vec2 o_depth;  // depth (m), lost (m)

float amount_of(ivec3 t, int n) {
  return n < 4 ? texelFetch(u_out_a, t, 0)[n] : texelFetch(u_out_b, t, 0)[n - 4];
}

uint code_of(uvec2 packed_codes, int n) { return (packed_codes[n >> 2] >> (8 * (n & 3))) & 0xffu; }

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  ivec3 t = ivec3(c, u_layer);
  vec2 d = texelFetch(u_depth, t, 0).rg;
  float s = d.r;
  float lost = d.g;
  vec4 a = texelFetch(u_out_a, t, 0);
  vec4 b = texelFetch(u_out_b, t, 0);
  uvec2 own = texelFetch(u_code, t, 0).rg;
  for (int n = 0; n < 8; ++n) {
    float amount = n < 4 ? a[n] : b[n - 4];
    s -= amount;
    if (code_of(own, n) == kCodeVoid) lost += amount;
  }
  for (int n = 0; n < 8; ++n) {
    ivec2 m = c - u_stride * kDir[n];
    if (!in_map(m)) continue;
    for (int lm = 0; lm < u_layers; ++lm) {
      uvec2 codes = texelFetch(u_code, ivec3(m, lm), 0).rg;
      if (code_of(codes, n) == uint(u_layer)) s += amount_of(ivec3(m, lm), n);
    }
  }
  o_depth = vec2(s, lost);
}
