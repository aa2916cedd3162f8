#version 450 core
// Steep routing: keeps (for an occlusion query) the texels whose pointer does
// not yet reach a terminal; writes nothing.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  uint p = texelFetch(u_pointer, ivec3(c, u_layer), 0).r;
  if (p == kPointerVoid || p == texel_index(c, u_layer)) discard;
  if (texelFetch(u_pointer, texel_of_index(p), 0).r == p) discard;
}
