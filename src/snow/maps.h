#pragma once
// Snow amount maps: the scene seen from straight above as up to L stacked
// surfaces per texel (Tokoi 2006; height spans after Onoue and Nishita).
//
// Grid: texel (i, j) covers world x in [origin.x + i*texel, +texel) and world
// z in [origin.y + j*texel, +texel); its centre is grid.center(i, j).
// Layers are ordered top-down: layer 0 is the highest surface under the sky.
// Every per-layer array has layers*height*width entries, index(l, i, j).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "core/default_init.h"

namespace snow {

/// A per layer texel array of SnowMaps: its resize leaves the new elements
/// unwritten, for SnowMaps to fill on all cores.
template <class T>
using LayerArray = std::vector<T, DefaultInitAllocator<T>>;

struct MapGrid {
  glm::vec2 origin{0.0f};  // world (x, z) of texel (0,0)'s corner, metres
  float texel = 0.1f;      // texel edge, metres
  int width = 0;           // texels along +x
  int height = 0;          // texels along +z

  glm::vec2 center(int i, int j) const {
    return origin + glm::vec2((float(i) + 0.5f) * texel, (float(j) + 0.5f) * texel);
  }
  size_t texels() const { return size_t(width) * size_t(height); }
};

constexpr float kNoSurface = std::numeric_limits<float>::quiet_NaN();
constexpr float kOpenSky = std::numeric_limits<float>::infinity();

struct SnowMaps {
  MapGrid grid;
  int layers = 0;  // L

  // Per layer texel (size layers * grid.texels()):
  LayerArray<float> ground;      // surface height (world y, m); NaN where no surface
  LayerArray<float> ceiling;     // height of the surface above; +inf for layer 0
  LayerArray<glm::vec3> normal;  // geometric normal as wound (may face down); 0 if none
  LayerArray<int32_t> object;    // scene object index; -1 where no surface

  uint64_t overflow_columns = 0;  // columns holding more than `layers` surfaces
  // Per column (j * width + i): the layer of the surface that bridge_gaps
  // laid across a narrow gap there (snow/bridge.h), -1 where none; empty
  // where none was laid.
  std::vector<int8_t> bridge;

  size_t index(int l, int i, int j) const {
    return (size_t(l) * size_t(grid.height) + size_t(j)) * size_t(grid.width) + size_t(i);
  }
  bool has_surface(int l, int i, int j) const { return !std::isnan(ground[index(l, i, j)]); }
  /// Allocates every array for `layers` layers of `grid`, all empty.
  void allocate(const MapGrid& g, int layer_count);
  /// Appends one empty layer. Within a capacity set by reserve_layers, the
  /// arrays neither move nor copy.
  void add_layer();
  /// Reserves capacity for `count` layers: address space only, so layers
  /// never added cost no memory.
  void reserve_layers(int count);
  /// Drops the trailing layers that hold no surface anywhere, so that later
  /// stages neither store nor compute them; keeps at least one layer and
  /// frees the memory. Returns the number of layers dropped.
  int drop_empty_layers();
};

inline void SnowMaps::reserve_layers(int count) {
  const size_t n = size_t(std::max(count, 0)) * grid.texels();
  ground.reserve(n);
  ceiling.reserve(n);
  normal.reserve(n);
  object.reserve(n);
}

inline int SnowMaps::drop_empty_layers() {
  const size_t texels = grid.texels();
  int used = layers;
  while (used > 1) {
    const auto first = ground.begin() + ptrdiff_t(size_t(used - 1) * texels);
    if (std::any_of(first, first + ptrdiff_t(texels), [](float g) { return !std::isnan(g); })) {
      break;
    }
    --used;
  }
  const int dropped = layers - used;
  if (dropped > 0) {
    const size_t n = size_t(used) * texels;
    const auto shrink = [n](auto& v) {
      v.resize(n);
      v.shrink_to_fit();
    };
    shrink(ground);
    shrink(ceiling);
    shrink(normal);
    shrink(object);
    layers = used;
  }
  return dropped;
}

}  // namespace snow
