#version 450 core
// Steep routing, pointer jumping: p <- p(p). Sets u_changed when a pointer
// moved on (a pointer that reached a terminal or the void stays), so the
// passes end when every chain has reached its end. A texel in a tile the
// receiver pass did not stamp points at itself (the pointers there may be
// stale when only the stamped tiles are drawn). Mirrors
// CpuStabilizer::route.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;
layout(std430, binding = SNOW_STABILIZE_JUMP_CHANGED) buffer JumpChanged {
  uint u_changed;  // cleared to 0 before the pass
};
layout(location = 0) out uint o_pointer;
layout(binding = SNOW_STABILIZE_TILE_ROUTED, r32i) uniform readonly iimage2D u_routed;
uniform int u_since;  // stamp of the receiver pass: tiles with a routed texel
uniform int u_tile;   // texels per tile side

void main() {
  uint p = texelFetch(u_pointer, ivec3(ivec2(gl_FragCoord.xy), u_layer), 0).r;
  if (p != kPointerVoid) {
    ivec3 t = texel_of_index(p);
    uint q = imageLoad(u_routed, t.xy / u_tile).r >= u_since ? texelFetch(u_pointer, t, 0).r : p;
    if (q != p) u_changed = 1u;
    p = q;
  }
  o_pointer = p;
}
