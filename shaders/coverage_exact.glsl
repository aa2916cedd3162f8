// Coverage counting, pass 2 of 2 (see coverage_common.glsl): for each queued
// receiver, each of its uncertain directions casts its line of fall exactly
// through the scene's BVH (the traversal of snow::Bvh::occluded, Moller-
// Trumbore triangle tests, as snow::reference::compute_coverage) and, with
// a snow surface, through the snow heightfield of every snowy layer (the
// triangles of snow::reference::snow_surface_triangles, walked cell by cell
// along the line's path). Adds to the receiver's count the lines that hit
// nothing.
#include "coverage_common.glsl"

layout(local_size_x = 64) in;

struct Node {
  vec3 min;
  uint first;  // leaf: first triangle; inner: the node after its subtree (skip link)
  vec3 max;
  uint count;  // leaf: triangle count; 0: inner node
};
layout(std430, binding = SNOW_COVERAGE_BVH_NODES) readonly buffer Nodes { Node nodes[]; };
layout(std430, binding = SNOW_COVERAGE_BVH_TRIANGLES) readonly buffer Triangles {
  float corners[];  // 9 per triangle, leaf order
};
uniform int node_count;

#if COVERAGE_SNOW
layout(binding = SNOW_COVERAGE_SNOW_TEXTURE) uniform sampler2DArray snow_surface;  // (top, depth)
uniform ivec2 grid_size;                // snow-map texels
uniform float cut;                      // metres, heightfield cut (kSnowSurfaceCutTexels)
uniform int snow_layer_count;           // entries of snow_layers
uniform int snow_layers[64];            // layers with snow
uniform float snow_top[64];             // metres, highest snow top of each of them
#endif

// Does the line p + s * dir hit the triangle (a, b, c) for some s in (s_min, s_max)?
bool hits_triangle(vec3 a, vec3 b, vec3 c, vec3 p, vec3 dir, float s_min, float s_max) {
  vec3 e1 = b - a;
  vec3 e2 = c - a;
  vec3 q = cross(dir, e2);
  float det = dot(e1, q);
  if (det == 0.0) return false;
  float inv = 1.0 / det;
  vec3 o = p - a;
  float u = dot(o, q) * inv;
  vec3 r = cross(o, e1);
  float v = dot(dir, r) * inv;
  float s = dot(e2, r) * inv;
  return u >= 0.0 && v >= 0.0 && u + v <= 1.0 && s > s_min && s < s_max;
}

vec3 corner(uint t, int c) {
  int k = int(t) * 9 + c * 3;
  return vec3(corners[k], corners[k + 1], corners[k + 2]);
}

bool hit_box(vec3 lo, vec3 hi, vec3 p, vec3 inv_dir, float s_min, float s_max) {
  vec3 t0 = (lo - p) * inv_dir;
  vec3 t1 = (hi - p) * inv_dir;
  vec3 near = min(t0, t1);
  vec3 far = max(t0, t1);
  float enter = max(max(near.x, near.y), max(near.z, s_min));
  float leave = min(min(far.x, far.y), min(far.z, s_max));
  return enter <= leave;
}

// The stackless pre-order walk of snow::Bvh::occluded.
bool scene_blocks(vec3 p, vec3 dir, float s_min, float s_max) {
  // No zero components: 1/0 would make 0 * inf = NaN on slab faces.
  vec3 safe = mix(dir, vec3(1e-20), lessThan(abs(dir), vec3(1e-20)));
  vec3 inv_dir = 1.0 / safe;
  uint i = 0u;
  while (i < uint(node_count)) {
    Node node = nodes[i];
    bool hit = hit_box(node.min, node.max, p, inv_dir, s_min, s_max);
    if (node.count == 0u) {
      i = hit ? i + 1u : node.first;
      continue;
    }
    if (hit) {
      for (uint t = node.first; t < node.first + node.count; ++t) {
        if (hits_triangle(corner(t, 0), corner(t, 1), corner(t, 2), p, dir, s_min, s_max)) {
          return true;
        }
      }
    }
    ++i;
  }
  return false;
}

#if COVERAGE_SNOW
// Snow heightfield quad (i, j) of `layer` (corners at texel centres (i, j) ..
// (i + 1, j + 1)), its two triangles under the rule of shadow_snow.vert.
bool quad_blocks(ivec2 ij, int layer, vec3 p, vec3 dir, float s_min, float s_max) {
  if (any(lessThan(ij, ivec2(0))) || any(greaterThanEqual(ij, grid_size - 1))) return false;
  const ivec2 kCorner[4] = ivec2[](ivec2(0, 0), ivec2(1, 0), ivec2(1, 1), ivec2(0, 1));
  vec3 q[4];
  bool has[4];
  bool snowy[4];
  for (int c = 0; c < 4; ++c) {
    vec2 s = texelFetch(snow_surface, ivec3(ij + kCorner[c], layer), 0).xy;
    vec2 xz = grid_origin + (vec2(ij + kCorner[c]) + 0.5) * texel;
    q[c] = vec3(xz.x, s.x, xz.y);
    has[c] = s.x > -1.0e38;
    snowy[c] = s.y > 0.0;
  }
  // (c00, c10, c11) and (c00, c11, c01).
  if (has[0] && has[1] && has[2] && (snowy[0] || snowy[1] || snowy[2]) &&
      max(max(q[0].y, q[1].y), q[2].y) - min(min(q[0].y, q[1].y), q[2].y) <= cut &&
      hits_triangle(q[0], q[1], q[2], p, dir, s_min, s_max)) {
    return true;
  }
  return has[0] && has[2] && has[3] && (snowy[0] || snowy[2] || snowy[3]) &&
         max(max(q[0].y, q[2].y), q[3].y) - min(min(q[0].y, q[2].y), q[3].y) <= cut &&
         hits_triangle(q[0], q[2], q[3], p, dir, s_min, s_max);
}

// Walks the quads under the line's path (2D DDA over quad cells, whose
// corners are texel centres) until the line rises above the layer's snow.
bool snow_blocks(vec3 p, vec3 dir, float s_min) {
  for (int m = 0; m < snow_layer_count; ++m) {
    int layer = snow_layers[m];
    float s_end = snow_top[m] - p.y;
    if (s_end <= s_min) continue;
    // Quad coordinates: quad i spans texel centres i .. i + 1.
    vec2 g = (p.xz - grid_origin) / texel - 0.5;
    vec2 step_dir = vec2(dir.x, dir.z) / texel;  // quad units per metre of rise
    ivec2 cell = ivec2(floor(g));
    ivec2 stepping = ivec2(sign(step_dir));
    vec2 inv = 1.0 / abs(step_dir);
    vec2 next = (vec2(cell) + max(vec2(stepping), vec2(0.0)) - g) / step_dir;
    next = mix(next, vec2(1e30), equal(step_dir, vec2(0.0)));
    float s = 0.0;
    for (int guard = 0; guard < 4 * (grid_size.x + grid_size.y) && s <= s_end; ++guard) {
      // The receiver's own cells are tested too; hits at s <= s_min are its own surface.
      if (quad_blocks(cell, layer, p, dir, s_min, s_end + 1.0)) return true;
      if (next.x < next.y) {
        s = next.x;
        next.x += inv.x;
        cell.x += stepping.x;
      } else {
        s = next.y;
        next.y += inv.y;
        cell.y += stepping.y;
      }
    }
  }
  return false;
}
#endif

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint q = gl_GlobalInvocationID.x; q < queue_count; q += stride) {
    uvec2 item = queue[q];
    Receiver rc = load_receiver(item.x);
    float s_min = 1e-4 + 1e-6 * abs(rc.p.y);  // as snow::reference::compute_coverage
    uint lit = 0u;
    for (uint mask = item.y; mask != 0u; mask &= mask - 1u) {
      vec4 d = batch_directions[findLSB(mask)];
      vec3 dir = vec3(d.x, 1.0, d.y);
      bool blocked = scene_blocks(rc.p, dir, s_min, y_top - rc.p.y + 1.0);
#if COVERAGE_SNOW
      blocked = blocked || snow_blocks(rc.p, dir, s_min);
#endif
      if (!blocked) ++lit;
    }
    if (lit != 0u) atomicAdd(counts[item.x], lit);
  }
}
