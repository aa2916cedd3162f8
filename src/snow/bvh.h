#pragma once
// A bounding volume hierarchy over a triangle soup, for occlusion rays: the
// CPU reference passes use it directly, the coverage pass uploads it for its
// exact ray casts (shaders/coverage_exact.glsl mirrors occluded()). Binned
// surface area heuristic splits, or the splits of the triangles' Morton
// order (Lauterbach et al. 2009, "Fast BVH construction on GPUs": the LBVH)
// where few rays will walk it; up to 4 triangles per leaf. Nodes are
// stored in pre-order (an inner node's left child follows it, its right
// subtree follows the left one) with skip links, so rays walk the tree
// without a stack; the node layout is what std430 storage buffers read as
// is, and the triangles are stored in leaf order.
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace snow {

class Bvh {
 public:
  Bvh() = default;
  /// 32 bytes, the std430 layout of struct { vec3 min; uint first; vec3 max; uint count; }.
  struct Node {
    glm::vec3 min{0.0f};
    uint32_t first = 0;  // leaf: first triangle (leaf order); inner: the node after its subtree
    glm::vec3 max{0.0f};
    uint32_t count = 0;  // leaf: triangle count (> 0); 0 for inner nodes
  };

  /// How the tree is split. Both trees answer every query alike; they
  /// differ in build time against walk time.
  enum class Build {
    Sah,     // binned surface area heuristic: the best walks, for many rays
    Morton,  // linear (Morton order) BVH: built in a fraction of the time, walks a little longer
  };

  /// Builds over triangles t = (corners[3t], corners[3t+1], corners[3t+2])
  /// (a trailing partial triangle is ignored); keeps its own copy, in leaf
  /// order.
  explicit Bvh(const std::vector<glm::vec3>& corners, Build how = Build::Sah);

  static constexpr uint32_t kNone = ~0u;
  /// The first triangle (leaf order) the walk finds that the ray origin + t *
  /// direction hits (either side) for some t in (t_min, t_max); kNone when
  /// there is none. direction need not be unit length.
  uint32_t first_hit(const glm::vec3& origin, const glm::vec3& direction, float t_min,
                     float t_max) const;
  /// True when the ray hits a triangle: first_hit(...) != kNone.
  bool occluded(const glm::vec3& origin, const glm::vec3& direction, float t_min,
                float t_max) const {
    return first_hit(origin, direction, t_min, t_max) != kNone;
  }

  /// True when occluded(origin, direction, t_min, t_max) reaches the leaf
  /// holding triangle t (leaf order) and finds one of its triangles hit: the
  /// ray hits the box of every node on the way down to that leaf, and a
  /// triangle of it. occluded() is then true: a cheap test of a likely
  /// occluder before the walk (false for t out of range).
  bool reaches(uint32_t t, const glm::vec3& origin, const glm::vec3& direction, float t_min,
               float t_max) const;

  size_t triangle_count() const { return corners_.size() / 3; }
  /// The nodes, root first (empty for no triangles).
  const std::vector<Node>& nodes() const { return nodes_; }
  /// The triangles' corners in leaf order (3 per triangle).
  const std::vector<glm::vec3>& corners() const { return corners_; }
  /// Original index of the triangle at each leaf-order position.
  const std::vector<uint32_t>& order() const { return order_; }

 private:
  // A triangle as the build sorts it: the build reorders these in place, so
  // it reads each node's range in memory order.
  struct Prim {
    glm::vec3 lo, hi, c;  // a triangle's box and centroid
    uint32_t index;       // its original index
  };
  // Builds the subtree over prims[first, first + count) into `out`, pre-order
  // from out.size(); its skip links index `out`. The two halves of the top
  // `parallel_levels` splits are built on two threads each, into vectors of
  // their own, and spliced in: the same nodes as a serial build. A node of
  // kLargeNode triangles or more runs its loops on all cores, its partition
  // through scratch[first, first + count) (null where no node is that large).
  void build(uint32_t first, uint32_t count, Prim* prims, Prim* scratch, std::vector<Node>& out,
             int parallel_levels);
  // The same over corners_ in Morton order (codes[k] of triangle k): each
  // node splits where the highest bit in which its codes differ turns on;
  // boxes are the union of the children's.
  void build_morton(uint32_t first, uint32_t count, const std::vector<uint32_t>& codes);

  std::vector<glm::vec3> corners_;
  std::vector<uint32_t> order_;
  std::vector<Node> nodes_;
};

}  // namespace snow
