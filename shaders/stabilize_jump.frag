#version 450 core
// Steep routing, pointer jumping: p <- p(p). Mirrors reference::Stabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;
layout(location = 0) out uint o_pointer;

void main() {
  uint p = texelFetch(u_pointer, ivec3(ivec2(gl_FragCoord.xy), u_layer), 0).r;
  if (p != kPointerVoid) p = texelFetch(u_pointer, texel_of_index(p), 0).r;
  o_pointer = p;
}
