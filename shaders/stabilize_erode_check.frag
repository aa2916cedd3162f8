#version 450 core
// Routing: keeps (for an occlusion query) the texels whose kept height
// changed in the last erosion pass (after the first pass, from its start
// value, with u_start); writes nothing.
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_STABLE_OLD) uniform sampler2DArray u_stable_old;

void main() {
  ivec3 t = ivec3(ivec2(gl_FragCoord.xy), u_layer);
  float old = u_start != 0 ? start_height(t, texelFetch(u_cells, t, 0))
                           : texelFetch(u_stable_old, t, 0).r;
  if (texelFetch(u_stable, t, 0).r == old) discard;
}
