// Which terminals of a pour are poured as one pile (contract:
// snow/stabilize/pour_units.h, snow/deposit.h).
#include "snow/stabilize/pour_units.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include <glm/gtc/constants.hpp>

#include "snow/column.h"
#include "snow/stabilize.h"
#include "snow/stabilize_cpu.h"

namespace snow {
namespace {

/// Piles under the open sky whose lone cones (lone_cone_rise) are at least
/// this many texels in radius are grouped where they overlap (PourUnits);
/// narrower ones are poured one by one (cheap, and they come to the same
/// rest whether the snow arrives at once or frame by frame, as in the live
/// preview).
constexpr float kWidePileTexels = 8.0f;

/// The height (m) of the lone cone of `volume` metres of depth on one texel
/// `texel` metres wide: the cone at the repose angle (tan) on flat ground
/// that holds it, V = pi h^3 / (3 tan^2); its radius is h / tan.
float lone_cone_rise(float volume, float tan, float texel) {
  const double v = double(volume) * double(texel) * double(texel);  // m^3
  return float(std::cbrt(3.0 * v * double(tan) * double(tan) / glm::pi<double>()));
}

/// Terminals are grouped on a grid of cells this many texels wide: two
/// terminals whose lone cones (lone_cone_rise) reach a common cell are close
/// enough to share a pile.
constexpr int kGroupCellTexels = 8;
/// A lone cone reaches this many cells from its terminal at most (a pile
/// covers 2^20 texels at most, snow/deposit.h: a disc of about 580 texels'
/// radius).
constexpr float kMaxGroupReachCells = 80.0f;

}  // namespace

// Two terminals under the open sky whose piles are wide (kWidePileTexels)
// are in one unit where their lone cones' discs meet (both reach a cell of
// kGroupCellTexels: coarse, as a pile is a warm start) and their heights
// overlap (tops closer than h + h'), or through a chain of such.
PourUnits plan_pour_units(const glm::vec4* cells, const float* depth, const float* arrive,
                          const std::vector<uint32_t>& ordered, const DepositGrid& grid,
                          PileGrouping grouping) {
  const bool group = grouping == PileGrouping::Wide;
  const size_t n = ordered.size();
  const size_t per_layer = size_t(grid.width) * size_t(grid.height);
  std::vector<float> top(n), rise(n);  // m: snow top, lone cone's height
  std::vector<uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  const auto root = [&](uint32_t t) {
    while (parent[t] != t) t = parent[t] = parent[parent[t]];
    return t;
  };
  const int cells_x = (grid.width + kGroupCellTexels - 1) / kGroupCellTexels;
  const int cells_y = (grid.height + kGroupCellTexels - 1) / kGroupCellTexels;
  std::vector<uint32_t> painted(group ? size_t(cells_x) * size_t(cells_y) : 0, UINT32_MAX);
  for (size_t t = 0; t < n; ++t) {
    const uint32_t p = ordered[t];
    const glm::vec4 cell = cells[p];
    top[t] = cell.x + depth[p];
    const float tan = cell.z;
    rise[t] = lone_cone_rise(arrive[p], tan, grid.texel);
    const float radius = rise[t] / tan / grid.texel;  // texels
    if (!group || cell.y < kCellOpenSky || !(radius >= kWidePileTexels)) continue;
    const float ci = (float((p % per_layer) % size_t(grid.width)) + 0.5f) / kGroupCellTexels;
    const float cj = (float((p % per_layer) / size_t(grid.width)) + 0.5f) / kGroupCellTexels;
    const float reach = std::min(radius / float(kGroupCellTexels) + 1.0f, kMaxGroupReachCells);
    const int y0 = std::max(0, int(std::floor(cj - reach)));
    const int y1 = std::min(cells_y - 1, int(std::ceil(cj + reach)));
    const int x0 = std::max(0, int(std::floor(ci - reach)));
    const int x1 = std::min(cells_x - 1, int(std::ceil(ci + reach)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const float dx = float(x) + 0.5f - ci, dy = float(y) + 0.5f - cj;
        if (dx * dx + dy * dy > reach * reach) continue;
        uint32_t& other = painted[size_t(y) * size_t(cells_x) + size_t(x)];
        if (other != UINT32_MAX && std::abs(top[t] - top[other]) <= rise[t] + rise[other]) {
          const uint32_t a = root(uint32_t(t)), b = root(other);
          parent[std::max(a, b)] = std::min(a, b);  // the first terminal is the root
        }
        other = uint32_t(t);
      }
    }
  }
  if (grouping == PileGrouping::Pressed) {
    // Per column, the last terminal seen there (+1; 0: none).
    std::vector<uint32_t> at(per_layer, 0u);
    const float continuity = kSurfaceContinuityTexels * grid.texel;  // m
    for (size_t t = 0; t < n; ++t) {
      const uint32_t p = ordered[t];
      const size_t c = p % per_layer;
      const int i = int(c % size_t(grid.width)), j = int(c / size_t(grid.width));
      for (int n8 = 0; n8 < 8; ++n8) {
        const int ni = i + kDirI[n8], nj = j + kDirJ[n8];
        if (ni < 0 || nj < 0 || ni >= grid.width || nj >= grid.height) continue;
        const uint32_t other = at[size_t(nj) * size_t(grid.width) + size_t(ni)];
        if (other == 0u || !(std::abs(cells[ordered[other - 1]].y - cells[p].y) < continuity))
          continue;
        const uint32_t a = root(uint32_t(t)), b = root(other - 1);
        parent[std::max(a, b)] = std::min(a, b);
      }
      at[c] = uint32_t(t) + 1u;
      top[t] = rise[t] = 0.0f;  // one apex for all
    }
  }
  // Units in the order of their first terminals (their roots).
  std::vector<uint32_t> unit(n, UINT32_MAX);
  std::vector<size_t> size;
  for (size_t t = 0; t < n; ++t) {
    const uint32_t r = root(uint32_t(t));
    if (unit[r] == UINT32_MAX) {
      unit[r] = uint32_t(size.size());
      size.push_back(0);
    }
    unit[t] = unit[r];
    ++size[unit[t]];
  }
  PourUnits units;
  units.begin.assign(size.size() + 1, 0);
  for (size_t u = 0; u < size.size(); ++u) units.begin[u + 1] = units.begin[u] + size[u];
  units.terminals.resize(n);
  units.apex.resize(n);
  std::vector<size_t> next(units.begin.begin(), units.begin.end() - 1);
  for (size_t t = 0; t < n; ++t) {
    const size_t at = next[unit[t]]++;
    units.terminals[at] = ordered[t];
    units.apex[at] = top[t] + rise[t];
  }
  return units;
}

}  // namespace snow
