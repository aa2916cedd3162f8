// Snow bridges over narrow gaps (contract: snow/bridge.h).
#include "snow/bridge.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/parallel.h"

namespace snow {
namespace {

struct Bridge {
  size_t column;  // j * width + i
  float height;   // m
  int32_t object;
};

// The first surface of column (i, j) with a height in (lo, hi) (m): its
// layer, or -1 where there is none (or the column is off the map).
int surface_between(const SnowMaps& maps, int i, int j, float lo, float hi) {
  if (i < 0 || j < 0 || i >= maps.grid.width || j >= maps.grid.height) return -1;
  for (int l = 0; l < maps.layers; ++l) {
    const float g = maps.ground[maps.index(l, i, j)];
    if (std::isnan(g)) return -1;
    if (g > lo && g < hi) return l;
  }
  return -1;
}

// The bridge over column (i, j), if it lies in a gap no wider than `width`.
bool find_bridge(const SnowMaps& maps, int i, int j, float width, Bridge& out) {
  static const int kDi[4] = {1, 0, 1, 1}, kDj[4] = {0, 1, 1, -1};
  const float texel = maps.grid.texel;
  const float drop = 0.5f * texel;
  bool found = false;
  float best_gap = width;
  for (int l = 0; l < maps.layers; ++l) {
    const size_t k = maps.index(l, i, j);
    const float g = maps.ground[k];
    if (std::isnan(g)) break;
    const float ceiling = maps.ceiling[k];
    for (int d = 0; d < 4; ++d) {
      const float step = d < 2 ? texel : texel * std::sqrt(2.0f);
      // Gap columns at most (the bound keeps the cost per column finite
      // on maps far finer than the width).
      const int reach = int(std::min(std::floor(width / step), float(kBridgeMaxTexels)));
      // The rims on either side: the first column with a surface above
      // this one's (by more than `drop`) and below its ceiling.
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
      if (gap > best_gap || std::abs(rim_h[0] - rim_h[1]) > kBridgeMaxSlope * across) continue;
      const float t = float(rim_n[0]) / float(rim_n[0] + rim_n[1]);
      out.height = rim_h[0] + (rim_h[1] - rim_h[0]) * t;
      out.object = rim_n[0] <= rim_n[1] ? rim_object[0] : rim_object[1];
      best_gap = gap;
      found = true;
    }
    if (found) break;  // the highest surface of the column that lies in a gap
  }
  return found;
}

}  // namespace

size_t bridge_gaps(SnowMaps& maps, float width) {
  if (!(width > 0.0f) || !std::isfinite(width) || !(maps.grid.texel > 0.0f) || maps.layers < 1)
    return 0;
  const size_t columns = maps.grid.texels();
  std::vector<std::vector<Bridge>> rows(size_t(maps.grid.height));
  parallel_for(rows.size(), [&](size_t row) {
    const int j = int(row);
    for (int i = 0; i < maps.grid.width; ++i) {
      Bridge b;
      if (find_bridge(maps, i, j, width, b)) {
        b.column = size_t(j) * size_t(maps.grid.width) + size_t(i);
        rows[row].push_back(b);
      }
    }
  });
  std::vector<Bridge> bridges;
  for (const auto& row : rows) bridges.insert(bridges.end(), row.begin(), row.end());
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
