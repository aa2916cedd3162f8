#pragma once
// A small bounding volume hierarchy over a triangle soup for the CPU
// reference passes (occlusion rays). Median split on the longest centroid
// axis, up to 4 triangles per leaf; plenty for test scenes.
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace snow {

class Bvh {
 public:
  Bvh() = default;
  /// Builds over triangles t = (corners[3t], corners[3t+1], corners[3t+2]).
  explicit Bvh(std::vector<glm::vec3> corners);

  /// True when the ray origin + t * direction hits a triangle (either side)
  /// for some t in (t_min, t_max). direction need not be unit length.
  bool occluded(const glm::vec3& origin, const glm::vec3& direction, float t_min,
                float t_max) const;

  size_t triangle_count() const { return corners_.size() / 3; }

 private:
  struct Node {
    glm::vec3 min, max;
    uint32_t first = 0;  // leaf: first index into order_; inner: right child (left = this + 1)
    uint32_t count = 0;  // leaf: triangle count; 0 for inner nodes
  };
  uint32_t build(uint32_t first, uint32_t count, std::vector<glm::vec3>& centroids);

  std::vector<glm::vec3> corners_;
  std::vector<uint32_t> order_;
  std::vector<Node> nodes_;
};

}  // namespace snow
