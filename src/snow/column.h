#pragma once
// The one rule that relates snow in neighbouring columns, shared by the
// stabilizer (CPU reference and GPU, mirrored in shaders/column.glsl) and by
// patch finding in polygonize: "neighbours are found by height, not by layer
// index" (DESIGN.md, snow amount maps).
#include "snow/maps.h"

namespace snow {

/// The layer of column (i, j) onto which snow at height h (world y, m) coming
/// from a neighbour comes to rest: the highest layer whose snow top
/// (ground + depth) lies at or below h and whose free gap (up to its ceiling)
/// contains h. Returns -1 when there is none (a wall is in the way, or the
/// column is empty). `depth` has the maps' layer layout.
inline int landing_layer(const SnowMaps& maps, const float* depth, int i, int j, float h) {
  for (int l = 0; l < maps.layers; ++l) {
    const size_t k = maps.index(l, i, j);
    const float g = maps.ground[k];
    if (std::isnan(g)) return -1;  // layers are packed from the top: no more surfaces
    if (h >= maps.ceiling[k]) return -1;  // h lies inside the solid above this gap
    if (g + depth[k] <= h) return l;
  }
  return -1;
}

}  // namespace snow
