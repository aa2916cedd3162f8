// Bounding volume hierarchy for the CPU reference passes; ray-triangle test
// after Moller and Trumbore, "Fast, minimum storage ray-triangle
// intersection" (1997).
#include "snow/bvh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/default_init.h"
#include "core/parallel.h"

namespace snow {
namespace {

constexpr uint32_t kLeafSize = 4;

// A node of at least this many triangles (the top few levels of a large
// scene's tree) runs its loops over them on all cores, in ranges of
// kLoopChunk, and splits them by a stable partition: the tree depends on the
// triangles alone, not on the number of cores. Below, a single thread's
// loops serve (each level's halves are built side by side) and the split is
// std::partition. This speeds up large scenes on many cores and costs
// nothing on 2 (tools/RESULTS.md).
constexpr uint32_t kLargeNode = 1u << 17;
constexpr size_t kLoopChunk = size_t(1) << 14;

// Inlined into both walks (occluded and reaches): with two callers GCC no
// longer inlines them, and a call per node slows the walk.
[[gnu::always_inline]] inline bool hit_box(const glm::vec3& min, const glm::vec3& max,
                                           const glm::vec3& origin, const glm::vec3& inv_dir,
                                           float t_min, float t_max) {
  for (int a = 0; a < 3; ++a) {
    float t0 = (min[a] - origin[a]) * inv_dir[a];
    float t1 = (max[a] - origin[a]) * inv_dir[a];
    if (t0 > t1) std::swap(t0, t1);
    // NaN (0 * inf on a slab boundary) must not reject: the comparisons below
    // keep the previous bounds when t0 or t1 is NaN.
    if (t0 > t_min) t_min = t0;
    if (t1 < t_max) t_max = t1;
    if (t_min > t_max) return false;
  }
  return true;
}

[[gnu::always_inline]] inline bool hit_triangle(const glm::vec3& a, const glm::vec3& b,
                                                const glm::vec3& c, const glm::vec3& origin,
                                                const glm::vec3& dir, float t_min, float t_max) {
  const glm::vec3 e1 = b - a;
  const glm::vec3 e2 = c - a;
  const glm::vec3 p = glm::cross(dir, e2);
  const float det = glm::dot(e1, p);
  if (det == 0.0f) return false;
  const float inv = 1.0f / det;
  const glm::vec3 s = origin - a;
  const float u = glm::dot(s, p) * inv;
  if (u < 0.0f || u > 1.0f) return false;
  const glm::vec3 q = glm::cross(s, e1);
  const float v = glm::dot(dir, q) * inv;
  if (v < 0.0f || u + v > 1.0f) return false;
  const float t = glm::dot(e2, q) * inv;
  return t > t_min && t < t_max;
}

// 10 bits spread to every third bit (Morton codes).
uint32_t spread_bits(uint32_t v) {
  v = (v | (v << 16)) & 0x030000ffu;
  v = (v | (v << 8)) & 0x0300f00fu;
  v = (v | (v << 4)) & 0x030c30c3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

}  // namespace

Bvh::Bvh(const std::vector<glm::vec3>& corners, Build how) {
  const uint32_t n = static_cast<uint32_t>(corners.size() / 3);
  if (n == 0) return;
  nodes_.reserve(2 * size_t(n));
  order_.resize(n);
  corners_.resize(3 * size_t(n));
  if (how == Build::Morton) {
    // Codes of the centroids on a grid of 1024^3 cubes over their bounds,
    // sorted by three passes of radix sort (stable: equal codes keep the
    // input's order), keyed code << 32 | triangle. The loops run on all
    // cores in ranges of kLoopChunk.
    const auto centroid = [&](size_t t) {
      return (corners[3 * t] + corners[3 * t + 1] + corners[3 * t + 2]) / 3.0f;
    };
    const size_t ranges = (size_t(n) + kLoopChunk - 1) / kLoopChunk;
    std::vector<std::array<glm::vec3, 2>> range_bounds(ranges);
    parallel_for_ranges(n, kLoopChunk, [&](size_t begin, size_t end) {
      glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
      for (size_t t = begin; t < end; ++t) {
        const glm::vec3 c = centroid(t);
        lo = glm::min(lo, c);  // (a NaN centroid is skipped)
        hi = glm::max(hi, c);
      }
      range_bounds[begin / kLoopChunk] = {lo, hi};
    });
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (const auto& [rlo, rhi] : range_bounds) {
      lo = glm::min(lo, rlo);
      hi = glm::max(hi, rhi);
    }
    const float extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    const float scale = extent > 0.0f && std::isfinite(extent) ? 1023.0f / extent : 0.0f;
    const auto cell = [&](float v, float v0) {
      const float f = (v - v0) * scale;
      return f > 0.0f ? uint32_t(std::min(f, 1023.0f)) : 0u;  // (NaN: 0)
    };
    std::vector<uint64_t, DefaultInitAllocator<uint64_t>> keys(n), sorted(n);
    parallel_for_ranges(n, kLoopChunk, [&](size_t begin, size_t end) {
      for (size_t t = begin; t < end; ++t) {
        const glm::vec3 c = centroid(t);
        // x and z above y: the rays mostly fall, so the high splits part
        // them across their way first.
        const uint32_t code = spread_bits(cell(c.x, lo.x)) << 2 |
                              spread_bits(cell(c.z, lo.z)) << 1 | spread_bits(cell(c.y, lo.y));
        keys[t] = uint64_t(code) << 32 | t;
      }
    });
    // Each pass counts the digits of each range, then every range moves its
    // keys to where its digits start: range r's keys of a digit after range
    // r - 1's, so the pass stays stable.
    std::vector<std::array<uint32_t, 1024>> start(ranges);
    for (int shift = 32; shift < 62; shift += 10) {
      parallel_for_ranges(n, kLoopChunk, [&](size_t begin, size_t end) {
        std::array<uint32_t, 1024>& count = start[begin / kLoopChunk];
        count.fill(0);
        for (size_t k = begin; k < end; ++k) ++count[(keys[k] >> shift) & 1023u];
      });
      uint32_t at = 0;
      for (size_t digit = 0; digit < 1024; ++digit) {
        for (size_t r = 0; r < ranges; ++r) {
          const uint32_t count = start[r][digit];
          start[r][digit] = at;
          at += count;
        }
      }
      parallel_for_ranges(n, kLoopChunk, [&](size_t begin, size_t end) {
        std::array<uint32_t, 1024>& to = start[begin / kLoopChunk];
        for (size_t k = begin; k < end; ++k) sorted[to[(keys[k] >> shift) & 1023u]++] = keys[k];
      });
      keys.swap(sorted);
    }
    std::vector<uint32_t> codes(n);
    parallel_for_ranges(n, kLoopChunk, [&](size_t begin, size_t end) {
      for (size_t k = begin; k < end; ++k) {
        codes[k] = uint32_t(keys[k] >> 32);
        order_[k] = uint32_t(keys[k]);
        for (int c = 0; c < 3; ++c) corners_[3 * k + c] = corners[3 * size_t(order_[k]) + c];
      }
    });
    // Serial: built in halves on 2 threads (as build() does) it was slower,
    // the right halves' splices copying and faulting in more than they save.
    build_morton(0, n, codes);
    return;
  }
  // The loops over all triangles before and after the build run on all
  // cores, each writing its own elements.
  constexpr size_t kChunk = size_t(1) << 14;
  std::vector<Prim, DefaultInitAllocator<Prim>> prims(n), scratch(n >= kLargeNode ? n : 0);
  parallel_for_ranges(n, kChunk, [&](size_t begin, size_t end) {
    for (size_t t = begin; t < end; ++t) {
      const glm::vec3 &a = corners[3 * t], &b = corners[3 * t + 1], &c3 = corners[3 * t + 2];
      prims[t] = {glm::min(a, glm::min(b, c3)), glm::max(a, glm::max(b, c3)), (a + b + c3) / 3.0f,
                  uint32_t(t)};
    }
  });
  // The halves of a split are built beside each other while they hold about
  // 16k triangles or more, at most one level past one task per thread: each
  // level's splices copy and fault in its right halves' nodes, so more
  // levels than that cost more than they save.
  int max_levels = 1;
  while ((1u << (max_levels - 1)) < default_threads()) ++max_levels;
  int parallel_levels = 0;
  while (parallel_levels < max_levels && (n >> parallel_levels) >= (1u << 14)) ++parallel_levels;
  build(0, n, prims.data(), scratch.data(), nodes_, parallel_levels);
  // Store the triangles in leaf order.
  parallel_for_ranges(n, kChunk, [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) {
      order_[k] = prims[k].index;
      for (int v = 0; v < 3; ++v) corners_[3 * k + v] = corners[3 * size_t(order_[k]) + v];
    }
  });
}

void Bvh::build_morton(uint32_t first, uint32_t count, const std::vector<uint32_t>& codes) {
  const size_t index = nodes_.size();
  nodes_.emplace_back();
  if (count <= kLeafSize) {
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (size_t k = 3 * size_t(first); k < 3 * size_t(first + count); ++k) {
      lo = glm::min(lo, corners_[k]);
      hi = glm::max(hi, corners_[k]);
    }
    nodes_[index] = {lo, first, hi, count};
    return;
  }
  const uint32_t a = codes[first], b = codes[first + count - 1];
  uint32_t half = count / 2;  // equal codes: the middle
  if (a != b) {
    // The codes are sorted and agree above this bit: those without it come first.
    const uint32_t bit = 1u << (31 - __builtin_clz(a ^ b));
    half = uint32_t(std::partition_point(codes.begin() + first, codes.begin() + first + count,
                                         [&](uint32_t c) { return !(c & bit); }) -
                    (codes.begin() + first));
  }
  build_morton(first, half, codes);
  const size_t right = nodes_.size();
  build_morton(first + half, count - half, codes);
  Node& node = nodes_[index];
  node.min = glm::min(nodes_[index + 1].min, nodes_[right].min);
  node.max = glm::max(nodes_[index + 1].max, nodes_[right].max);
  node.first = static_cast<uint32_t>(nodes_.size());  // skip: past the subtree
  node.count = 0;
}

namespace {

// The loops of one node over prims [first, first + count): a large node's
// (kLargeNode triangles or more) on all cores, fn(r, begin, end) once per
// range r of kLoopChunk, whose results the caller merges in range order; a
// small node's once, as range 0.
struct NodeRanges {
  NodeRanges(uint32_t first, uint32_t count)
      : first(first),
        count(count),
        large(count >= kLargeNode),
        ranges(large ? (size_t(count) + kLoopChunk - 1) / kLoopChunk : 1) {}

  template <class Fn>
  void each(Fn&& fn) const {
    if (!large) return fn(size_t(0), size_t(first), size_t(first) + count);
    parallel_for(ranges, [&](size_t r) {
      fn(r, first + r * kLoopChunk, std::min(first + (r + 1) * kLoopChunk, size_t(first) + count));
    });
  }

  uint32_t first, count;
  bool large;
  size_t ranges;
};

// A node's box (lo, hi) and its centroids' box (clo, chi).
struct NodeBox {
  glm::vec3 lo{std::numeric_limits<float>::max()}, hi{-std::numeric_limits<float>::max()};
  glm::vec3 clo{std::numeric_limits<float>::max()}, chi{-std::numeric_limits<float>::max()};
};

template <class Prim>
NodeBox node_box(const NodeRanges& node, const Prim* prims) {
  NodeBox one_box;  // a small node's (most nodes: no allocation)
  std::vector<NodeBox> range_boxes(node.large ? node.ranges : 0);
  NodeBox* boxes = node.large ? range_boxes.data() : &one_box;
  node.each([&](size_t r, size_t begin, size_t end) {
    NodeBox b;
    for (size_t k = begin; k < end; ++k) {
      const Prim& p = prims[k];
      b.lo = glm::min(b.lo, p.lo);
      b.hi = glm::max(b.hi, p.hi);
      b.clo = glm::min(b.clo, p.c);
      b.chi = glm::max(b.chi, p.c);
    }
    boxes[r] = b;
  });
  NodeBox box = boxes[0];
  for (size_t r = 1; r < node.ranges; ++r) {
    const NodeBox& b = boxes[r];
    box.lo = glm::min(box.lo, b.lo);
    box.hi = glm::max(box.hi, b.hi);
    box.clo = glm::min(box.clo, b.clo);
    box.chi = glm::max(box.chi, b.chi);
  }
  return box;
}

// kBins bins of the centroids along each axis of a node's centroid box.
constexpr int kBins = 16;
struct Binning {
  Binning(const glm::vec3& clo, const glm::vec3& extent) : clo(clo) {
    for (int ax = 0; ax < 3; ++ax) scale[ax] = extent[ax] > 0.0f ? float(kBins) / extent[ax] : 0.0f;
  }
  int bin_of(const glm::vec3& c, int ax) const {
    const float f = (c[ax] - clo[ax]) * scale[ax];
    return f > 0.0f ? int(std::min(f, float(kBins - 1))) : 0;  // (NaN: 0)
  }
  glm::vec3 clo, scale;
};

struct Bin {
  glm::vec3 lo{std::numeric_limits<float>::max()}, hi{-std::numeric_limits<float>::max()};
  uint32_t n = 0;
};
using Bins = std::array<std::array<Bin, kBins>, 3>;

template <class Prim>
Bins fill_bins(const NodeRanges& node, const Prim* prims, const Binning& binning) {
  Bins bins;
  std::vector<Bins> range_bins(node.large ? node.ranges : 0);
  node.each([&](size_t r, size_t begin, size_t end) {
    Bins& into = node.large ? range_bins[r] : bins;
    for (size_t k = begin; k < end; ++k) {
      const Prim& p = prims[k];
      for (int ax = 0; ax < 3; ++ax) {
        Bin& bin = into[size_t(ax)][size_t(binning.bin_of(p.c, ax))];
        bin.lo = glm::min(bin.lo, p.lo);
        bin.hi = glm::max(bin.hi, p.hi);
        ++bin.n;
      }
    }
  });
  if (node.large) bins = range_bins[0];
  for (size_t r = 1; r < node.ranges; ++r) {
    for (size_t ax = 0; ax < 3; ++ax) {
      for (size_t b = 0; b < size_t(kBins); ++b) {
        const Bin& add = range_bins[r][ax][b];
        bins[ax][b].lo = glm::min(bins[ax][b].lo, add.lo);
        bins[ax][b].hi = glm::max(bins[ax][b].hi, add.hi);
        bins[ax][b].n += add.n;
      }
    }
  }
  return bins;
}

// The split: of the planes between the bins along each axis, the one of
// least surface area heuristic cost (binned SAH, Wald 2007): triangles of
// bins <= bin go left. axis < 0 where no plane splits the node.
struct Split {
  int axis = -1, bin = -1;
};

Split sah_split(const Bins& bins, const glm::vec3& extent) {
  const auto area = [](const glm::vec3& a, const glm::vec3& b) {
    const glm::vec3 d = glm::max(b - a, glm::vec3(0.0f));
    return d.x * d.y + d.y * d.z + d.z * d.x;
  };
  float best_cost = std::numeric_limits<float>::max();
  Split best;
  for (int ax = 0; ax < 3; ++ax) {
    if (!(extent[ax] > 0.0f)) continue;
    float right_cost[kBins] = {};  // area x count of bins b.. (b >= 1)
    Bin right;
    for (int b = kBins - 1; b > 0; --b) {
      const Bin& bin = bins[size_t(ax)][size_t(b)];
      right.lo = glm::min(right.lo, bin.lo);
      right.hi = glm::max(right.hi, bin.hi);
      right.n += bin.n;
      right_cost[b] = right.n > 0 ? area(right.lo, right.hi) * float(right.n) : -1.0f;
    }
    Bin left;
    for (int b = 0; b + 1 < kBins; ++b) {
      const Bin& bin = bins[size_t(ax)][size_t(b)];
      left.lo = glm::min(left.lo, bin.lo);
      left.hi = glm::max(left.hi, bin.hi);
      left.n += bin.n;
      if (left.n == 0 || right_cost[b + 1] < 0.0f) continue;
      const float cost = area(left.lo, left.hi) * float(left.n) + right_cost[b + 1];
      if (cost < best_cost) {
        best_cost = cost;
        best = {ax, b};
      }
    }
  }
  return best;
}

// Moves the node's triangles left of `split` before the others; returns how
// many went left. A large node's partition is stable (each range's lefts
// and rights go to their places in scratch, then back), so the tree does
// not depend on the number of cores.
template <class Prim>
uint32_t partition_node(const NodeRanges& node, Prim* prims, Prim* scratch, const Binning& binning,
                        const Split& split) {
  const auto left = [&](const Prim& p) { return binning.bin_of(p.c, split.axis) <= split.bin; };
  if (!node.large) {
    return uint32_t(std::partition(prims + node.first, prims + node.first + node.count, left) -
                    (prims + node.first));
  }
  std::vector<uint32_t> lefts(node.ranges + 1, 0);
  node.each([&](size_t r, size_t begin, size_t end) {
    lefts[r + 1] = uint32_t(std::count_if(prims + begin, prims + end, left));
  });
  for (size_t r = 0; r < node.ranges; ++r) lefts[r + 1] += lefts[r];
  const uint32_t half = lefts[node.ranges];
  node.each([&](size_t r, size_t begin, size_t end) {
    Prim* to_left = scratch + node.first + lefts[r];
    Prim* to_right = scratch + node.first + half + (begin - node.first - lefts[r]);
    for (size_t k = begin; k < end; ++k) *(left(prims[k]) ? to_left++ : to_right++) = prims[k];
  });
  node.each([&](size_t, size_t begin, size_t end) {
    std::copy(scratch + begin, scratch + end, prims + begin);
  });
  return half;
}

}  // namespace

void Bvh::build(uint32_t first, uint32_t count, Prim* prims, Prim* scratch, std::vector<Node>& out,
                int parallel_levels) {
  // Depth-first layout: an inner node's left child follows it directly.
  const size_t index = out.size();
  out.emplace_back();
  const NodeRanges node(first, count);
  const NodeBox box = node_box(node, prims);
  out[index].min = box.lo;
  out[index].max = box.hi;
  const glm::vec3 extent = box.chi - box.clo;
  if (count <= kLeafSize || !(std::max({extent.x, extent.y, extent.z}) > 0.0f)) {
    out[index].first = first;
    out[index].count = count;
    return;
  }
  // Binned SAH: against a median split of the longest axis its build is
  // slower, but its tree's walks (sky cull, CPU casts) are faster by more.
  const Binning binning(box.clo, extent);
  const Split split = sah_split(fill_bins(node, prims, binning), extent);
  uint32_t half = split.axis >= 0 ? partition_node(node, prims, scratch, binning, split) : 0;
  if (half == 0 || half == count) {
    // Every centroid in one bin (they nearly coincide): the median of the
    // longest axis.
    const int axis =
        extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    half = count / 2;
    std::nth_element(prims + first, prims + first + half, prims + first + count,
                     [&](const Prim& a, const Prim& b) { return a.c[axis] < b.c[axis]; });
  }
  if (parallel_levels > 0) {
    // The halves touch disjoint ranges of prims; the right one is spliced
    // in after the left one, its skip links moved by where it lands.
    std::vector<Node> right;
    right.reserve(2 * size_t(count - half));
    parallel_for(2, [&](size_t task) {
      if (task == 0) {
        build(first, half, prims, scratch, out, parallel_levels - 1);
      } else {
        build(first + half, count - half, prims, scratch, right, parallel_levels - 1);
      }
    });
    const uint32_t offset = static_cast<uint32_t>(out.size());
    for (Node& n : right) {
      if (n.count == 0) n.first += offset;
    }
    out.insert(out.end(), right.begin(), right.end());
  } else {
    build(first, half, prims, scratch, out, 0);
    build(first + half, count - half, prims, scratch, out, 0);
  }
  out[index].first = static_cast<uint32_t>(out.size());  // skip: past the subtree
  out[index].count = 0;
}

uint32_t Bvh::first_hit(const glm::vec3& origin, const glm::vec3& direction, float t_min,
                        float t_max) const {
  // Stackless pre-order walk: a hit inner node goes on to its left child (the
  // next node), a missed one skips its subtree; leaves go on to the next node.
  const glm::vec3 inv_dir = 1.0f / direction;
  const uint32_t n = static_cast<uint32_t>(nodes_.size());
  for (uint32_t i = 0; i < n;) {
    const Node& node = nodes_[i];
    const bool hit = hit_box(node.min, node.max, origin, inv_dir, t_min, t_max);
    if (node.count == 0) {
      i = hit ? i + 1 : node.first;
      continue;
    }
    if (hit) {
      for (uint32_t t = node.first; t < node.first + node.count; ++t) {
        if (hit_triangle(corners_[3 * t], corners_[3 * t + 1], corners_[3 * t + 2], origin,
                         direction, t_min, t_max)) {
          return t;
        }
      }
    }
    ++i;
  }
  return kNone;
}

bool Bvh::reaches(uint32_t t, const glm::vec3& origin, const glm::vec3& direction, float t_min,
                  float t_max) const {
  if (t >= triangle_count()) return false;
  // The boxes occluded() tests on its way to t's leaf, with its arithmetic,
  // then the leaf's triangles. A subtree's last node in pre-order is a leaf,
  // where the subtree's triangles end: t is in the left child's subtree when
  // it comes before that end.
  const glm::vec3 inv_dir = 1.0f / direction;
  uint32_t i = 0;
  for (;;) {
    const Node& node = nodes_[i];
    if (!hit_box(node.min, node.max, origin, inv_dir, t_min, t_max)) return false;
    if (node.count > 0) break;
    const uint32_t left = i + 1;
    const uint32_t end = nodes_[left].count > 0 ? left + 1 : nodes_[left].first;
    const Node& last = nodes_[end - 1];
    i = t < last.first + last.count ? left : end;
  }
  const Node& leaf = nodes_[i];
  for (uint32_t k = leaf.first; k < leaf.first + leaf.count; ++k) {
    if (hit_triangle(corners_[3 * k], corners_[3 * k + 1], corners_[3 * k + 2], origin, direction,
                     t_min, t_max)) {
      return true;
    }
  }
  return false;
}

}  // namespace snow
