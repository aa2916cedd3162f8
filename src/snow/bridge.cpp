// Snow bridges over narrow gaps (contract: snow/bridge.h).
#include "snow/bridge.h"

#include <algorithm>
#include <cmath>
#include <limits>
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

// The first surface of column (i, j) with a height in (lo, hi) (m): its
// layer, or -1 where there is none (or the column is off the map). The
// layers run from the top down, so the walk ends at the first one no
// higher than lo.
int surface_between(const SnowMaps& maps, int i, int j, float lo, float hi) {
  if (i < 0 || j < 0 || i >= maps.grid.width || j >= maps.grid.height) return -1;
  for (int l = 0; l < maps.layers; ++l) {
    const float g = maps.ground[maps.index(l, i, j)];
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

// For direction d, per column, the highest surface (layer 0; -inf where
// none) of the `reach` columns ahead of it along d (ahead) and behind it
// (behind): where either lies no higher than a surface's height + drop, no
// rim stands on that side. Running maxima in blocks of `reach` along each
// line of the map in that direction (van Herk / Gil-Werman: a few
// comparisons per column whatever the reach; a window within one block
// reads the whole block's, which only keeps more candidates).
void highest_along(const SnowMaps& maps, int d, int reach, std::vector<float>& ahead,
                   std::vector<float>& behind) {
  const int w = maps.grid.width, h = maps.grid.height;
  const float none = -std::numeric_limits<float>::infinity();
  ahead.assign(size_t(w) * size_t(h), none);
  behind.assign(ahead.size(), none);
  // The lines start at the columns whose previous one along d is off the map.
  std::vector<glm::ivec2> starts;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const int pi = i - kDi[d], pj = j - kDj[d];
      if (pi < 0 || pj < 0 || pi >= w || pj >= h) starts.push_back({i, j});
    }
  }
  parallel_for(starts.size(), [&](size_t s) {
    std::vector<size_t> at;
    std::vector<float> v, first, last;  // max from the block's start, to its end
    for (int i = starts[s].x, j = starts[s].y; i >= 0 && j >= 0 && i < w && j < h;
         i += kDi[d], j += kDj[d]) {
      at.push_back(size_t(j) * size_t(w) + size_t(i));
      const float g = maps.ground[at.back()];
      v.push_back(std::isnan(g) ? none : g);
    }
    const int n = int(v.size());
    first.resize(v.size());
    last.resize(v.size());
    for (int m = 0; m < n; ++m) first[m] = m % reach == 0 ? v[m] : std::max(first[m - 1], v[m]);
    for (int m = n - 1; m >= 0; --m) {
      last[m] = (m + 1) % reach == 0 || m == n - 1 ? v[m] : std::max(last[m + 1], v[m]);
    }
    // The maximum over [a, b], b - a < reach: a and b lie in one block or
    // in two neighbouring ones.
    const auto window = [&](int a, int b) { return a > b ? none : std::max(last[a], first[b]); };
    for (int m = 0; m < n; ++m) {
      ahead[at[m]] = window(m + 1, std::min(n - 1, m + reach));
      behind[at[m]] = window(std::max(0, m - reach), m - 1);
    }
  });
}

// Direction d's bridge over column (i, j) (columns `step` metres apart
// along d), if it lies in a gap no wider than `width` along d, on a layer
// no lower than best's: the highest such layer, replacing best where it is
// higher, or as high and the gap no wider.
void find_bridge(const SnowMaps& maps, int i, int j, int d, float width, float step, int reach,
                 float ahead, float behind, Best& best) {
  const float drop = 0.5f * maps.grid.texel;
  for (int l = 0; l < maps.layers && l <= best.layer; ++l) {
    const size_t k = maps.index(l, i, j);
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
      const int si = side == 0 ? 1 : -1;
      both = false;
      for (int n = 1; n <= reach; ++n) {
        const int ni = i + si * n * kDi[d], nj = j + si * n * kDj[d];
        const int rl = surface_between(maps, ni, nj, g + drop, ceiling);
        if (rl < 0) continue;
        const size_t kr = maps.index(rl, ni, nj);
        if (!(maps.normal[kr].y > 0.0f)) break;  // the underside of something
        rim_h[side] = maps.ground[kr];
        rim_n[side] = n;
        rim_object[side] = maps.object[kr];
        both = true;
        break;
      }
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
  std::vector<float> ahead, behind;
  for (int d = 0; d < 4; ++d) {
    const float step = d < 2 ? maps.grid.texel : maps.grid.texel * std::sqrt(2.0f);
    // Gap columns at most (the bound keeps the cost per column finite on
    // maps far finer than the width).
    const int reach = int(std::min(std::floor(width / step), float(kBridgeMaxTexels)));
    if (reach < 1) continue;
    highest_along(maps, d, reach, ahead, behind);
    parallel_for(size_t(maps.grid.height), [&](size_t j) {
      for (int i = 0; i < maps.grid.width; ++i) {
        const size_t c = j * size_t(maps.grid.width) + size_t(i);
        find_bridge(maps, i, int(j), d, width, step, reach, ahead[c], behind[c], best[c]);
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
