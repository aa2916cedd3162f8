#version 450 core
// One depth-peeling pass: keeps the highest surface more than merge_distance
// below the previous layer's surface at this texel (the depth test picks the
// highest of those). Every triangle counts, whatever its winding.
#include "bindings.h"

layout(binding = SNOW_PEEL_PREV_TEXTURE) uniform usampler2D prev_surface;  // x = height bits

uniform int first_layer;       // 1: no previous layer
uniform float merge_distance;  // metres

in float v_height;

// (height bits, triangle index): the CPU looks up the triangle's normal and
// object, which keeps this target at 8 bytes a texel.
layout(location = 0) out uvec2 out_surface;

void main() {
  if (first_layer == 0) {
    float prev = uintBitsToFloat(texelFetch(prev_surface, ivec2(gl_FragCoord.xy), 0).x);
    if (!(v_height < prev - merge_distance)) discard;
  }
  out_surface = uvec2(floatBitsToUint(v_height), uint(gl_PrimitiveID));
}
