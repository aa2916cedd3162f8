#version 450 core
// Routing, scatter: one point per layer texel (gl_VertexID = texel index);
// the excess of a routed texel (ground + depth - kept height) goes to its
// terminal (the geometry shader picks the layer; additive blending in
// primitive order sums it in texel order, as the CPU does).
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_POINTER) uniform usampler2DArray u_pointer;

out VertexData {
  flat int emit;
  flat ivec3 target;
  flat float amount;
} v_out;

void main() {
  uint k = uint(gl_VertexID);
  ivec3 t = texel_of_index(k);
  uint p = texelFetch(u_pointer, t, 0).r;
  bool surface = (int(texelFetch(u_cells, t, 0).w) & kCellSurface) != 0;  // else p is not set
  v_out.emit = (surface && p != k && p != kPointerVoid) ? 1 : 0;
  v_out.target = v_out.emit != 0 ? texel_of_index(p) : ivec3(0);
  float s = texelFetch(u_depth, t, 0).r;
  v_out.amount = min((texelFetch(u_cells, t, 0).x + s) - texelFetch(u_stable, t, 0).r,
                     s);  // never more than the snow (CpuStabilizer::route)
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
