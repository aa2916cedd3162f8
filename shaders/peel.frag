#version 450 core
// One depth-peeling pass: keeps the highest surface more than merge_distance
// below the previous layer's surface at this texel (the depth test picks the
// highest of those). Every triangle counts, whatever its winding.
#include "bindings.h"

layout(binding = SNOW_PEEL_PREV_TEXTURE) uniform sampler2D prev_surface;  // x = height
layout(std430, binding = SNOW_PEEL_TRIANGLES) readonly buffer Triangles {
  vec4 triangles[];  // xyz unit normal as wound, w object index (int bits)
};

uniform int first_layer;       // 1: no previous layer
uniform float merge_distance;  // metres

in float v_height;

layout(location = 0) out vec4 out_surface;  // (height, normal.xyz)
layout(location = 1) out int out_object;

void main() {
  if (first_layer == 0) {
    float prev = texelFetch(prev_surface, ivec2(gl_FragCoord.xy), 0).x;
    if (!(v_height < prev - merge_distance)) discard;
  }
  vec4 t = triangles[gl_PrimitiveID];
  out_surface = vec4(v_height, t.xyz);
  out_object = floatBitsToInt(t.w);
}
