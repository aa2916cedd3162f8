#version 450 core
// Adds snow: depth += add on texels with a surface where add > 0
// (CpuStabilizer::add_snow; the product amount * scale is made on the
// CPU so both sides add the same float).
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_ADD) uniform sampler2DArray u_add;
layout(location = 0) out vec2 o_depth;

void main() {
  ivec3 t = ivec3(ivec2(gl_FragCoord.xy), u_layer);
  vec2 d = texelFetch(u_depth, t, 0).rg;
  float add = texelFetch(u_add, t, 0).r;
  if ((int(texelFetch(u_cells, t, 0).w) & kCellSurface) != 0 && add > 0.0) d.r = d.r + add;
  o_depth = d;
}
