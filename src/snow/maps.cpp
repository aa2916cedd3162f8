#include "snow/maps.h"

#include <algorithm>

#include "core/parallel.h"

namespace snow {
namespace {

// Layer texels per task of the fills below (1.5 MiB of the four arrays).
constexpr size_t kFillChunk = size_t(1) << 16;

// Sizes the arrays to n layer texels and marks those from `first` on as
// holding no surface, on all cores. The pages are fresh, so the writing is
// mostly the kernel's faulting them in, which on one core would be a large
// share of the CPU peel on a large map.
void resize_cleared(SnowMaps& maps, size_t first, size_t n) {
  maps.ground.resize(n);
  maps.ceiling.resize(n);
  maps.normal.resize(n);
  maps.object.resize(n);
  if (n <= first) return;
  parallel_for_ranges(n - first, kFillChunk, [&](size_t begin, size_t end) {
    const auto at = [first](size_t k) { return ptrdiff_t(first + k); };
    std::fill(maps.ground.begin() + at(begin), maps.ground.begin() + at(end), kNoSurface);
    std::fill(maps.ceiling.begin() + at(begin), maps.ceiling.begin() + at(end), kOpenSky);
    std::fill(maps.normal.begin() + at(begin), maps.normal.begin() + at(end), glm::vec3(0.0f));
    std::fill(maps.object.begin() + at(begin), maps.object.begin() + at(end), -1);
  });
}

}  // namespace

void SnowMaps::allocate(const MapGrid& g, int layer_count) {
  grid = g;
  layers = layer_count;
  overflow_columns = 0;
  // The old arrays go first: the fill then writes each page once.
  ground = {};
  ceiling = {};
  normal = {};
  object = {};
  bridge = {};
  resize_cleared(*this, 0, size_t(std::max(layers, 0)) * grid.texels());
}

void SnowMaps::add_layer() {
  resize_cleared(*this, size_t(layers) * grid.texels(), size_t(layers + 1) * grid.texels());
  ++layers;
}

}  // namespace snow
