// The scene's frame (contract: scene/frame.h).
#include "scene/frame.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace snow {

bool z_up_from_name(const std::string& name) {
  if (name == "y") return false;
  if (name == "z") return true;
  throw InputError("--up must be y or z, got '" + name + "'");
}

void to_metres_y_up(Scene& scene, const FileFrame& frame) {
  if (frame.is_identity()) return;
  const auto turn = [&](const glm::vec3& v) { return frame.z_up ? glm::vec3(v.x, v.z, -v.y) : v; };
  scene.bounds = Bounds{};
  for (glm::vec3& p : scene.positions) {
    p = turn(p) * frame.unit_scale;
    scene.bounds.extend(p);
  }
  for (glm::vec3& n : scene.normals) n = turn(n);
  for (SceneLines& lines : scene.lines)
    for (glm::vec3& p : lines.segments) p = turn(p) * frame.unit_scale;
  // The frame's map F (scale, then turn) as a matrix; a motion M in the
  // file's frame is F * M * F^-1 in the run's.
  const double s = frame.unit_scale;
  const glm::dmat4 map = frame.z_up ? glm::dmat4(glm::dvec4(s, 0, 0, 0), glm::dvec4(0, 0, -s, 0),
                                                 glm::dvec4(0, s, 0, 0), glm::dvec4(0, 0, 0, 1))
                                    : glm::dmat4(glm::dvec4(s, 0, 0, 0), glm::dvec4(0, s, 0, 0),
                                                 glm::dvec4(0, 0, s, 0), glm::dvec4(0, 0, 0, 1));
  const glm::dmat4 unmap = glm::inverse(map);
  for (NodeMotion& motion : scene.motions)
    for (glm::mat4& move : motion.moves) move = glm::mat4(map * glm::dmat4(move) * unmap);
}

void to_file_frame(TriMesh& mesh, const FileFrame& frame) {
  if (frame.is_identity()) return;
  const auto turn_back = [&](const glm::vec3& v) {
    return frame.z_up ? glm::vec3(v.x, -v.z, v.y) : v;
  };
  for (glm::vec3& p : mesh.positions) p = turn_back(p / frame.unit_scale);
  for (glm::vec3& n : mesh.normals) n = turn_back(n);
}

FrameFigures frame_figures(const Scene& scene) {
  FrameFigures out;
  std::vector<float> sizes;
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const Bounds b = object_bounds(scene, int(o));
    if (!b.empty()) {
      const glm::vec3 s = b.size();
      sizes.push_back(std::max({s.x, s.y, s.z}));
    }
  }
  if (!sizes.empty()) {
    std::nth_element(sizes.begin(), sizes.begin() + ptrdiff_t(sizes.size() / 2), sizes.end());
    out.median_object_size = sizes[sizes.size() / 2];
  }
  const double facing = std::cos(25.0 * M_PI / 180.0);
  for (size_t t = 0; 3 * t + 2 < scene.positions.size(); ++t) {
    const glm::dvec3 a = scene.positions[3 * t], b = scene.positions[3 * t + 1],
                     c = scene.positions[3 * t + 2];
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const double twice_area = glm::length(n);
    if (!(twice_area > 0.0)) continue;
    if (std::abs(n.y) >= facing * twice_area) out.area_facing_y += 0.5 * twice_area;
    if (std::abs(n.z) >= facing * twice_area) out.area_facing_z += 0.5 * twice_area;
  }
  return out;
}

}  // namespace snow
