#version 450 core
// Convergence check: per block of u_block x u_block columns (all layers), the
// largest move of the last outflow pass (sum of a texel's 8 amounts, summed
// in direction order as the reference does), the sums of depth and lost, and
// the sum of out_a.r (after routing: the snow scattered to terminals).
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_out_a;
layout(binding = SNOW_STABILIZE_OUT_B) uniform sampler2DArray u_out_b;
uniform int u_block;       // columns per block side
uniform int u_with_moves;  // 0: the outflow textures hold no pass (moves read as 0)

layout(location = 0) out vec4 o_block;  // max move, sum depth, sum lost, sum out_a.r (m)

void main() {
  ivec2 b = ivec2(gl_FragCoord.xy) * u_block;
  float largest = 0.0, depth = 0.0, lost = 0.0, scattered = 0.0;
  for (int y = 0; y < u_block; ++y) {
    for (int x = 0; x < u_block; ++x) {
      ivec2 c = b + ivec2(x, y);
      if (!in_map(c)) continue;
      for (int l = 0; l < u_layers; ++l) {
        ivec3 t = ivec3(c, l);
        vec2 d = texelFetch(u_depth, t, 0).rg;
        depth += d.r;
        lost += d.g;
        vec4 a = texelFetch(u_out_a, t, 0);
        scattered += a.x;
        if (u_with_moves != 0) {
          vec4 o = texelFetch(u_out_b, t, 0);
          float sum = 0.0;
          sum += a.x;
          sum += a.y;
          sum += a.z;
          sum += a.w;
          sum += o.x;
          sum += o.y;
          sum += o.z;
          sum += o.w;
          largest = max(largest, sum);
        }
      }
    }
  }
  o_block = vec4(largest, depth, lost, scattered);
}
