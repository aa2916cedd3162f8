// Sky enclosures (contract: scene/enclosure.h).
#include "scene/enclosure.h"

#include <algorithm>
#include <cmath>

namespace snow {
namespace {

// Samples per side of the footprint grid that the cover is measured on.
constexpr int kCoverSamples = 32;

// The share of the kCoverSamples^2 sample points over `footprint` (x, z)
// under which a triangle of object `o` lies at or above `above` (world y).
double cover_share(const Scene& scene, const SceneObject& o, const Bounds& footprint, float above) {
  const int n = kCoverSamples;
  const glm::vec2 lo(footprint.min.x, footprint.min.z), hi(footprint.max.x, footprint.max.z);
  const glm::vec2 cell = glm::max((hi - lo) / float(n), glm::vec2(1e-30f));
  std::vector<uint8_t> covered(size_t(n) * size_t(n), 0);
  const size_t first = size_t(o.first_triangle);
  for (size_t t = first; t < first + o.triangle_count && 3 * t + 2 < scene.positions.size(); ++t) {
    const glm::vec3 a = scene.positions[3 * t], b = scene.positions[3 * t + 1],
                    c = scene.positions[3 * t + 2];
    if (std::max({a.y, b.y, c.y}) < above) continue;
    const float det = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
    if (!(std::abs(det) > 0.0f)) continue;  // seen edge-on from above
    const int i0 = std::max(0, int(std::floor((std::min({a.x, b.x, c.x}) - lo.x) / cell.x - 0.5f)));
    const int i1 =
        std::min(n - 1, int(std::ceil((std::max({a.x, b.x, c.x}) - lo.x) / cell.x - 0.5f)));
    const int j0 = std::max(0, int(std::floor((std::min({a.z, b.z, c.z}) - lo.y) / cell.y - 0.5f)));
    const int j1 =
        std::min(n - 1, int(std::ceil((std::max({a.z, b.z, c.z}) - lo.y) / cell.y - 0.5f)));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        uint8_t& hit = covered[size_t(j) * size_t(n) + size_t(i)];
        if (hit) continue;
        const float x = lo.x + (float(i) + 0.5f) * cell.x, z = lo.y + (float(j) + 0.5f) * cell.y;
        // Barycentric coordinates of (x, z) in the triangle's projection.
        const float u = ((x - a.x) * (c.z - a.z) - (c.x - a.x) * (z - a.z)) / det;
        const float v = ((b.x - a.x) * (z - a.z) - (x - a.x) * (b.z - a.z)) / det;
        if (u < 0.0f || v < 0.0f || u + v > 1.0f) continue;
        if (a.y + u * (b.y - a.y) + v * (c.y - a.y) >= above) hit = 1;
      }
    }
  }
  size_t count = 0;
  for (uint8_t hit : covered) count += hit;
  return double(count) / double(covered.size());
}

}  // namespace

std::vector<int> find_sky_enclosures(const Scene& scene, double min_cover) {
  const size_t objects = scene.objects.size();
  std::vector<Bounds> bounds(objects);
  for (size_t o = 0; o < objects; ++o) bounds[o] = object_bounds(scene, int(o));
  std::vector<uint8_t> left(objects, 1);
  std::vector<int> found;
  for (;;) {
    int outer = -1;
    for (size_t o = 0; o < objects && outer < 0; ++o) {
      if (!left[o] || bounds[o].empty()) continue;
      Bounds rest;  // every other object left
      size_t others = 0;
      for (size_t p = 0; p < objects; ++p) {
        if (p == o || !left[p] || bounds[p].empty()) continue;
        rest.extend(bounds[p].min);
        rest.extend(bounds[p].max);
        ++others;
      }
      if (others == 0) continue;
      const glm::vec3 slack = 1e-3f * glm::max(rest.size(), glm::vec3(1e-6f));
      const Bounds& b = bounds[o];
      const bool holds = b.min.x <= rest.min.x + slack.x && b.max.x >= rest.max.x - slack.x &&
                         b.min.z <= rest.min.z + slack.z && b.max.z >= rest.max.z - slack.z &&
                         b.max.y > rest.max.y;
      if (holds && cover_share(scene, scene.objects[o], rest, rest.max.y) >= min_cover) {
        outer = int(o);
      }
    }
    if (outer < 0) break;
    found.push_back(outer);
    left[size_t(outer)] = 0;
  }
  return found;
}

}  // namespace snow
