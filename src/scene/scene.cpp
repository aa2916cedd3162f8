#include "scene/scene.h"

#include <algorithm>

#include "core/error.h"
#include "core/parallel.h"

namespace snow {

Scene without_geometry(const Scene& scene) {
  Scene out;
  out.materials = scene.materials;
  out.images = scene.images;
  out.stats = scene.stats;
  out.warnings = scene.warnings;
  out.source = scene.source;
  out.generator = scene.generator;
  out.lines = scene.lines;
  out.motions = scene.motions;
  return out;
}

Bounds object_bounds(const Scene& scene, int object) {
  if (object < 0 || object >= int(scene.objects.size()))
    throw InputError("scene: object " + std::to_string(object) + " does not exist");
  const SceneObject& o = scene.objects[size_t(object)];
  const size_t first = size_t(o.first_triangle) * 3;
  const size_t end = std::min(first + size_t(o.triangle_count) * 3, scene.positions.size());
  Bounds b;
  for (size_t k = first; k < end; ++k) b.extend(scene.positions[k]);
  return b;
}

int Scene::object_of_triangle(size_t t) const {
  auto it =
      std::upper_bound(objects.begin(), objects.end(), t,
                       [](size_t tri, const SceneObject& o) { return tri < o.first_triangle; });
  if (it == objects.begin()) return -1;
  --it;
  return t < size_t(it->first_triangle) + it->triangle_count ? int(it - objects.begin()) : -1;
}

glm::vec3 triangle_normal(const Scene& scene, size_t t) {
  const glm::dvec3 a(scene.positions[3 * t]);
  const glm::dvec3 n = glm::cross(glm::dvec3(scene.positions[3 * t + 1]) - a,
                                  glm::dvec3(scene.positions[3 * t + 2]) - a);
  const double len = glm::length(n);
  return len > 0 ? glm::vec3(n / len) : glm::vec3(0.0f);
}

TriangleAttributes triangle_attributes(const Scene& scene) {
  const size_t count = scene.triangle_count();
  TriangleAttributes out;
  out.normal.resize(count);
  out.object.assign(count, -1);
  constexpr size_t kChunk = size_t(1) << 14;
  parallel_for_ranges(count, kChunk, [&](size_t begin, size_t end) {
    for (size_t t = begin; t < end; ++t) out.normal[t] = triangle_normal(scene, t);
  });
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const SceneObject& obj = scene.objects[o];
    for (uint32_t k = 0; k < obj.triangle_count && obj.first_triangle + k < count; ++k) {
      out.object[obj.first_triangle + k] = int32_t(o);
    }
  }
  return out;
}

}  // namespace snow
