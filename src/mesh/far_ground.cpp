// The open ground's snow beyond the maps (contract: mesh/far_ground.h).
#include "mesh/far_ground.h"

#include <array>

namespace snow {

SnowPatch far_ground_snow(const FlatGround& ground, const Bounds& region, float depth,
                          float overlap, float seam, float bottom_offset, const std::string& name) {
  SnowPatch patch;
  patch.object = ground.object;
  TriMesh& m = patch.mesh;
  m.name = name;
  const float top = ground.y + depth - seam, bottom = ground.y - bottom_offset;
  const glm::vec2 o0(ground.bounds.min.x, ground.bounds.min.z),
      o1(ground.bounds.max.x, ground.bounds.max.z);
  const glm::vec2 i0(region.min.x + overlap, region.min.z + overlap),
      i1(region.max.x - overlap, region.max.z - overlap);
  // Corners counter-clockwise seen from above (+Y), from (min x, min z).
  const auto corners = [](glm::vec2 a, glm::vec2 b) {
    return std::array<glm::vec2, 4>{a, glm::vec2(a.x, b.y), b, glm::vec2(b.x, a.y)};
  };
  const std::array<glm::vec2, 4> outer = corners(o0, o1), inner = corners(i0, i1);
  // Vertices: outer top 0-3, inner top 4-7, outer bottom 8-11, inner bottom 12-15.
  for (const auto& [ring, y] : {std::pair{outer, top}, std::pair{inner, top},
                                std::pair{outer, bottom}, std::pair{inner, bottom}}) {
    for (const glm::vec2& c : ring) m.positions.emplace_back(c.x, y, c.y);
  }
  const auto quad = [&](uint32_t a, uint32_t b, uint32_t c, uint32_t d) {  // a b c d CCW
    for (uint32_t v : {a, b, c, a, c, d}) m.indices.push_back(v);
  };
  for (uint32_t k = 0; k < 4; ++k) {
    const uint32_t n = (k + 1) % 4;
    quad(k, n, 4 + n, 4 + k);            // top ring, facing +Y
    quad(8 + k, 12 + k, 12 + n, 8 + n);  // bottom ring, facing -Y
    quad(k, 8 + k, 8 + n, n);            // outer wall, facing out
    quad(4 + k, 4 + n, 12 + n, 12 + k);  // inner wall, facing into the hole
  }
  // Flat normals are wrong on shared corners; a box's faces meet at right
  // angles, so each vertex takes the top's or the bottom's normal.
  for (const glm::vec3& p : m.positions) {
    m.normals.emplace_back(0.0f, p.y == top ? 1.0f : -1.0f, 0.0f);
    m.uvs.emplace_back(p.x, p.z);
  }
  m.material = 0;
  const double outer_area = double(o1.x - o0.x) * double(o1.y - o0.y);
  const double hole = double(i1.x - i0.x) * double(i1.y - i0.y);
  patch.area = outer_area - hole;
  patch.volume = patch.area * double(top - bottom);
  patch.depth_volume = patch.area * double(depth);
  return patch;
}

}  // namespace snow
