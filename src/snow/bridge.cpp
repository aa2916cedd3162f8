// Snow bridges over narrow gaps (contract: snow/bridge.h).
#include "snow/bridge.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "core/parallel.h"

namespace snow {
namespace {

struct Bridge {
  size_t column;  // j * width + i
  float height;   // m
  int32_t object;
};

// The first surface of column c (j * width + i) with a height in (lo, hi)
// (m): its layer, or -1 where there is none. The layers run from the top
// down, so the walk ends at the first one no higher than lo.
int surface_between(const SnowMaps& maps, size_t c, float lo, float hi) {
  const size_t columns = maps.grid.texels();
  for (int l = 0; l < maps.layers; ++l) {
    const float g = maps.ground[size_t(l) * columns + c];
    if (!(g > lo)) return -1;  // also where there is no surface (NaN)
    if (g < hi) return l;
  }
  return -1;
}

constexpr int kDi[4] = {1, 0, 1, 1}, kDj[4] = {0, 1, 1, -1};

// The best bridge found so far over a column: the highest layer that lies
// in a gap, and there the narrowest gap (the later direction on a tie).
struct Best {
  int layer = 64;  // 64: none
  float gap = 0.0f;
  float height = 0.0f;
  int32_t object = -1;
};

/// A scan for a rim looks at the columns of a line in blocks of this many:
/// a block with no surface in the scan's range of heights is passed at once.
constexpr int kBlockColumns = 8;

// One line of the map's columns along direction d, from a column whose
// previous one along d is off the map to the last one on it.
class Line {
 public:
  Line(const SnowMaps& maps, int d, glm::ivec2 start, int reach) : maps_(maps), reach_(reach) {
    const int w = maps.grid.width, h = maps.grid.height;
    for (int i = start.x, j = start.y; i >= 0 && j >= 0 && i < w && j < h;
         i += kDi[d], j += kDj[d]) {
      at_.push_back(size_t(j) * size_t(w) + size_t(i));
    }
    const int n = size();
    // Running maxima of the highest surface (layer 0; -inf where none) in
    // blocks of `reach` (van Herk / Gil-Werman: a few comparisons per column
    // whatever the reach; a window within one block reads the whole block's,
    // which only keeps more candidates).
    const float none = -std::numeric_limits<float>::infinity();
    std::vector<float> v(size_t(n), none);
    for (int m = 0; m < n; ++m) {
      const float g = maps.ground[at_[size_t(m)]];
      if (!std::isnan(g)) v[size_t(m)] = g;
    }
    first_.resize(v.size());
    last_.resize(v.size());
    for (int m = 0; m < n; ++m) {
      first_[m] = m % reach == 0 ? v[m] : std::max(first_[m - 1], v[m]);
    }
    for (int m = n - 1; m >= 0; --m) {
      last_[m] = (m + 1) % reach == 0 || m == n - 1 ? v[m] : std::max(last_[m + 1], v[m]);
    }
    // Per block of kBlockColumns columns, the heights of all their surfaces,
    // sorted.
    const size_t columns = maps.grid.texels();
    for (int m = 0; m < n; ++m) {
      if (m % kBlockColumns == 0) block_begin_.push_back(uint32_t(heights_.size()));
      for (int l = 0; l < maps.layers; ++l) {
        const float g = maps.ground[size_t(l) * columns + at_[size_t(m)]];
        if (std::isnan(g)) break;
        heights_.push_back(g);
      }
      if (m % kBlockColumns == kBlockColumns - 1 || m == n - 1) {
        std::sort(heights_.begin() + block_begin_.back(), heights_.end());
      }
    }
    block_begin_.push_back(uint32_t(heights_.size()));
  }
  int size() const { return int(at_.size()); }
  size_t column(int m) const { return at_[size_t(m)]; }
  // The highest surface of the `reach` columns after position m, and before
  // it (-inf where none).
  float ahead(int m) const { return window(m + 1, std::min(size() - 1, m + reach_)); }
  float behind(int m) const { return window(std::max(0, m - reach_), m - 1); }
  // The nearest position m + n * side (n in 1..reach; side +1 or -1) whose
  // column has a surface in (lo, hi), and that surface's layer
  // (surface_between); {0, -1} where none lies within reach.
  std::pair<int, int> rim(int m, int side, float lo, float hi) const {
    for (int n = 1; n <= reach_;) {
      const int p = m + side * n;
      if (p < 0 || p >= size()) break;
      const int b = p / kBlockColumns;
      if (!block_has(b, lo, hi)) {  // on to the block's far end
        const int end = side > 0 ? (b + 1) * kBlockColumns : b * kBlockColumns - 1;
        n += side * (end - p);
        continue;
      }
      const int rl = surface_between(maps_, column(p), lo, hi);
      if (rl >= 0) return {n, rl};
      ++n;
    }
    return {0, -1};
  }

 private:
  // The maximum over positions [a, b], b - a < reach: a and b lie in one
  // block or in two neighbouring ones.
  float window(int a, int b) const {
    return a > b ? -std::numeric_limits<float>::infinity() : std::max(last_[a], first_[b]);
  }
  // Whether a column of block b has a surface in (lo, hi).
  bool block_has(int b, float lo, float hi) const {
    const auto begin = heights_.begin() + block_begin_[size_t(b)];
    const auto end = heights_.begin() + block_begin_[size_t(b) + 1];
    const auto above = std::upper_bound(begin, end, lo);
    return above != end && *above < hi;
  }

  const SnowMaps& maps_;
  int reach_;
  std::vector<size_t> at_;
  std::vector<float> first_, last_;  // max from a reach block's start, to its end
  std::vector<uint32_t> block_begin_;
  std::vector<float> heights_;
};

// Direction d's bridge over the column at position m of `line` (columns
// `step` metres apart along d), if it lies in a gap no wider than `width`
// along d, on a layer no lower than best's: the highest such layer,
// replacing best where it is higher, or as high and the gap no wider.
void find_bridge(const SnowMaps& maps, const Line& line, int m, float width, float step,
                 Best& best) {
  const float drop = 0.5f * maps.grid.texel;
  const size_t columns = maps.grid.texels();
  const size_t c = line.column(m);
  const float ahead = line.ahead(m), behind = line.behind(m);
  for (int l = 0; l < maps.layers && l <= best.layer; ++l) {
    const size_t k = size_t(l) * columns + c;
    const float g = maps.ground[k];
    if (std::isnan(g)) break;
    if (!(ahead > g + drop) || !(behind > g + drop)) continue;  // no rim on one side
    const float ceiling = maps.ceiling[k];
    // The rims on either side: the first column with a surface above this
    // one's (by more than `drop`) and below its ceiling.
    float rim_h[2] = {0.0f, 0.0f};
    int rim_n[2] = {0, 0};
    int32_t rim_object[2] = {-1, -1};
    bool both = true;
    for (int side = 0; side < 2 && both; ++side) {
      const auto [n, rl] = line.rim(m, side == 0 ? 1 : -1, g + drop, ceiling);
      both = false;
      if (rl < 0) break;
      const size_t kr = size_t(rl) * columns + line.column(m + (side == 0 ? n : -n));
      if (!(maps.normal[kr].y > 0.0f)) break;  // the underside of something
      rim_h[side] = maps.ground[kr];
      rim_n[side] = n;
      rim_object[side] = maps.object[kr];
      both = true;
    }
    if (!both) continue;
    const float gap = float(rim_n[0] + rim_n[1] - 1) * step;
    const float across = float(rim_n[0] + rim_n[1]) * step;
    if (gap > (l == best.layer ? best.gap : width) ||
        std::abs(rim_h[0] - rim_h[1]) > kBridgeMaxSlope * across) {
      continue;
    }
    const float t = float(rim_n[0]) / float(rim_n[0] + rim_n[1]);
    best = {l, gap, rim_h[0] + (rim_h[1] - rim_h[0]) * t,
            rim_n[0] <= rim_n[1] ? rim_object[0] : rim_object[1]};
    return;  // the highest layer of the column that lies in a gap along d
  }
}

}  // namespace

size_t bridge_gaps(SnowMaps& maps, float width) {
  if (!(width > 0.0f) || !std::isfinite(width) || !(maps.grid.texel > 0.0f) || maps.layers < 1)
    return 0;
  const size_t columns = maps.grid.texels();
  // Direction by direction (x, z, the two diagonals), each column's best.
  std::vector<Best> best(columns);
  for (int d = 0; d < 4; ++d) {
    const float step = d < 2 ? maps.grid.texel : maps.grid.texel * std::sqrt(2.0f);
    // Gap columns at most (the bound keeps the cost per column finite on
    // maps far finer than the width).
    const int reach = int(std::min(std::floor(width / step), float(kBridgeMaxTexels)));
    if (reach < 1) continue;
    // The lines start at the columns whose previous one along d is off the
    // map; each column lies on one line, so the lines write apart.
    std::vector<glm::ivec2> starts;
    const int w = maps.grid.width, h = maps.grid.height;
    for (int j = 0; j < h; ++j) {
      for (int i = 0; i < w; ++i) {
        const int pi = i - kDi[d], pj = j - kDj[d];
        if (pi < 0 || pj < 0 || pi >= w || pj >= h) starts.push_back({i, j});
      }
    }
    parallel_for(starts.size(), [&](size_t s) {
      const Line line(maps, d, starts[s], reach);
      for (int m = 0; m < line.size(); ++m) {
        find_bridge(maps, line, m, width, step, best[line.column(m)]);
      }
    });
  }
  std::vector<Bridge> bridges;
  for (size_t c = 0; c < columns; ++c) {
    if (best[c].layer < 64) bridges.push_back({c, best[c].height, best[c].object});
  }
  if (bridges.empty()) return 0;
  // Room for one more surface in every bridged column.
  const auto full = [&](size_t c) {
    return !std::isnan(maps.ground[size_t(maps.layers - 1) * columns + c]);
  };
  if (maps.layers < 64 && std::any_of(bridges.begin(), bridges.end(),
                                      [&](const Bridge& b) { return full(b.column); })) {
    maps.reserve_layers(maps.layers + 1);
    maps.add_layer();
  }
  maps.bridge.assign(columns, int8_t(-1));
  size_t added = 0;
  for (const Bridge& b : bridges) {
    if (full(b.column)) continue;
    const auto at = [&](int l) { return size_t(l) * columns + b.column; };
    int layer = 0;  // the bridge's layer: below every surface higher than it
    while (layer < maps.layers && !std::isnan(maps.ground[at(layer)]) &&
           maps.ground[at(layer)] > b.height) {
      ++layer;
    }
    for (int l = maps.layers - 1; l > layer; --l) {
      maps.ground[at(l)] = maps.ground[at(l - 1)];
      maps.ceiling[at(l)] = maps.ceiling[at(l - 1)];
      maps.normal[at(l)] = maps.normal[at(l - 1)];
      maps.object[at(l)] = maps.object[at(l - 1)];
    }
    maps.ground[at(layer)] = b.height;
    maps.ceiling[at(layer)] = layer > 0 ? maps.ground[at(layer - 1)] : kOpenSky;
    maps.normal[at(layer)] = glm::vec3(0.0f, 1.0f, 0.0f);
    maps.object[at(layer)] = b.object;
    if (layer + 1 < maps.layers && !std::isnan(maps.ground[at(layer + 1)])) {
      maps.ceiling[at(layer + 1)] = b.height;
    }
    maps.bridge[b.column] = int8_t(layer);
    ++added;
  }
  return added;
}

}  // namespace snow
