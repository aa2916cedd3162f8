#version 450 core
// Snow sums: per block of u_block x u_block columns (the layers with a
// surface; the others hold no snow), the sums of depth and lost, and the sum
// of out_a.r (after routing: the snow scattered to terminals). The largest
// move of a pass comes from the gather pass.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_OUT_A) uniform sampler2DArray u_out_a;
layout(binding = SNOW_STABILIZE_COLUMN) uniform usampler2D u_column;  // surfaces per column
uniform int u_block;  // columns per block side

layout(location = 0) out vec4 o_block;  // sum depth, sum lost, sum out_a.r (m), 0

void main() {
  ivec2 b = ivec2(gl_FragCoord.xy) * u_block;
  float depth = 0.0, lost = 0.0, scattered = 0.0;
  for (int y = 0; y < u_block; ++y) {
    for (int x = 0; x < u_block; ++x) {
      ivec2 c = b + ivec2(x, y);
      if (!in_map(c)) continue;
      int surfaces = int(texelFetch(u_column, c, 0).r);  // layers are packed
      for (int l = 0; l < surfaces; ++l) {
        ivec3 t = ivec3(c, l);
        vec2 d = texelFetch(u_depth, t, 0).rg;
        depth += d.r;
        lost += d.g;
        scattered += texelFetch(u_out_a, t, 0).r;
      }
    }
  }
  o_block = vec4(depth, lost, scattered, 0.0);
}
