#version 450 core
// Coverage counting (src/snow/coverage.cpp; Tokoi 2006, section 4): for
// every receiver (a surface texel of some layer) and every shadow map of the
// batch, the receiver sees the sky along that direction when nothing in the
// shadow map lies higher than it (plus a slope-scaled bias). Adds the lit
// count of the batch to the receiver's running count.
#include "bindings.h"

layout(local_size_x = 64) in;

layout(std430, binding = SNOW_COVERAGE_RECEIVERS) readonly buffer Receivers {
  uvec4 receivers[];  // x: i | j << 16, y: height bits, z: half(n.x, n.y), w: half(n.z, 0)
};
layout(std430, binding = SNOW_COVERAGE_COUNTS) buffer Counts { uint counts[]; };
layout(std430, binding = SNOW_COVERAGE_DIRECTIONS) readonly buffer Directions {
  vec4 directions[];  // (a, b, u0, v0) as in shadow.vert, for every direction
};
layout(binding = SNOW_COVERAGE_SHADOW_TEXTURE) uniform sampler2DArray shadow_maps;

uniform int first_receiver;
uniform int receiver_count;
uniform int first_direction;  // direction of shadow-map layer 0
uniform int direction_count;  // layers in this batch
uniform vec2 grid_origin;     // metres
uniform float texel;          // snow-map texel, metres
uniform float shadow_texel;   // shadow-map texel, metres
uniform ivec2 shadow_size;    // texels
uniform float y_top;          // metres, depth 0
uniform float y_range;        // metres
uniform float bias;           // metres, constant
uniform float slope_bias;     // factor on the height change across half a shadow texel
uniform float max_bias;       // metres, cap of the slope term

void main() {
  int id = first_receiver + int(gl_GlobalInvocationID.x);
  if (id >= receiver_count) return;
  uvec4 r = receivers[id];
  vec2 xz = grid_origin + (vec2(r.x & 0xffffu, r.x >> 16) + 0.5) * texel;
  float y = uintBitsToFloat(r.y);
  vec3 n = vec3(unpackHalf2x16(r.z), unpackHalf2x16(r.w).x);
  float slope_scale = slope_bias * 0.5 * shadow_texel * (abs(n.x) + abs(n.z));
  uint lit = 0u;
  for (int k = 0; k < direction_count; ++k) {
    vec4 d = directions[first_direction + k];
    vec2 uv = vec2(xz.x - d.z - y * d.x, xz.y - d.w - y * d.y);
    ivec2 t = ivec2(floor(uv / shadow_texel));
    float depth = 1.0;
    if (all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, shadow_size))) {
      depth = texelFetch(shadow_maps, ivec3(t, k), 0).r;
    }
    float occluder = y_top - depth * y_range;
    // Height change of the receiver's plane per shadow texel, in u and v:
    // |n.x| / |n.(a, 1, b)| and |n.z| / |n.(a, 1, b)|.
    float denom = max(abs(n.x * d.x + n.y + n.z * d.y), 1e-6);
    float b = bias + min(slope_scale / denom, max_bias);
    if (y + b >= occluder) ++lit;
  }
  counts[id] += lit;
}
