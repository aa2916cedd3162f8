#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/parallel.h"
#include "core/zeroed.h"
#include "snow/column.h"
#include "snow/deposit.h"
#include "snow/stabilize_cpu.h"

namespace snow {

namespace {

constexpr uint32_t kNowhere = 0xffffffffu;   // a path's end: what arrives stays
constexpr uint32_t kIntoVoid = 0xfffffffeu;  // what passes on leaves the scene

}  // namespace

std::vector<uint32_t> spill_excess(const glm::vec4* cells, const float* stable, float* depth,
                                   float* lost, const DepositGrid& grid, float min_excess) {
  const size_t per_layer = size_t(grid.width) * size_t(grid.height);
  const size_t count = per_layer * size_t(grid.layers);
  const float rise = kSurfaceContinuityTexels * grid.texel;
  const float diagonal = float(double(grid.texel) * 1.4142135623730951);
  const auto kept = [stable](size_t k) { return stable[k]; };
  // The sources, in texel order, and what each gives up (m).
  ZeroedArray<float> flow(count);
  std::vector<std::vector<uint32_t>> source_rows(size_t(grid.layers) * size_t(grid.height));
  parallel_for(source_rows.size(), [&](size_t row) {
    const size_t first = row * size_t(grid.width);
    for (size_t k = first; k < first + size_t(grid.width); ++k) {
      if ((int(cells[k].w) & kCellSurface) == 0) continue;
      const float top = cells[k].x + depth[k];
      if (top > stable[k] + min_excess) {
        flow[k] = std::min(top - stable[k], depth[k]);
        source_rows[row].push_back(uint32_t(k));
      }
    }
  });
  // Where what texel k passes on goes (kNowhere, kIntoVoid, or the
  // neighbour that limits it, as route()'s receiver rule), and its room
  // (m): how far its free top may rise before that neighbour's kept height
  // plus the repose slope (or its ceiling) stops it; none on a source, or
  // beside the void.
  const auto follow = [&](uint32_t k, float* room) {
    const size_t column = k % per_layer;
    const int i = int(column % size_t(grid.width)), j = int(column / size_t(grid.width));
    const glm::vec4 cell = cells[k];
    const float he = free_top(cell, depth[k]);
    uint32_t p = kNowhere;
    float bound = cell.y - kCeilingClearance, best = 0.0f;
    for (int n = 0; n < 8; ++n) {
      const int ni = i + kDirI[n], nj = j + kDirJ[n];
      int land_l = kLandVoid;
      if (ni >= 0 && nj >= 0 && ni < grid.width && nj < grid.height) {
        const CellColumn<decltype(kept)> col{cells, per_layer,
                                             size_t(nj) * size_t(grid.width) + size_t(ni), kept};
        land_l = land_in_column(col, grid.layers, he, cell.x, rise);
      }
      if (land_l == kLandVoid) {
        p = kIntoVoid;
        bound = he;
        break;
      }
      if (land_l < 0) continue;
      const size_t kt = size_t(land_l) * per_layer + size_t(nj) * size_t(grid.width) + size_t(ni);
      const float via = stable[kt] + (n < 4 ? grid.texel : diagonal) * cell.z;
      bound = std::min(bound, via);
      if (stable[kt] < stable[k] && (p == kNowhere || via < best)) {
        best = via;
        p = uint32_t(kt);
      }
    }
    *room = flow[k] > 0.0f ? 0.0f : std::max(bound - he, 0.0f);
    return p;
  };
  // The texels on the paths from the sources, and how many paths arrive at
  // each (the sources taken in texel order).
  std::vector<uint32_t> reached;
  ZeroedArray<uint32_t> arrivals(count), next(count);
  ZeroedArray<float> room(count);
  ZeroedArray<uint8_t> seen(count);  // 1: on a path; 2: on a path that ends in the void
  for (const std::vector<uint32_t>& row : source_rows) {
    for (const uint32_t source : row) {
      for (uint32_t q = source; q != kNowhere && q != kIntoVoid;) {
        if (seen[q]) break;  // its path was walked, and counted, before
        seen[q] = 1;
        reached.push_back(q);
        next[q] = follow(q, &room[q]);
        const uint32_t p = next[q];
        if (p != kNowhere && p != kIntoVoid) ++arrivals[p];
        q = p;
      }
    }
  }
  source_rows = {};
  // Kahn's order: a texel is taken once every path into it has been; the
  // kept heights fall strictly along the paths, so every texel is.
  std::vector<uint32_t> order;
  order.reserve(reached.size());
  for (uint32_t k : reached) {
    if (arrivals[k] == 0) order.push_back(k);
  }
  for (size_t r = 0; r < order.size(); ++r) {
    const uint32_t p = next[order[r]];
    if (p != kNowhere && p != kIntoVoid && --arrivals[p] == 0) order.push_back(p);
  }
  // Only paths that end in the void drain: snow sent down one that ends in
  // a hollow would pile up there as a spike (the relaxation spreads what
  // the next pass finds there, the settling routing pours it).
  for (size_t r = order.size(); r-- > 0;) {
    const uint32_t k = order[r], p = next[k];
    seen[k] = p == kIntoVoid || (p != kNowhere && seen[p] == 2) ? 2 : 1;
  }
  ZeroedArray<float> change(count);  // collects the arrivals, then the change of depth (m)
  for (const uint32_t k : order) {
    if (seen[k] != 2) continue;
    const float arrived = change[k];
    const float stays = std::min(arrived, room[k]);
    const float passes = (flow[k] + arrived) - stays;
    const uint32_t p = next[k];
    if (p == kIntoVoid) {
      lost[k] = lost[k] + passes;
    } else {
      change[p] = change[p] + passes;
    }
    change[k] = stays - flow[k];
  }
  std::vector<uint32_t> changed;
  for (uint32_t k : reached) {
    if (change[k] == 0.0f) continue;
    depth[k] = depth[k] + change[k];
    changed.push_back(k);
  }
  return changed;
}

}  // namespace snow
