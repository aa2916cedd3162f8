#version 450 core
// Adds snow: depth += amount * u_scale on texels with a surface where that
// is > 0, and the held cap grows by as much, up to min(u_stand, holding
// depth) (CpuStabilizer::add_snow; the batch job's amounts come
// multiplied, with u_scale 1; the live preview's kept amount is scaled here).
uniform float u_scale;
#include "bindings.h"
#include "column.glsl"

layout(binding = SNOW_STABILIZE_ADD) uniform sampler2DArray u_add;
layout(binding = SNOW_STABILIZE_HOLD_IMAGE, rg32f) uniform image2DArray u_hold_image;
layout(location = 0) out vec2 o_depth;

void main() {
  ivec3 t = ivec3(ivec2(gl_FragCoord.xy), u_layer);
  vec2 d = texelFetch(u_depth, t, 0).rg;
  float add = texelFetch(u_add, t, 0).r * u_scale;
  if ((int(texelFetch(u_cells, t, 0).w) & kCellSurface) != 0 && add > 0.0) {
    d.r = d.r + add;
    vec2 hold = imageLoad(u_hold_image, t).rg;  // this fragment's own texel only
    hold.g = min(hold.g + add, min(u_stand, hold.r));
    imageStore(u_hold_image, t, vec4(hold, 0.0, 0.0));
  }
  o_depth = d;
}
