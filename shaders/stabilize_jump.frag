#version 450 core
// Steep routing, pointer jumping: p <- p(p). Sets u_changed when a pointer
// moved on (a pointer that reached a terminal or the void stays), so the
// passes end when every chain has reached its end. Mirrors
// reference::Stabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;
layout(std430, binding = SNOW_STABILIZE_JUMP_CHANGED) buffer JumpChanged {
  uint u_changed;  // cleared to 0 before the pass
};
layout(location = 0) out uint o_pointer;

void main() {
  uint p = texelFetch(u_pointer, ivec3(ivec2(gl_FragCoord.xy), u_layer), 0).r;
  if (p != kPointerVoid) {
    uint q = texelFetch(u_pointer, texel_of_index(p), 0).r;
    if (q != p) u_changed = 1u;
    p = q;
  }
  o_pointer = p;
}
