// CoverageMethod::CpuShadowMaps: the shadow-map method on the CPU cores
// (Tokoi 2006, section 4, as the GPU passes; shaders/coverage_common.glsl).
// Each worker draws a direction's shadow map (the highest surface at each
// texel centre along the lines of fall, the depth test of the GL pass),
// classifies every receiver on it as the compute pass does (four texels
// against the receiver's own plane: lit, blocked or uncertain), settles
// runs of neighbouring receivers at once where the texels they read bound
// them, and casts the uncertain pairs exactly through the scene's BVH.
// Only the triangles near texels that receivers read are drawn.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <numeric>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/packing.hpp>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "snow/bvh.h"
#include "snow/coverage/internal.h"
#include "snow/maps.h"
#include "snow/reference/coverage_ref.h"

namespace snow::cov {
namespace {

constexpr float kNoShadow = -std::numeric_limits<float>::infinity();  // no surface drawn

// floor(x) and ceil(x) clamped to [lo, hi], as int(std::clamp(std::floor(x),
// lo, hi)) and int(std::clamp(std::ceil(x), lo, hi)) for x not NaN:
// clamping first, then truncating, saves the floating-point rounding that
// x86-64's baseline (SSE2) lacks (a third of the classification's time).
inline int floor_in(double x, int lo, int hi) {
  const double c = std::clamp(x, double(lo), double(hi));
  const int t = int(c);
  return t - int(c < double(t));
}
inline int ceil_in(double x, int lo, int hi) {
  const double c = std::clamp(x, double(lo), double(hi));
  const int t = int(c);
  return t + int(c > double(t));
}

/// A texel of a CPU shadow map drawn by no scene triangle (or by the snow
/// surface's).
constexpr uint32_t kNoTriangle = ~0u;
// Texels a triangle's box spans along x from which its rows are drawn as runs.
constexpr int kMinRun = 8;

/// The tiles of kShift x kShift texels of a CPU shadow map that some
/// receiver reads: a triangle whose box meets none of them is not drawn.
struct TexelMask {
  static constexpr int kShift = 4;
  int tiles_x = 0;
  std::vector<uint8_t> on;

  void reset(glm::ivec2 size) {
    tiles_x = ((size.x - 1) >> kShift) + 1;
    on.assign(size_t(tiles_x) * size_t(((size.y - 1) >> kShift) + 1), 0);
  }
  /// Marks texels [i0, i1] x [j0, j1].
  void mark(int i0, int i1, int j0, int j1) {
    for (int b = j0 >> kShift; b <= j1 >> kShift; ++b) {
      std::fill_n(on.begin() + ptrdiff_t(size_t(b) * size_t(tiles_x) + size_t(i0 >> kShift)),
                  (i1 >> kShift) - (i0 >> kShift) + 1, uint8_t(1));
    }
  }
  /// fn(s, e) for each longest span [s, e] of texels [a, b] of row j that
  /// lies in marked tiles, left to right.
  template <class Fn>
  void each_span(int j, int a, int b, const Fn& fn) const {
    const uint8_t* row = on.data() + size_t(j >> kShift) * size_t(tiles_x);
    for (int t = a >> kShift; t <= b >> kShift;) {
      if (!row[t]) {
        ++t;
        continue;
      }
      const int s = std::max(a, t << kShift);
      while (t <= b >> kShift && row[t]) ++t;
      fn(s, std::min(b, (t << kShift) - 1));
    }
  }
  /// Sets the marked tiles' texels of a map of `size` texels to v.
  void fill(std::vector<float>& map, glm::ivec2 size, float v) const {
    for (int j = 0; j < size.y; ++j) {
      each_span(j, 0, size.x - 1, [&](int s, int e) {
        std::fill_n(map.begin() + ptrdiff_t(size_t(j) * size_t(size.x) + size_t(s)), e - s + 1, v);
      });
    }
  }
  /// Whether a tile of texels [i0, i1] x [j0, j1] is marked.
  bool any(int i0, int i1, int j0, int j1) const {
    for (int b = j0 >> kShift; b <= j1 >> kShift; ++b) {
      const uint8_t* row = on.data() + size_t(b) * size_t(tiles_x);
      for (int a = i0 >> kShift; a <= i1 >> kShift; ++a) {
        if (row[a]) return true;
      }
    }
    return false;
  }
};

/// Draws a soup of triangles into a CPU shadow map: each texel keeps the
/// highest surface at its centre along the direction's lines of fall (the
/// depth test of the GL pass), and in `drawn` (unless empty) the index of
/// the triangle it came from (`numbered`: the soup's t / 3; else
/// kNoTriangle), a likely occluder for the exact casts. A centre is drawn
/// when it is inside or on
/// the triangle's edges; the height is the triangle's plane in the sheared
/// space, as GL interpolates depth. Triangles seen edge-on draw nothing, nor
/// do those whose box meets no tile of `read` (given): no receiver reads
/// their texels; and rows drawn as runs leave out the texels of tiles not
/// in `read`. Draws the soup's triangles [first, first + count). Returns
/// how many `read` left out.
size_t draw_cpu_shadow_map(const std::vector<glm::vec3>& corners, const ShadowFrame& f,
                           std::vector<float>& height, std::vector<uint32_t>& drawn, bool numbered,
                           const TexelMask* read = nullptr, size_t first = 0,
                           size_t count = std::numeric_limits<size_t>::max()) {
  size_t skipped = 0;
  const size_t end = 3 * std::min(corners.size() / 3, first + std::min(count, corners.size()));
  for (size_t t = 3 * first; t < end; t += 3) {
    glm::dvec2 q[3];
    double h[3];
    for (int e = 0; e < 3; ++e) {
      q[e] = f.texel_of(corners[t + size_t(e)]);
      h[e] = corners[t + size_t(e)].y;
    }
    const glm::dvec2 e1 = q[1] - q[0], e2 = q[2] - q[0];
    const double area = e1.x * e2.y - e1.y * e2.x;
    if (!(std::abs(area) > 0.0)) continue;  // edge-on, or not finite
    const glm::dvec2 lo = glm::min(q[0], glm::min(q[1], q[2]));
    const glm::dvec2 hi = glm::max(q[0], glm::max(q[1], q[2]));
    // Clamped before the conversion: triangles far outside the map.
    const int i0 = ceil_in(lo.x - 0.5, 0, f.size.x);
    const int j0 = ceil_in(lo.y - 0.5, 0, f.size.y);
    const int i1 = floor_in(hi.x - 0.5, -1, f.size.x - 1);
    const int j1 = floor_in(hi.y - 0.5, -1, f.size.y - 1);
    if (i0 > i1 || j0 > j1) continue;
    if (read && !read->any(i0, i1, j0, j1)) {
      ++skipped;
      continue;
    }
    // Height h0 + gx (x - q0.x) + gy (y - q0.y); edge functions A x + B y +
    // C, >= 0 inside whichever way the triangle winds.
    const double gx = ((h[1] - h[0]) * e2.y - (h[2] - h[0]) * e1.y) / area;
    const double gy = ((h[2] - h[0]) * e1.x - (h[1] - h[0]) * e2.x) / area;
    const double sign = area > 0.0 ? 1.0 : -1.0;
    double ea[3], eb[3], ec[3];
    for (int e = 0; e < 3; ++e) {
      const glm::dvec2& a = q[e];
      const glm::dvec2& b = q[(e + 1) % 3];
      ea[e] = -(b.y - a.y) * sign;
      eb[e] = (b.x - a.x) * sign;
      ec[e] = -(ea[e] * a.x + eb[e] * a.y);
    }
    // Rows as runs (below) where they are long enough to pay for finding
    // them, and the coefficients are finite, far from overflowing.
    bool runs = i1 - i0 >= kMinRun;
    for (int e = 0; e < 3 && runs; ++e) {
      runs = std::abs(ea[e]) < 1e300 && std::abs(eb[e]) < 1e300 && std::abs(ec[e]) < 1e300;
    }
    const uint32_t id = numbered ? uint32_t(t / 3) : kNoTriangle;
    for (int j = j0; j <= j1; ++j) {
      const double y = j + 0.5;
      const size_t at = size_t(j) * size_t(f.size.x);
      float* row = height.data() + at;
      uint32_t* row_drawn = drawn.empty() ? nullptr : drawn.data() + at;
      // The row's terms of the sums below, rounded as they were there:
      // (A x + B y) + C and (h0 + gx (x - q0.x)) + gy (y - q0.y).
      const double eby[3] = {eb[0] * y, eb[1] * y, eb[2] * y};
      const double rise_y = gy * (y - q[0].y);
      const auto draw = [&](int i, double x) {
        const float v = float(h[0] + gx * (x - q[0].x) + rise_y);
        if (row[i] < v) {  // std::max(row[i], v), the depth test
          row[i] = v;
          if (row_drawn) row_drawn[i] = id;
        }
      };
      if (!runs) {
        for (int i = i0; i <= i1; ++i) {
          const double x = i + 0.5;
          if (ea[0] * x + eby[0] + ec[0] < 0.0 || ea[1] * x + eby[1] + ec[1] < 0.0 ||
              ea[2] * x + eby[2] + ec[2] < 0.0) {
            continue;
          }
          draw(i, x);
        }
        continue;
      }
      // An edge function so rounded is monotone in x (rounding is), so the
      // centres inside make a run: found by stepping from each edge's
      // solution with the exact test, they are the centres the test above
      // keeps, without testing the centres outside.
      const auto inside = [&](int e, int i) { return ea[e] * (i + 0.5) + eby[e] + ec[e] >= 0.0; };
      int a = i0, b = i1;
      for (int e = 0; e < 3 && a <= b; ++e) {
        if (ea[e] > 0.0) {  // inside from some x on: the first inside
          const double x = -(eby[e] + ec[e]) / ea[e] - 0.5;
          int s = ceil_in(x, a, b + 1);
          while (s > a && inside(e, s - 1)) --s;
          while (s <= b && !inside(e, s)) ++s;
          a = s;
        } else if (ea[e] < 0.0) {  // inside up to some x: the last inside
          const double x = -(eby[e] + ec[e]) / ea[e] - 0.5;
          int s = floor_in(x, a - 1, b);
          while (s < b && inside(e, s + 1)) ++s;
          while (s >= a && !inside(e, s)) --s;
          b = s;
        } else if (!inside(e, a)) {
          b = a - 1;
        }
      }
      if (read) {
        read->each_span(j, a, b, [&](int s, int e) {
          for (int i = s; i <= e; ++i) draw(i, i + 0.5);
        });
      } else {
        for (int i = a; i <= b; ++i) draw(i, i + 0.5);
      }
    }
  }
  return skipped;
}

/// Bounds [lo, hi] of texel_of(q) - 0.5 (classify_on_cpu's c, before its
/// clamping) over the points q of the box [box_lo, box_hi] in map f: each
/// bound is texel_of's sum with the box's extreme terms, and rounding keeps
/// the order of such sums, so no point of the box falls outside.
inline void box_coordinates(const ShadowFrame& f, const glm::vec3& box_lo, const glm::vec3& box_hi,
                            glm::dvec2& lo, glm::dvec2& hi) {
  const double a = f.params.x, b = f.params.y;
  const double ay_lo = std::min(a * box_lo.y, a * box_hi.y);
  const double ay_hi = std::max(a * box_lo.y, a * box_hi.y);
  const double by_lo = std::min(b * box_lo.y, b * box_hi.y);
  const double by_hi = std::max(b * box_lo.y, b * box_hi.y);
  lo = glm::dvec2((double(box_lo.x) - f.params.z - ay_hi) * f.inv_st - 0.5,
                  (double(box_lo.z) - f.params.w - by_hi) * f.inv_st - 0.5);
  hi = glm::dvec2((double(box_hi.x) - f.params.z - ay_lo) * f.inv_st - 0.5,
                  (double(box_hi.z) - f.params.w - by_lo) * f.inv_st - 0.5);
}

/// The share of the triangles a worker's first CPU shadow map must leave
/// out for the worker to go on culling (TexelMask).
constexpr double kCullShare = 0.25;

/// The first triangle (leaf order) under node n of a BVH's nodes
/// (`triangles`, the count, for n past the last node).
size_t first_triangle(const std::vector<Bvh::Node>& nodes, size_t n, size_t triangles) {
  if (n >= nodes.size()) return triangles;
  while (nodes[n].count == 0) ++n;  // an inner node's left child follows it
  return nodes[n].first;
}

/// draw_cpu_shadow_map of the BVH's triangles (numbered in leaf order), a
/// subtree at a time: one whose box's texels (padded by one) lie off the
/// map, or meet no tile of `read` (given), is left out whole, as each of
/// its triangles would be. The others are drawn in leaf order, as the soup
/// is, so ties keep the same triangle. Returns the triangles left out.
size_t draw_cpu_shadow_map(const Bvh& bvh, const ShadowFrame& f, std::vector<float>& height,
                           std::vector<uint32_t>& drawn, const TexelMask* read) {
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  size_t skipped = 0;
  for (size_t n = 0; n < nodes.size();) {
    const Bvh::Node& node = nodes[n];
    // Texel centres i + 0.5 inside the box's sheared shadow (texel_of).
    glm::dvec2 lo, hi;
    box_coordinates(f, node.min, node.max, lo, hi);
    const int i0 = ceil_in(lo.x, -2, f.size.x + 1) - 1;
    const int i1 = floor_in(hi.x, -2, f.size.x + 1) + 1;
    const int j0 = ceil_in(lo.y, -2, f.size.y + 1) - 1;
    const int j1 = floor_in(hi.y, -2, f.size.y + 1) + 1;
    const int ci0 = std::max(i0, 0), ci1 = std::min(i1, f.size.x - 1);
    const int cj0 = std::max(j0, 0), cj1 = std::min(j1, f.size.y - 1);
    const bool off = ci0 > ci1 || cj0 > cj1 || (read && !read->any(ci0, ci1, cj0, cj1));
    if (node.count > 0) {  // leaf
      if (off) {
        skipped += node.count;
      } else {
        skipped += draw_cpu_shadow_map(bvh.corners(), f, height, drawn, true, read, node.first,
                                       node.count);
      }
      ++n;
    } else if (off) {
      const size_t next = node.first;
      skipped += first_triangle(nodes, next, bvh.triangle_count()) -
                 first_triangle(nodes, n, bvh.triangle_count());
      n = next;
    } else {
      ++n;
    }
  }
  return skipped;
}

/// classify() of shaders/coverage_common.glsl on a CPU shadow map, for the
/// receiver at p with normal n and n_dot_p = n.p: which of the four texels
/// around it hold a surface above its plane, bits 0..3 for (i0, j0), (i1,
/// j0), (i0, j1), (i1, j1) (none: lit, all: blocked, else uncertain); `at`
/// is the index of texel (i0, j0). The plane test h > own + bias, own =
/// (n.p - n.x u - n.z v) / D, is made without the division: (h - bias) D
/// against n.p - n.x u - n.z v, the comparison turned over where D < 0.
inline int classify_on_cpu(const std::vector<float>& height, const ShadowFrame& f,
                           const glm::vec3& p, const glm::vec3& n, double n_dot_p, float bias,
                           size_t& at) {
  const glm::dvec2 c = f.texel_of(p) - 0.5;
  const int i0 = floor_in(c.x, 0, f.size.x - 2);
  const int j0 = floor_in(c.y, 0, f.size.y - 2);
  at = size_t(j0) * size_t(f.size.x) + size_t(i0);
  const float* row0 = height.data() + at;
  const float* row1 = row0 + f.size.x;
  const double h00 = row0[0], h10 = row0[1], h01 = row1[0], h11 = row1[1];
  const double plane_d = double(n.x) * f.params.x + double(n.y) + double(n.z) * f.params.y;
  if (std::abs(plane_d) > 1e-3) {
    const double u0 = f.params.z + (i0 + 0.5) * f.st, v0 = f.params.w + (j0 + 0.5) * f.st;
    const double g00 = n_dot_p - n.x * u0 - n.z * v0;
    const double du = -n.x * f.st, dv = -n.z * f.st;
    const double g10 = g00 + du, g01 = g00 + dv, g11 = g00 + du + dv;
    const double a00 = (h00 - bias) * plane_d, a10 = (h10 - bias) * plane_d;
    const double a01 = (h01 - bias) * plane_d, a11 = (h11 - bias) * plane_d;
    if (plane_d > 0.0) {
      return int(a00 > g00) | int(a10 > g10) << 1 | int(a01 > g01) << 2 | int(a11 > g11) << 3;
    }
    return int(a00 < g00) | int(a10 < g10) << 1 | int(a01 < g01) << 2 | int(a11 < g11) << 3;
  }
  const double y = double(p.y) + bias;
  return int(h00 > y) | int(h10 > y) << 1 | int(h01 > y) << 2 | int(h11 > y) << 3;
}

/// A run of receivers (indices [r0, r1) of the list) on one row of one layer,
/// with the bounds of their points and normals: classify_run_on_cpu settles
/// all of a run's pairs with one direction at once where their shadow-map
/// texels all lie above or all below every receiver's plane.
struct ReceiverRun {
  uint32_t r0 = 0, r1 = 0;
  float x_lo = 0, x_hi = 0, z_lo = 0, z_hi = 0, y_lo = 0, y_hi = 0;
  float ny_lo = 0, ny_hi = 0;  // n.y
  float nxz = 0;               // |n.x| + |n.z|
  bool bounded = false;        // every bound above finite

  /// Takes in the bounds of `other`, which follows this run.
  void join(const ReceiverRun& other) {
    r1 = other.r1;
    x_lo = std::min(x_lo, other.x_lo);
    x_hi = std::max(x_hi, other.x_hi);
    z_lo = std::min(z_lo, other.z_lo);
    z_hi = std::max(z_hi, other.z_hi);
    y_lo = std::min(y_lo, other.y_lo);
    y_hi = std::max(y_hi, other.y_hi);
    ny_lo = std::min(ny_lo, other.ny_lo);
    ny_hi = std::max(ny_hi, other.ny_hi);
    nxz = std::max(nxz, other.nxz);
    bounded = bounded && other.bounded;
  }
};
/// Receivers are settled in runs of at most kRunTexels columns, and these
/// in groups of kRunsPerGroup runs, where a group is settled whole: long
/// runs settle open ground at once, short ones still settle where rows
/// cross trees and walls.
constexpr int kRunTexels = 4;
constexpr size_t kRunsPerGroup = 4;

/// Bounds [lo, hi] of classify_on_cpu's texel coordinates c (before their
/// clamping) of the run's points on map f, padded for rounding; not finite
/// for a run that is not bounded.
inline void run_coordinates(const ShadowFrame& f, const ReceiverRun& run, glm::dvec2& lo,
                            glm::dvec2& hi) {
  constexpr double kPad = 1e-3;
  box_coordinates(f, glm::vec3(run.x_lo, run.y_lo, run.z_lo),
                  glm::vec3(run.x_hi, run.y_hi, run.z_hi), lo, hi);
  lo -= kPad;
  hi += kPad;
}

/// Marks in `read` the texels that classify_on_cpu reads for the run's
/// receivers on map f (all of them for a run that is not bounded).
inline void mark_run_texels(const ShadowFrame& f, const ReceiverRun& run, TexelMask& read) {
  glm::dvec2 lo, hi;
  run_coordinates(f, run, lo, hi);
  if (!run.bounded || !std::isfinite(lo.x) || !std::isfinite(lo.y) || !std::isfinite(hi.x) ||
      !std::isfinite(hi.y)) {
    read.mark(0, f.size.x - 1, 0, f.size.y - 1);
    return;
  }
  read.mark(floor_in(lo.x, 0, f.size.x - 2), floor_in(hi.x, 0, f.size.x - 2) + 1,
            floor_in(lo.y, 0, f.size.y - 2), floor_in(hi.y, 0, f.size.y - 2) + 1);
}

/// What classify_on_cpu gives every receiver of a run on one map: all 0,
/// all 15, or not known without classifying each.
enum class RunVerdict { Lit, Blocked, Mixed };

/// classify_on_cpu for all of a run's receivers at once, where the texels
/// they read bound it. A receiver p with normal n reads the four texels
/// around its point's texel coordinates c (when c lies inside the map, so
/// none is clamped), each at most one texel from c along u and v. The
/// surface of a texel (i, j) is above the plane where h - bias > own, own
/// being the plane's height on the texel's line of fall: own = p.y + (n.x
/// dx + n.z dz) / D, with D = n.x a + n.y + n.z b (a, b: the shear) and
/// |dx|, |dz| <= st. So |own - p.y| <= st (|n.x| + |n.z|) / |D|, and every
/// bit is set (or none is) where the highest (lowest) texel of the run's
/// region clears the highest (lowest) own by a margin far above the
/// rounding of classify_on_cpu's sums. Runs with |D| near classify_on_cpu's
/// 1e-3 (planes along the lines of fall) are Mixed. Same bits as
/// classifying each receiver.
inline RunVerdict classify_run_on_cpu(const std::vector<float>& height, const ShadowFrame& f,
                                      const ReceiverRun& run, float bias) {
  if (!run.bounded) return RunVerdict::Mixed;
  const double a = f.params.x, b = f.params.y;
  glm::dvec2 lo, hi;
  run_coordinates(f, run, lo, hi);
  if (!(lo.x >= 0.0 && lo.y >= 0.0 && hi.x <= f.size.x - 2 && hi.y <= f.size.y - 2)) {
    return RunVerdict::Mixed;  // a texel clamped at the map's edge, or not finite
  }
  const int i_lo = int(lo.x), i_hi = int(hi.x) + 1;
  const int j_lo = int(lo.y), j_hi = int(hi.y) + 1;
  if ((i_hi - i_lo + 1) * (j_hi - j_lo + 1) > 64) return RunVerdict::Mixed;
  // |D| >= |n.y| - (|n.x| + |n.z|) max(|a|, |b|), the same sign for all.
  const double tilt = double(run.nxz) * std::max(std::abs(a), std::abs(b));
  double d_min = double(run.ny_lo) - tilt;
  if (!(d_min > 2e-3)) d_min = -double(run.ny_hi) - tilt;
  if (!(d_min > 2e-3)) return RunVerdict::Mixed;
  const double reach = f.st * double(run.nxz) / d_min;
  float h_lo = std::numeric_limits<float>::infinity(), h_hi = -h_lo;
  for (int j = j_lo; j <= j_hi; ++j) {
    const float* row = height.data() + size_t(j) * size_t(f.size.x);
    for (int i = i_lo; i <= i_hi; ++i) {
      h_lo = std::min(h_lo, row[i]);
      h_hi = std::max(h_hi, row[i]);
    }
  }
  const double scale =
      1.0 + std::max({std::abs(double(run.x_lo)), std::abs(double(run.x_hi)),
                      std::abs(double(run.z_lo)), std::abs(double(run.z_hi)),
                      std::abs(double(run.y_lo)), std::abs(double(run.y_hi)), reach});
  const double margin = 1e-7 * scale;
  if (double(h_lo) - double(bias) > double(run.y_hi) + reach + margin) return RunVerdict::Blocked;
  if (double(h_hi) - double(bias) < double(run.y_lo) - reach - margin) return RunVerdict::Lit;
  return RunVerdict::Mixed;
}

// A receiver's point, normal and n.p, as classify_on_cpu reads them.
struct Point {
  glm::vec3 p, n;
  double n_dot_p;
};

std::vector<Point> receiver_points(const MapGrid& grid, const std::vector<glm::uvec4>& recv) {
  std::vector<Point> points(recv.size());
  for (size_t r = 0; r < recv.size(); ++r) {
    const glm::vec3 p = receiver_point(grid, recv[r]);
    const glm::vec3 n(glm::unpackHalf2x16(recv[r].z), glm::unpackHalf2x16(recv[r].w).x);
    points[r] = {p, n, double(n.x) * p.x + double(n.y) * p.y + double(n.z) * p.z};
  }
  return points;
}

// Runs of receivers for classify_run_on_cpu, and groups of them: each run
// and group on one row of one layer, kRunTexels and kRunsPerGroup *
// kRunTexels columns at most.
struct RunList {
  std::vector<ReceiverRun> runs, groups;
  std::vector<uint32_t> group_runs;  // first run of each group, then runs.size()
};

RunList receiver_runs(const std::vector<Point>& points, const std::vector<glm::uvec4>& recv,
                      const std::vector<uint32_t>& recv_index, size_t texels) {
  RunList out;
  std::vector<ReceiverRun>& runs = out.runs;
  std::vector<ReceiverRun>& groups = out.groups;
  std::vector<uint32_t>& group_runs = out.group_runs;
  const auto same_row = [&](size_t r, size_t first, int span) {
    const glm::ivec2 t = receiver_texel(recv[r]), t0 = receiver_texel(recv[first]);
    return recv_index[r] / texels == recv_index[first] / texels && t.y == t0.y && t.x - t0.x < span;
  };
  for (size_t r = 0; r < recv.size(); ++r) {
    const Point& q = points[r];
    ReceiverRun run;
    run.r0 = uint32_t(r);
    run.r1 = uint32_t(r + 1);
    run.x_lo = run.x_hi = q.p.x;
    run.z_lo = run.z_hi = q.p.z;
    run.y_lo = run.y_hi = q.p.y;
    run.ny_lo = run.ny_hi = q.n.y;
    run.nxz = std::abs(q.n.x) + std::abs(q.n.z);
    run.bounded = std::isfinite(q.p.x) && std::isfinite(q.p.y) && std::isfinite(q.p.z) &&
                  std::isfinite(q.n.y) && std::isfinite(run.nxz);
    if (!runs.empty() && same_row(r, runs.back().r0, kRunTexels)) {
      runs.back().join(run);
    } else {
      runs.push_back(run);
    }
  }
  for (size_t u = 0; u < runs.size(); ++u) {
    if (!groups.empty() && u - group_runs.back() < kRunsPerGroup &&
        same_row(runs[u].r0, groups.back().r0, int(kRunsPerGroup) * kRunTexels)) {
      groups.back().join(runs[u]);
    } else {
      groups.push_back(runs[u]);
      group_runs.push_back(uint32_t(u));
    }
  }
  group_runs.push_back(uint32_t(runs.size()));
  return out;
}

// What one worker draws into and counts.
struct Worker {
  std::vector<float> height;    // the shadow map being drawn
  std::vector<uint32_t> drawn;  // the triangle drawn into each texel (with hints), else empty
  std::vector<uint16_t> lit;    // per receiver: directions lit (at most 4096: 16 bits)
  TexelMask mask;               // the texels the receivers read (with run bounds)
  bool cull = true;             // draws only triangles whose box meets a marked tile
  uint64_t uncertain = 0, settled = 0, left_out = 0;  // CpuShadowMapCounts' terms
};

// The method over all directions: CpuShadowMapper(...).run().
class CpuShadowMapper {
 public:
  // Lists the receivers' points and runs (recv_index: each receiver's
  // layer texel index) and makes the workers. Throws InputError when
  // memory for the workers' maps runs out.
  CpuShadowMapper(const Bvh& bvh, const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
                  const std::vector<ShadowFrame>& frames, float bias,
                  const std::vector<float>* snow_depth, const std::vector<glm::uvec4>& recv,
                  const std::vector<uint32_t>& recv_index, bool run_bounds, double memory_bytes)
      : bvh_(bvh), dirs_(dirs), frames_(frames), bias_(bias), run_bounds_(run_bounds) {
    if (snow_depth) {
      snow_triangles_ = reference::snow_surface_triangles(maps, *snow_depth);
      snow_bvh_ = std::make_unique<Bvh>(snow_triangles_);
    }
    points_ = receiver_points(maps.grid, recv);
    runs_ = receiver_runs(points_, recv, recv_index, maps.grid.texels());
    make_workers(recv.size(), memory_bytes);
  }

  // Every direction on every receiver; progress between rounds (Progress is
  // not thread-safe). Sets coverage[recv_index[r]] of each receiver.
  CpuShadowMapCounts run(const std::vector<uint32_t>& recv_index, std::vector<float>& coverage,
                         Progress& progress);

 private:
  void make_workers(size_t receivers, double memory_bytes);
  void draw_map(Worker& w, size_t k);
  void classify_map(Worker& w, size_t k);
  void classify_each(Worker& w, size_t k, size_t r0, size_t r1, uint32_t& last);
  bool settle(Worker& w, size_t k, const ReceiverRun& run);

  const Bvh& bvh_;
  const std::vector<glm::vec3>& dirs_;
  const std::vector<ShadowFrame>& frames_;
  const float bias_;
  const bool run_bounds_;  // runs settled at once, only the texels they read drawn (masks)
  std::vector<glm::vec3> snow_triangles_;
  std::unique_ptr<Bvh> snow_bvh_;
  std::vector<Point> points_;
  RunList runs_;
  std::vector<Worker> workers_;
  bool hints_ = false;  // workers keep the triangle drawn into each texel
  bool culls_ = false;  // workers may draw only the triangles near marked tiles
};

// As many workers as maps of frames_ fit in `memory_bytes`, each keeping
// the triangle drawn into each texel where that memory is left.
void CpuShadowMapper::make_workers(size_t receivers, double memory_bytes) {
  const glm::ivec2 size = frames_.front().size;
  const double map_bytes = 4.0 * double(size.x) * double(size.y);
  const size_t workers = size_t(std::clamp(
      memory_bytes / map_bytes, 1.0, double(std::min<size_t>(default_threads(), dirs_.size()))));
  hints_ = 2.0 * map_bytes * double(workers) <= memory_bytes;
  // With runs of receivers, each map marks the tiles that its groups of
  // receivers read (TexelMask), and clears and draws only those. Where the
  // triangles outnumber the groups, it also draws only the triangles whose
  // box meets a marked tile, found through the BVH. Where a worker's first
  // map leaves out less than kCullShare that way (receivers all over a
  // model), the walk costs more than it saves, and it draws every triangle.
  culls_ = run_bounds_ && bvh_.triangle_count() + snow_triangles_.size() / 3 >= runs_.groups.size();
  workers_.resize(workers);
  try {
    for (Worker& w : workers_) {
      w.height.resize(size_t(size.x) * size_t(size.y));
      if (hints_) w.drawn.resize(w.height.size());
      w.lit.assign(receivers, 0);
    }
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory for shadow maps of " + std::to_string(size.x) +
                     " x " + std::to_string(size.y) + " texels; use a coarser texel size");
  }
}

// Clears worker w's map and draws direction k's into it: the scene's
// triangles, then the snow surface's.
void CpuShadowMapper::draw_map(Worker& w, size_t k) {
  const glm::ivec2 size = frames_[k].size;
  TexelMask* read = nullptr;
  if (run_bounds_) {
    read = &w.mask;
    read->reset(size);
    for (const ReceiverRun& group : runs_.groups) mark_run_texels(frames_[k], group, *read);
    read->fill(w.height, size, kNoShadow);
  } else {
    std::fill(w.height.begin(), w.height.end(), kNoShadow);
  }
  // Each worker culls its first map; it goes on culling only where that
  // left out a good share of the triangles.
  const bool cull = culls_ && w.cull;
  const size_t out =
      (cull ? draw_cpu_shadow_map(bvh_, frames_[k], w.height, w.drawn, read)
            : draw_cpu_shadow_map(bvh_.corners(), frames_[k], w.height, w.drawn, true, read)) +
      draw_cpu_shadow_map(snow_triangles_, frames_[k], w.height, w.drawn, false, read);
  w.left_out += out;
  if (cull && k < workers_.size()) {
    w.cull = double(out) >= kCullShare * double(bvh_.triangle_count());
  }
}

// Receivers [r0, r1) on direction k's map, each on its own; the uncertain
// pairs cast exactly (`last`: the triangle that blocked the last pair cast).
void CpuShadowMapper::classify_each(Worker& w, size_t k, size_t r0, size_t r1, uint32_t& last) {
  const glm::vec3 up = -dirs_[k];  // the casts' ray, as reference::sees_sky's
  const size_t sx = size_t(frames_[k].size.x);
  for (size_t r = r0; r < r1; ++r) {
    const glm::vec3& p = points_[r].p;
    size_t at = 0;
    const int above =
        classify_on_cpu(w.height, frames_[k], p, points_[r].n, points_[r].n_dot_p, bias_, at);
    if (above == 0 || above == 15) {
      w.lit[r] += above == 0;
      continue;
    }
    ++w.uncertain;
    // Most uncertain pairs are blocked, often by a triangle drawn into a
    // texel above the receiver: one that the walk would reach and find hit
    // (Bvh::reaches) settles the pair as the whole walk would.
    const float t_min = reference::own_surface(p.y) / up.y;  // as sees_sky
    const size_t texel[4] = {at, at + 1, at + sx, at + sx + 1};
    uint32_t tried = kNoTriangle;
    bool blocked = !(up.y > 0.0f);  // (fall directions point down)
    for (int e = 0; e < 4 && hints_ && !blocked; ++e) {
      const uint32_t id = w.drawn[texel[e]];
      if (!(above >> e & 1) || id == kNoTriangle || id == tried) continue;
      tried = id;
      blocked = bvh_.reaches(id, p, up, t_min, kOpenSky);
    }
    // Then the triangle that blocked the last pair cast, then the walk.
    w.lit[r] += !blocked && sees_sky_after(bvh_, snow_bvh_.get(), p, up, t_min, last, tried);
  }
}

// Whether the run's receivers were settled together on direction k's map.
bool CpuShadowMapper::settle(Worker& w, size_t k, const ReceiverRun& run) {
  const RunVerdict verdict = classify_run_on_cpu(w.height, frames_[k], run, bias_);
  if (verdict == RunVerdict::Mixed) return false;
  if (verdict == RunVerdict::Lit) {
    for (size_t r = run.r0; r < run.r1; ++r) ++w.lit[r];
  }
  w.settled += run.r1 - run.r0;
  return true;
}

// Every receiver on direction k's map (drawn): a group at once, else its
// runs, else each receiver.
void CpuShadowMapper::classify_map(Worker& w, size_t k) {
  uint32_t last = Bvh::kNone;
  const RunList& l = runs_;
  for (size_t g = 0; g < l.groups.size(); ++g) {
    if (run_bounds_ && settle(w, k, l.groups[g])) continue;
    for (size_t u = l.group_runs[g]; u < l.group_runs[g + 1]; ++u) {
      if (!run_bounds_ || !settle(w, k, l.runs[u])) {
        classify_each(w, k, l.runs[u].r0, l.runs[u].r1, last);
      }
    }
  }
}

CpuShadowMapCounts CpuShadowMapper::run(const std::vector<uint32_t>& recv_index,
                                        std::vector<float>& coverage, Progress& progress) {
  const size_t workers = workers_.size();
  const size_t per_round = 4 * workers;  // progress between rounds
  for (size_t k0 = 0; k0 < dirs_.size(); k0 += per_round) {
    const size_t k1 = std::min(dirs_.size(), k0 + per_round);
    parallel_for(
        workers,
        [&](size_t w) {
          for (size_t k = k0 + w; k < k1; k += workers) {
            draw_map(workers_[w], k);
            classify_map(workers_[w], k);
          }
        },
        unsigned(workers));
    progress.update(double(k1));
  }
  for (size_t r = 0; r < recv_index.size(); ++r) {
    uint32_t sum = 0;
    for (const Worker& w : workers_) sum += w.lit[r];
    coverage[recv_index[r]] = float(sum) / float(dirs_.size());
  }
  CpuShadowMapCounts counts;
  for (const Worker& w : workers_) {
    counts.uncertain += w.uncertain;
    counts.settled += w.settled;
    counts.left_out += w.left_out;
  }
  return counts;
}

}  // namespace

CpuShadowMapCounts shadow_maps_on_cpu(
    const Bvh& bvh, const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
    const std::vector<ShadowFrame>& frames, float bias, const std::vector<float>* snow_depth,
    const std::vector<glm::uvec4>& recv, const std::vector<uint32_t>& recv_index, bool run_bounds,
    double memory_bytes, std::vector<float>& coverage, Progress& progress) {
  CpuShadowMapper mapper(bvh, maps, dirs, frames, bias, snow_depth, recv, recv_index, run_bounds,
                         memory_bytes);
  return mapper.run(recv_index, coverage, progress);
}

// The triangles that TexelMask and draw_cpu_shadow_map of a BVH would
// leave in, estimated from the leaves' boxes (internal.h).
size_t triangles_near_receivers(const Bvh& bvh, const MapGrid& grid,
                                const std::vector<glm::uvec4>& recv,
                                const std::vector<uint8_t>& culled, double reach) {
  constexpr int kTile = 16;
  const int tw = (grid.width + kTile - 1) / kTile, th = (grid.height + kTile - 1) / kTile;
  // Receivers per tile, summed (sum[(b + 1) (tw + 1) + a + 1]: tiles below b, left of a).
  std::vector<uint32_t> sum(size_t(tw + 1) * size_t(th + 1), 0);
  for (size_t r = 0; r < recv.size(); ++r) {
    if (culled[r]) continue;
    const glm::ivec2 t = receiver_texel(recv[r]) / kTile;
    sum[size_t(t.y + 1) * size_t(tw + 1) + size_t(t.x + 1)] = 1;
  }
  for (int b = 1; b <= th; ++b) {
    for (int a = 1; a <= tw; ++a) {
      const size_t at = size_t(b) * size_t(tw + 1) + size_t(a);
      sum[at] += sum[at - 1] + sum[at - size_t(tw + 1)] - sum[at - size_t(tw + 1) - 1];
    }
  }
  const double tile = double(grid.texel) * kTile;
  const auto tile_of = [&](double x, double origin, int tiles) {
    return int(std::clamp(std::floor((x - origin) / tile), -1.0, double(tiles)));
  };
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  if (nodes.empty()) return 0;
  // Receivers in every tile, and the root's box on the grid: every node's
  // box, within the root's, meets some tile, so every node is near (no
  // walk of the nodes, which a small, dense model on few texels would pay).
  const Bvh::Node& root = nodes.front();
  if (sum.back() == uint32_t(tw) * uint32_t(th) && tile_of(root.min.x, grid.origin.x, tw) >= 0 &&
      tile_of(root.max.x, grid.origin.x, tw) < tw && tile_of(root.min.z, grid.origin.y, th) >= 0 &&
      tile_of(root.max.z, grid.origin.y, th) < th) {
    return bvh.triangle_count();
  }
  size_t drawn = 0;
  for (size_t n = 0; n < nodes.size();) {
    const Bvh::Node& node = nodes[n];
    const int a0 = std::max(0, tile_of(double(node.min.x) - reach, grid.origin.x, tw));
    const int a1 = std::min(tw - 1, tile_of(double(node.max.x) + reach, grid.origin.x, tw));
    const int b0 = std::max(0, tile_of(double(node.min.z) - reach, grid.origin.y, th));
    const int b1 = std::min(th - 1, tile_of(double(node.max.z) + reach, grid.origin.y, th));
    const bool near = a0 <= a1 && b0 <= b1 &&
                      sum[size_t(b1 + 1) * size_t(tw + 1) + size_t(a1 + 1)] -
                              sum[size_t(b0) * size_t(tw + 1) + size_t(a1 + 1)] -
                              sum[size_t(b1 + 1) * size_t(tw + 1) + size_t(a0)] +
                              sum[size_t(b0) * size_t(tw + 1) + size_t(a0)] >
                          0;
    if (node.count > 0 && near) drawn += node.count;
    n = node.count > 0 || near ? n + 1 : size_t(node.first);
  }
  return drawn;
}

}  // namespace snow::cov
