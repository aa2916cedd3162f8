#version 450 core
// Steep routing, scatter: emits the routed snow as a one-texel point on its
// terminal's layer.
#include "bindings.h"
#include "column.glsl"

layout(points) in;
layout(points, max_vertices = 1) out;

in VertexData {
  flat int emit;
  flat ivec3 target;
  flat float amount;
} v_in[];

flat out float g_amount;

void main() {
  if (v_in[0].emit == 0) return;
  vec2 p = (vec2(v_in[0].target.xy) + 0.5) / vec2(u_size) * 2.0 - 1.0;
  gl_Position = vec4(p, 0.0, 1.0);
  gl_Layer = v_in[0].target.z;
  gl_PointSize = 1.0;
  g_amount = v_in[0].amount;
  EmitVertex();
  EndPrimitive();
}
