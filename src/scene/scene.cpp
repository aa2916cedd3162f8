#include "scene/scene.h"

#include <algorithm>

namespace snow {

int Scene::object_of_triangle(size_t t) const {
  auto it = std::upper_bound(objects.begin(), objects.end(), t,
                             [](size_t tri, const SceneObject& o) { return tri < o.first_triangle; });
  if (it == objects.begin()) return -1;
  --it;
  return t < size_t(it->first_triangle) + it->triangle_count ? int(it - objects.begin()) : -1;
}

}  // namespace snow
