// Shared by the coverage counting passes (coverage_count.glsl and
// coverage_exact.glsl, src/snow/coverage/gpu.cpp; Tokoi 2006, section 4).
// Before including, define COVERAGE_SNOW to 1 when a snow surface was drawn
// into the shadow maps (their texels then carry the snow layer), else 0.
//
// A receiver (a surface texel of some layer) sees the sky along a direction
// when its own line of fall p + s * (a, 1, b), s > 0 (s = height above p),
// is free. Pass 1 (coverage_count.glsl) decides from the shadow map alone:
// the depths at the four texel centres around the receiver's projection are
// gathered and compared with the receiver's own plane extended to each
// centre (a receiver-plane depth bias: exact on every slope, no acne). No
// centre above the plane (plus the bias): lit. All four above: blocked (a
// gap narrower than a shadow texel between occluders is below the maps'
// resolution). Mixed (a silhouette, or the foot of a wall, passes next to
// the receiver): uncertain, queued for pass 2 (coverage_exact.glsl), which
// casts the receiver's line exactly through the scene's BVH.
#include "bindings.h"

layout(std430, binding = SNOW_COVERAGE_RECEIVERS) readonly buffer Receivers {
  uvec4 receivers[];  // x: i | j << 16, y: height bits, z: half(n.x, n.y), w: half(n.z, 0)
};
layout(std430, binding = SNOW_COVERAGE_COUNTS) buffer Counts { uint counts[]; };
layout(std430, binding = SNOW_COVERAGE_QUEUE) buffer Queue {
  uint queue_count;  // receivers with uncertain directions in this batch
  uint queue_pad[3];
  uvec2 queue[];     // (receiver, bit k set: direction k of the batch is uncertain)
};
// Depth of the highest surface per texel: height = y_top - depth * y_range.
layout(binding = SNOW_COVERAGE_SHADOW_TEXTURE) uniform sampler2DArray shadow_maps;

uniform vec4 batch_directions[64];  // (a, b, u0, v0) as in shadow.vert, per batch layer
uniform int direction_count;        // layers in this batch
uniform vec2 grid_origin;     // metres
uniform float texel;          // snow-map texel, metres
uniform float shadow_texel;   // shadow-map texel, metres
uniform ivec2 shadow_size;    // texels
uniform vec2 shadow_scale;    // 1 / (shadow_texel * shadow_size): metres to texture coordinates
uniform float bias;           // metres, receiver-plane depth bias
uniform float y_top;          // metres, depth 0
uniform float y_range;        // metres, depth 1 is y_top - y_range

struct Receiver {
  vec3 p;  // metres
  vec3 n;  // surface normal (any orientation)
  float n_dot_p;
};

Receiver load_receiver(uint id) {
  uvec4 r = receivers[id];
  Receiver rc;
  vec2 xz = grid_origin + (vec2(r.x & 0xffffu, r.x >> 16) + 0.5) * texel;
  rc.p = vec3(xz.x, uintBitsToFloat(r.y), xz.y);
  rc.n = vec3(unpackHalf2x16(r.z), unpackHalf2x16(r.w).x);
  rc.n_dot_p = dot(rc.n, rc.p);
  return rc;
}

// 0: lit, 1: blocked, 2: uncertain, for direction k of the batch.
int classify(Receiver rc, int k) {
  vec4 d = batch_directions[k];
  // The receiver's line in shadow-map metres and texture coordinates; the
  // gather returns centres (i0, j1), (i1, j1), (i1, j0), (i0, j0), with
  // i0 = floor(f.x - 0.5) in texels.
  vec2 m = vec2(rc.p.x - d.z - rc.p.y * d.x, rc.p.z - d.w - rc.p.y * d.y);
  vec2 uv = m * shadow_scale;
  vec4 height = y_top - textureGather(shadow_maps, vec3(uv, float(k)), 0) * y_range;
  // The receiver's plane n.(q - p) = 0 meets the line over shadow-texel
  // centre (uc, vc) (q = (uc + h a, h, vc + h b)) at h = (n.p - n.x uc -
  // n.z vc) / D, D = n.(a, 1, b); D near 0: the plane is seen edge-on and
  // every stored surface above the receiver counts.
  float plane_d = dot(rc.n, vec3(d.x, 1.0, d.y));
  float inv_d = 1.0 / plane_d;
  vec2 c0 = d.zw + (floor(uv * vec2(shadow_size) - 0.5) + 0.5) * shadow_texel;  // (i0, j0)
  float own00 = (rc.n_dot_p - rc.n.x * c0.x - rc.n.z * c0.y) * inv_d;
  float du = -rc.n.x * shadow_texel * inv_d;
  float dv = -rc.n.z * shadow_texel * inv_d;
  vec4 own = abs(plane_d) > 1e-3 ? vec4(own00 + dv, own00 + du + dv, own00 + du, own00)
                                 : vec4(rc.p.y);
  bvec4 above = greaterThan(height, own + bias);
  return !any(above) ? 0 : (all(above) ? 1 : 2);
}
