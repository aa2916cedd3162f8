// Flat grounds (contract: scene/flat_ground.h).
#include "scene/flat_ground.h"

#include <algorithm>
#include <cmath>

namespace snow {
namespace {

// Area (m^2) that a level ground's triangles must cover of its bounds'.
constexpr double kFillShare = 0.999;

}  // namespace

std::optional<FlatGround> find_flat_ground(const Scene& scene) {
  const size_t objects = scene.objects.size();
  if (objects < 2) return std::nullopt;
  std::vector<Bounds> bounds(objects);
  for (size_t o = 0; o < objects; ++o) bounds[o] = object_bounds(scene, int(o));
  std::optional<FlatGround> best;
  double best_area = 0.0;
  for (size_t o = 0; o < objects; ++o) {
    const Bounds& b = bounds[o];
    if (b.empty()) continue;
    const glm::vec3 size = b.size();
    const double width = std::max(size.x, size.z);
    if (!(width > 0.0) || size.y > 1e-3 * width) continue;  // not level
    const double rect = double(size.x) * double(size.z);
    if (!(rect > best_area)) continue;
    double area = 0.0;
    const SceneObject& so = scene.objects[o];
    for (size_t t = so.first_triangle; t < size_t(so.first_triangle) + so.triangle_count; ++t) {
      const glm::dvec3 a = scene.positions[3 * t], p = scene.positions[3 * t + 1],
                       c = scene.positions[3 * t + 2];
      area += 0.5 * std::abs(glm::cross(p - a, c - a).y);
    }
    if (area < kFillShare * rect) continue;  // holes, or overlapping triangles count twice
    FlatGround g;
    g.object = int(o);
    g.y = b.max.y;
    g.bounds = b;
    bool under = true;
    for (size_t p = 0; p < objects && under; ++p) {
      if (p == o || bounds[p].empty()) continue;
      g.detail.extend(bounds[p].min);
      g.detail.extend(bounds[p].max);
      under = bounds[p].min.y >= b.min.y - 1e-3f * float(width);
    }
    if (!under || g.detail.empty()) continue;
    if (g.detail.min.x < b.min.x || g.detail.max.x > b.max.x || g.detail.min.z < b.min.z ||
        g.detail.max.z > b.max.z) {
      continue;
    }
    best = g;
    best_area = rect;
  }
  return best;
}

Scene with_ground_clipped(const Scene& scene, const FlatGround& ground, const Bounds& region) {
  Scene out = without_geometry(scene);
  const bool shading = !scene.normals.empty();
  const bool uvs = !scene.uvs.empty();
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    SceneObject object = scene.objects[o];
    const size_t begin = size_t(object.first_triangle) * 3;
    const size_t end = begin + size_t(object.triangle_count) * 3;
    object.first_triangle = uint32_t(out.triangle_count());
    if (int(o) == ground.object) {
      const float y = ground.y;
      const glm::vec3 a(region.min.x, y, region.min.z), b(region.max.x, y, region.min.z),
          c(region.max.x, y, region.max.z), d(region.min.x, y, region.max.z);
      for (const glm::vec3& p : {a, c, b, a, d, c}) out.positions.push_back(p);  // facing +Y
      if (shading) out.normals.insert(out.normals.end(), 6, glm::vec3(0.0f, 1.0f, 0.0f));
      if (uvs) {
        for (const glm::vec3& p : {a, c, b, a, d, c}) out.uvs.emplace_back(p.x, p.z);
      }
      object.triangle_count = 2;
    } else {
      out.positions.insert(out.positions.end(), scene.positions.begin() + ptrdiff_t(begin),
                           scene.positions.begin() + ptrdiff_t(end));
      if (shading) {
        out.normals.insert(out.normals.end(), scene.normals.begin() + ptrdiff_t(begin),
                           scene.normals.begin() + ptrdiff_t(end));
      }
      if (uvs) {
        out.uvs.insert(out.uvs.end(), scene.uvs.begin() + ptrdiff_t(begin),
                       scene.uvs.begin() + ptrdiff_t(end));
      }
    }
    out.objects.push_back(object);
  }
  for (const glm::vec3& p : out.positions) out.bounds.extend(p);
  return out;
}

}  // namespace snow
