// The receivers of the coverage stage: every layer texel with a surface,
// packed for the passes (internal.h, Receivers), with what the snow surface
// adds where a snow depth is given (the snow-on-snow tops, their normals,
// and the quads of the snow heightfield to draw into the shadow maps).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/packing.hpp>

#include "core/parallel.h"
#include "snow/coverage.h"
#include "snow/coverage/internal.h"
#include "snow/maps.h"

namespace snow::cov {
namespace {

// The snow surface's unit normal at layer texel (l, i, j) of `top` (ground
// + depth per layer texel).
glm::vec3 gradient_normal(const SnowMaps& maps, const std::vector<float>& top, int l, int i,
                          int j) {
  // Snow-surface normal from one-sided height differences on the same layer:
  // per axis, the steeper available side (bias must cover both triangles).
  const MapGrid& g = maps.grid;
  const float cut = kSnowSurfaceCutTexels * g.texel;
  const float h = top[maps.index(l, i, j)];
  const auto slope = [&](int di, int dj) {
    float best = 0.0f;
    for (int side : {-1, 1}) {
      const int ni = i + side * di, nj = j + side * dj;
      if (ni < 0 || nj < 0 || ni >= g.width || nj >= g.height) continue;
      const float hn = top[maps.index(l, ni, nj)];
      if (std::isnan(hn) || std::abs(hn - h) > cut) continue;
      const float s = (hn - h) * float(side) / g.texel;
      if (std::abs(s) > std::abs(best)) best = s;
    }
    return best;
  };
  return glm::normalize(glm::vec3(-slope(1, 0), 1.0f, -slope(0, 1)));
}

// The heights and snowy texels of one row of a layer's receivers.
struct RowBounds {
  float y_lo = kOpenSky, y_hi = -kOpenSky;
  glm::ivec4 snowy{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(), -1, -1};
};

// Ground + depth per layer texel (kNoSurface where there is no surface; a
// depth that is not finite or not positive counts as 0).
std::vector<float> snow_tops(const SnowMaps& maps, const std::vector<float>& snow_depth) {
  const size_t total = maps.ground.size();
  std::vector<float> top(total, kNoSurface);
  for (size_t k = 0; k < total; ++k) {
    const float s = snow_depth[k];
    if (!std::isnan(maps.ground[k])) {
      top[k] = maps.ground[k] + (std::isfinite(s) && s > 0.0f ? s : 0.0f);
    }
  }
  return top;
}

// The first receiver of each row of each layer (layer, row order: the rows
// before it hold that many), then the count; rows counted on all cores.
std::vector<size_t> row_starts(const SnowMaps& maps) {
  const MapGrid& grid = maps.grid;
  const size_t rows = size_t(maps.layers) * size_t(grid.height);
  std::vector<size_t> row_start(rows + 1, 0);
  parallel_for(rows, [&](size_t row) {
    const size_t k0 = row * size_t(grid.width);
    row_start[row + 1] = size_t(std::count_if(maps.ground.begin() + ptrdiff_t(k0),
                                              maps.ground.begin() + ptrdiff_t(k0 + grid.width),
                                              [](float g) { return !std::isnan(g); }));
  });
  std::partial_sum(row_start.begin(), row_start.end(), row_start.begin());
  return row_start;
}

// Packs the receivers of row `row` (of all layers' rows) from list index r
// on, and bounds their heights and snowy texels.
void list_row(const SnowMaps& maps, const std::vector<float>* snow_depth, size_t row, size_t r,
              Receivers& out, RowBounds& b) {
  const MapGrid& grid = maps.grid;
  const int l = int(row / size_t(grid.height));
  const int j = int(row % size_t(grid.height));
  for (int i = 0; i < grid.width; ++i) {
    const size_t k = maps.index(l, i, j);
    const float g = maps.ground[k];
    if (std::isnan(g)) continue;
    float y = g;
    glm::vec3 n = maps.normal[k];
    if (snow_depth) {
      const float s = (*snow_depth)[k];
      if (std::isfinite(s) && s > 0.0f) {
        y = out.top[k];
        n = gradient_normal(maps, out.top, l, i, j);
        b.snowy = glm::ivec4(std::min(b.snowy.x, i), std::min(b.snowy.y, j), std::max(b.snowy.z, i),
                             std::max(b.snowy.w, j));
      }
    }
    b.y_lo = std::min(b.y_lo, y);
    b.y_hi = std::max(b.y_hi, y);
    uint32_t y_word;
    std::memcpy(&y_word, &y, sizeof y);
    out.recv[r] =
        glm::uvec4(uint32_t(i) | (uint32_t(j) << 16), y_word,
                   glm::packHalf2x16(glm::vec2(n.x, n.y)), glm::packHalf2x16(glm::vec2(n.z, 0.0f)));
    out.recv_index[r] = uint32_t(k);
    ++r;
  }
}

// The receivers' height range, and the snowy layers and their quads, from
// the rows' bounds.
void gather_bounds(const SnowMaps& maps, const std::vector<RowBounds>& row_bounds, Receivers& out) {
  const MapGrid& grid = maps.grid;
  for (int l = 0; l < maps.layers; ++l) {
    // Texel bounds of the layer's snow (min i, min j, max i, max j).
    glm::ivec4 snowy(grid.width, grid.height, -1, -1);
    for (int j = 0; j < grid.height; ++j) {
      const RowBounds& b = row_bounds[size_t(l) * size_t(grid.height) + size_t(j)];
      out.y_lo = std::min(out.y_lo, b.y_lo);
      out.y_hi = std::max(out.y_hi, b.y_hi);
      snowy = glm::ivec4(glm::min(glm::ivec2(snowy), glm::ivec2(b.snowy)),
                         glm::max(glm::ivec2(snowy.z, snowy.w), glm::ivec2(b.snowy.z, b.snowy.w)));
    }
    const bool layer_has_snow = snowy.z >= 0;
    if (layer_has_snow && grid.width > 1 && grid.height > 1) {
      // Quads with a snowy corner: quad (i, j) has corners i..i+1, j..j+1.
      out.snowy_layers.push_back(l);
      out.snowy_quads.push_back(
          glm::ivec4(std::max(0, snowy.x - 1), std::min(grid.width - 1, snowy.z + 1),
                     std::max(0, snowy.y - 1), std::min(grid.height - 1, snowy.w + 1)));
    }
  }
}

}  // namespace

void list_receivers(const SnowMaps& maps, const std::vector<float>* snow_depth, Receivers& out) {
  if (snow_depth) out.top = snow_tops(maps, *snow_depth);
  // Every layer texel with a surface is a receiver, listed in layer, row,
  // column order: each row of each layer on all cores, at the offset that
  // the rows before it take.
  const std::vector<size_t> row_start = row_starts(maps);
  const size_t rows = row_start.size() - 1;
  out.recv.resize(row_start[rows]);
  out.recv_index.resize(row_start[rows]);
  std::vector<RowBounds> row_bounds(rows);
  parallel_for(rows, [&](size_t row) {
    list_row(maps, snow_depth, row, row_start[row], out, row_bounds[row]);
  });
  gather_bounds(maps, row_bounds, out);
}

}  // namespace snow::cov

namespace snow {

void mask_coverage(const SnowMaps& maps, const std::vector<uint8_t>& receives,
                   std::vector<float>& coverage) {
  const size_t columns = maps.grid.texels();
  for (size_t c = 0; c < maps.bridge.size(); ++c) {
    for (int l = maps.bridge[c] + 1; maps.bridge[c] >= 0 && l < maps.layers; ++l)
      coverage[size_t(l) * columns + c] = 0;
  }
  if (receives.empty()) return;
  for (size_t k = 0; k < coverage.size(); ++k) {
    const int32_t object = maps.object[k];
    if (object >= 0 && size_t(object) < receives.size() && !receives[size_t(object)])
      coverage[k] = 0;
  }
}

}  // namespace snow
