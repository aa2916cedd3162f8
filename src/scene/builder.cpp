// Scenes built in code (see builder.h). Every closed primitive is assembled
// from convex faces whose vertices are welded by exact position, each face
// oriented against an outward hint, so the result is a closed oriented
// 2-manifold by construction (tests/test_builder.cpp checks it).
#include "scene/builder.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <tuple>
#include <utility>

#include "core/error.h"

namespace snow {
namespace {

constexpr float kPi = 3.14159265358979323846f;
const glm::vec4 kDefaultColor{0.6f, 0.6f, 0.6f, 1.0f};

float radians(float deg) { return deg * kPi / 180.0f; }

/// Collects welded vertices and triangles oriented against outward hints.
class Shape {
 public:
  uint32_t vertex(const glm::vec3& p) {
    auto key = std::make_tuple(p.x, p.y, p.z);
    auto it = index_.find(key);
    if (it != index_.end()) return it->second;
    const auto i = uint32_t(positions.size());
    positions.push_back(p);
    index_.emplace(key, i);
    return i;
  }
  /// Triangle a, b, c, flipped when its normal points away from `outward`.
  void tri(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& outward) {
    const glm::vec3 n = glm::cross(b - a, c - a);
    uint32_t ia = vertex(a), ib = vertex(b), ic = vertex(c);
    if (glm::dot(n, outward) < 0.0f) std::swap(ib, ic);
    indices.insert(indices.end(), {ia, ib, ic});
  }
  /// Convex quad a, b, c, d (in cyclic order), oriented against `outward`.
  void quad(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& d,
            const glm::vec3& outward) {
    tri(a, b, c, outward);
    tri(a, c, d, outward);
  }

  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;

 private:
  std::map<std::tuple<float, float, float>, uint32_t> index_;
};

/// Closed box [lo, hi] into `s`; `inward` flips it (a cavity).
void box_faces(Shape& s, const glm::vec3& lo, const glm::vec3& hi, bool inward = false) {
  const float f = inward ? -1.0f : 1.0f;
  auto p = [&](int x, int y, int z) {
    return glm::vec3(x ? hi.x : lo.x, y ? hi.y : lo.y, z ? hi.z : lo.z);
  };
  s.quad(p(0, 0, 0), p(0, 1, 0), p(0, 1, 1), p(0, 0, 1), f * glm::vec3(-1, 0, 0));
  s.quad(p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1), f * glm::vec3(1, 0, 0));
  s.quad(p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1), f * glm::vec3(0, -1, 0));
  s.quad(p(0, 1, 0), p(1, 1, 0), p(1, 1, 1), p(0, 1, 1), f * glm::vec3(0, 1, 0));
  s.quad(p(0, 0, 0), p(1, 0, 0), p(1, 1, 0), p(0, 1, 0), f * glm::vec3(0, 0, -1));
  s.quad(p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1), f * glm::vec3(0, 0, 1));
}

/// Closed triangular prism along x from x0 to x1 over the (z, y) triangle
/// a, b, c.
void prism_x_faces(Shape& s, float x0, float x1, const glm::vec2& a, const glm::vec2& b,
                   const glm::vec2& c) {
  auto p = [](float x, const glm::vec2& zy) { return glm::vec3(x, zy.y, zy.x); };
  s.tri(p(x0, a), p(x0, b), p(x0, c), glm::vec3(-1, 0, 0));
  s.tri(p(x1, a), p(x1, b), p(x1, c), glm::vec3(1, 0, 0));
  const glm::vec2 centroid = (a + b + c) / 3.0f;
  const std::array<glm::vec2, 3> v{a, b, c};
  for (int k = 0; k < 3; ++k) {
    const glm::vec2 u = v[k], w = v[(k + 1) % 3];
    const glm::vec2 out2 = (u + w) * 0.5f - centroid;
    s.quad(p(x0, u), p(x1, u), p(x1, w), p(x0, w), glm::vec3(0, out2.y, out2.x));
  }
}

void require(bool ok, const std::string& name, const std::string& what) {
  if (!ok) throw InputError("scene builder: object '" + name + "': " + what);
}

bool finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

glm::vec3 flat_normal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 n = glm::cross(b - a, c - a);
  const float len = glm::length(n);
  return len > 0.0f ? n / len : glm::vec3(0, 1, 0);
}

}  // namespace

// --- SceneBuilder -------------------------------------------------------------

int SceneBuilder::add_material(const std::string& name, const glm::vec4& base_color,
                               float roughness, float metallic) {
  MeshMaterial m;
  m.name = name;
  m.base_color = base_color;
  m.roughness = roughness;
  m.metallic = metallic;
  materials_.push_back(m);
  return int(materials_.size()) - 1;
}

int SceneBuilder::add_object(BuilderObject object) {
  require(object.material >= -1 && object.material < int(materials_.size()), object.name,
          "material " + std::to_string(object.material) + " does not exist");
  objects_.push_back(std::move(object));
  return int(objects_.size()) - 1;
}

int SceneBuilder::add_mesh(const std::string& name, const std::vector<glm::vec3>& positions,
                           const std::vector<uint32_t>& indices, int material) {
  require(indices.size() % 3 == 0, name, "index count is not a multiple of 3");
  for (uint32_t i : indices)
    require(i < positions.size(), name, "index " + std::to_string(i) + " out of range");
  for (const glm::vec3& p : positions) require(finite(p), name, "non-finite position");
  BuilderObject o;
  o.name = name;
  o.positions = positions;
  o.indices = indices;
  o.material = material;
  o.closed = check_topology(positions, indices).closed();
  return add_object(std::move(o));
}

int SceneBuilder::add_box(const std::string& name, const glm::vec3& min, const glm::vec3& max,
                          int material) {
  require(finite(min) && finite(max) && min.x < max.x && min.y < max.y && min.z < max.z, name,
          "box needs min < max");
  Shape s;
  box_faces(s, min, max);
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::add_plane(const std::string& name, float y, const glm::vec2& min_xz,
                            const glm::vec2& max_xz, int material) {
  require(std::isfinite(y) && min_xz.x < max_xz.x && min_xz.y < max_xz.y, name,
          "plane needs min < max");
  Shape s;
  s.quad(glm::vec3(min_xz.x, y, min_xz.y), glm::vec3(max_xz.x, y, min_xz.y),
         glm::vec3(max_xz.x, y, max_xz.y), glm::vec3(min_xz.x, y, max_xz.y), glm::vec3(0, 1, 0));
  return add_object({name, std::move(s.positions), std::move(s.indices), material, false});
}

float SceneBuilder::gable_roof_ridge_y(const glm::vec3& min, const glm::vec3& max, float pitch_deg,
                                       float thickness) {
  const float t = std::tan(radians(pitch_deg));
  return min.y + 0.5f * (max.z - min.z) * t + thickness / std::cos(radians(pitch_deg));
}

int SceneBuilder::add_gable_roof(const std::string& name, const glm::vec3& min,
                                 const glm::vec3& max, float pitch_deg, float overhang,
                                 float thickness, int material) {
  require(finite(min) && finite(max) && min.x < max.x && min.z < max.z, name,
          "roof needs min < max in x and z");
  require(pitch_deg > 0.0f && pitch_deg < 80.0f, name, "roof pitch must be in (0, 80) degrees");
  require(overhang >= 0.0f && thickness > 0.0f, name, "roof needs overhang >= 0 and thickness > 0");
  const float slope = std::tan(radians(pitch_deg));
  const float rise = thickness / std::cos(radians(pitch_deg));
  const float zm = 0.5f * (min.z + max.z);
  const float za = min.z - overhang, zc = max.z + overhang;
  const float y_eave = min.y - overhang * slope;
  const float y_ridge = min.y + 0.5f * (max.z - min.z) * slope;
  const float x0 = min.x - overhang, x1 = max.x + overhang;
  // Cross-section (z, y): underside A-B-C, top F-E-D.
  const glm::vec2 A(za, y_eave), B(zm, y_ridge), C(zc, y_eave);
  const glm::vec2 D(zc, y_eave + rise), E(zm, y_ridge + rise), F(za, y_eave + rise);
  auto p = [](float x, const glm::vec2& zy) { return glm::vec3(x, zy.y, zy.x); };
  Shape s;
  const glm::vec3 down_front(0, -1, slope), down_back(0, -1, -slope);
  s.quad(p(x0, A), p(x1, A), p(x1, B), p(x0, B), down_front);  // underside, front slope
  s.quad(p(x0, B), p(x1, B), p(x1, C), p(x0, C), down_back);   // underside, back slope
  s.quad(p(x0, F), p(x1, F), p(x1, E), p(x0, E), glm::vec3(0, 1, -slope));  // top, front
  s.quad(p(x0, E), p(x1, E), p(x1, D), p(x0, D), glm::vec3(0, 1, slope));   // top, back
  s.quad(p(x0, A), p(x1, A), p(x1, F), p(x0, F), glm::vec3(0, 0, -1));      // front fascia
  s.quad(p(x0, C), p(x1, C), p(x1, D), p(x0, D), glm::vec3(0, 0, 1));       // back fascia
  for (int end = 0; end < 2; ++end) {  // gable ends: two parallelograms each
    const float x = end ? x1 : x0;
    const glm::vec3 out(end ? 1.0f : -1.0f, 0, 0);
    s.quad(p(x, A), p(x, B), p(x, E), p(x, F), out);
    s.quad(p(x, B), p(x, C), p(x, D), p(x, E), out);
  }
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::add_cylinder(const std::string& name, const glm::vec3& base_center, float radius,
                               float height, int segments, int material) {
  require(finite(base_center) && radius > 0.0f && height > 0.0f, name,
          "cylinder needs radius > 0 and height > 0");
  require(segments >= 3, name, "cylinder needs at least 3 segments");
  Shape s;
  const glm::vec3 up(0, height, 0);
  auto ring = [&](int k) {
    const float a = 2.0f * kPi * float(k % segments) / float(segments);
    return base_center + radius * glm::vec3(std::cos(a), 0, std::sin(a));
  };
  for (int k = 0; k < segments; ++k) {
    const glm::vec3 b0 = ring(k), b1 = ring(k + 1);
    const glm::vec3 out = 0.5f * (b0 + b1) - base_center;
    s.quad(b0, b1, b1 + up, b0 + up, out);
    s.tri(base_center, b0, b1, glm::vec3(0, -1, 0));
    s.tri(base_center + up, b0 + up, b1 + up, glm::vec3(0, 1, 0));
  }
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::add_bowl(const std::string& name, const glm::vec3& center, float radius,
                           float depth, float wall, int segments, int material) {
  require(finite(center) && radius > 0.0f && wall > 0.0f && wall < radius && wall < depth, name,
          "bowl needs 0 < wall < radius and wall < depth");
  require(segments >= 3, name, "bowl needs at least 3 segments");
  const float inner = radius - wall;
  auto ring = [&](int k, float r, float y) {
    const float a = 2.0f * kPi * float(k % segments) / float(segments);
    return center + glm::vec3(r * std::cos(a), y, r * std::sin(a));
  };
  Shape s;
  const glm::vec3 floor_center = center + glm::vec3(0, wall, 0);
  for (int k = 0; k < segments; ++k) {
    const glm::vec3 ob0 = ring(k, radius, 0), ob1 = ring(k + 1, radius, 0);
    const glm::vec3 ot0 = ring(k, radius, depth), ot1 = ring(k + 1, radius, depth);
    const glm::vec3 it0 = ring(k, inner, depth), it1 = ring(k + 1, inner, depth);
    const glm::vec3 ib0 = ring(k, inner, wall), ib1 = ring(k + 1, inner, wall);
    glm::vec3 radial = 0.5f * (ob0 + ob1) - center;
    radial.y = 0;
    s.tri(center, ob0, ob1, glm::vec3(0, -1, 0));       // underside
    s.quad(ob0, ob1, ot1, ot0, radial);                 // outer wall
    s.quad(ot0, ot1, it1, it0, glm::vec3(0, 1, 0));     // rim
    s.quad(it0, it1, ib1, ib0, -radial);                // inner wall
    s.tri(floor_center, ib0, ib1, glm::vec3(0, 1, 0));  // basin floor
  }
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::add_stairs(const std::string& name, const glm::vec3& origin, int steps,
                             float step_width, float tread, float riser, int material) {
  require(finite(origin) && steps >= 1 && step_width > 0.0f && tread > 0.0f && riser > 0.0f, name,
          "stairs need steps >= 1 and positive width, tread and riser");
  const float x0 = origin.x, x1 = origin.x + step_width;
  auto zy = [&](int kz, int ky) {  // profile point (z index, y index)
    return glm::vec2(origin.z + float(kz) * tread, origin.y + float(ky) * riser);
  };
  auto p = [](float x, const glm::vec2& v) { return glm::vec3(x, v.y, v.x); };
  Shape s;
  for (int k = 0; k < steps; ++k) {
    // Riser k: z = k*tread, y from k*riser to (k+1)*riser.
    s.quad(p(x0, zy(k, k)), p(x1, zy(k, k)), p(x1, zy(k, k + 1)), p(x0, zy(k, k + 1)),
           glm::vec3(0, 0, -1));
    // Tread k.
    s.quad(p(x0, zy(k, k + 1)), p(x1, zy(k, k + 1)), p(x1, zy(k + 1, k + 1)),
           p(x0, zy(k + 1, k + 1)), glm::vec3(0, 1, 0));
    // Bottom strip k.
    s.quad(p(x0, zy(k, 0)), p(x1, zy(k, 0)), p(x1, zy(k + 1, 0)), p(x0, zy(k + 1, 0)),
           glm::vec3(0, -1, 0));
    // Side columns: (k,0), (k+1,0), (k+1,k+1), (k,k+1) and (k,k) on the left
    // edge when k > 0; fanned from (k+1, 0), which is off the left edge.
    for (int side = 0; side < 2; ++side) {
      const float x = side ? x1 : x0;
      const glm::vec3 out(side ? 1.0f : -1.0f, 0, 0);
      const glm::vec3 apex = p(x, zy(k + 1, 0));
      s.tri(apex, p(x, zy(k + 1, k + 1)), p(x, zy(k, k + 1)), out);
      if (k > 0) {
        s.tri(apex, p(x, zy(k, k + 1)), p(x, zy(k, k)), out);
        s.tri(apex, p(x, zy(k, k)), p(x, zy(k, 0)), out);
      } else {
        s.tri(apex, p(x, zy(k, k + 1)), p(x, zy(k, 0)), out);
      }
    }
  }
  // Back face.
  s.quad(p(x0, zy(steps, 0)), p(x1, zy(steps, 0)), p(x1, zy(steps, steps)), p(x0, zy(steps, steps)),
         glm::vec3(0, 0, 1));
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::add_beam(const std::string& name, const glm::vec3& from, const glm::vec3& to,
                           float width, float height, int material) {
  const glm::vec3 d = to - from;
  const float horizontal = std::sqrt(d.x * d.x + d.z * d.z);
  require(finite(from) && finite(to) && horizontal > 0.0f, name,
          "beam needs distinct end points in x,z");
  require(width > 0.0f && height > 0.0f, name, "beam needs width > 0 and height > 0");
  const glm::vec3 h(d.x / horizontal, 0, d.z / horizontal);
  const glm::vec3 side(-h.z, 0, h.x);
  const glm::vec3 sw = side * (0.5f * width), up(0, 0.5f * height, 0);
  // Corner c(e, sgn_side, sgn_up), e = 0 at `from`, 1 at `to`.
  auto c = [&](int e, int sd, int u) { return (e ? to : from) + (sd ? sw : -sw) + (u ? up : -up); };
  Shape s;
  s.quad(c(0, 0, 0), c(0, 1, 0), c(0, 1, 1), c(0, 0, 1), -h);
  s.quad(c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1), h);
  s.quad(c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1), -side);
  s.quad(c(0, 1, 0), c(1, 1, 0), c(1, 1, 1), c(0, 1, 1), side);
  s.quad(c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1), glm::vec3(0, 1, 0));
  s.quad(c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0), glm::vec3(0, -1, 0));
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::add_wall_ring(const std::string& name, const glm::vec3& min, const glm::vec3& max,
                                float thickness, int material) {
  require(finite(min) && finite(max) && min.x < max.x && min.y < max.y && min.z < max.z, name,
          "wall ring needs min < max");
  require(thickness > 0.0f && 2.0f * thickness < max.x - min.x && 2.0f * thickness < max.z - min.z,
          name, "wall ring needs 0 < 2 * thickness < footprint");
  const float t = thickness;
  // Outer and inner corners, counter-clockwise seen from above (xz).
  const std::array<glm::vec2, 4> outer{glm::vec2(min.x, min.z), glm::vec2(min.x, max.z),
                                       glm::vec2(max.x, max.z), glm::vec2(max.x, min.z)};
  const std::array<glm::vec2, 4> inner{
      glm::vec2(min.x + t, min.z + t), glm::vec2(min.x + t, max.z - t),
      glm::vec2(max.x - t, max.z - t), glm::vec2(max.x - t, min.z + t)};
  auto p = [](const glm::vec2& xz, float y) { return glm::vec3(xz.x, y, xz.y); };
  const glm::vec2 mid((min.x + max.x) * 0.5f, (min.z + max.z) * 0.5f);
  Shape s;
  for (int k = 0; k < 4; ++k) {
    const int n = (k + 1) % 4;
    const glm::vec2 out2 = (outer[k] + outer[n]) * 0.5f - mid;
    const glm::vec3 out(out2.x, 0, out2.y);
    s.quad(p(outer[k], min.y), p(outer[n], min.y), p(outer[n], max.y), p(outer[k], max.y), out);
    s.quad(p(inner[k], min.y), p(inner[n], min.y), p(inner[n], max.y), p(inner[k], max.y), -out);
    s.quad(p(outer[k], max.y), p(outer[n], max.y), p(inner[n], max.y), p(inner[k], max.y),
           glm::vec3(0, 1, 0));
    s.quad(p(outer[k], min.y), p(outer[n], min.y), p(inner[n], min.y), p(inner[k], min.y),
           glm::vec3(0, -1, 0));
  }
  return add_object({name, std::move(s.positions), std::move(s.indices), material, true});
}

int SceneBuilder::find_object(const std::string& name) const {
  for (size_t i = 0; i < objects_.size(); ++i)
    if (objects_[i].name == name) return int(i);
  return -1;
}

bool SceneBuilder::needs_default_material() const {
  for (const BuilderObject& o : objects_)
    if (o.material < 0) return true;
  return false;
}

std::vector<MeshMaterial> SceneBuilder::materials() const {
  std::vector<MeshMaterial> out = materials_;
  if (needs_default_material()) {
    MeshMaterial m;
    m.name = "Default";
    m.base_color = kDefaultColor;
    out.push_back(m);
  }
  return out;
}

Scene SceneBuilder::build() const {
  Scene scene;
  for (const MeshMaterial& m : materials()) {
    Material mat;
    mat.name = m.name;
    mat.base_color = m.base_color;
    scene.materials.push_back(mat);
  }
  const int default_material = int(materials_.size());
  for (size_t i = 0; i < objects_.size(); ++i) {
    const BuilderObject& o = objects_[i];
    SceneObject so;
    so.name = o.name;
    so.node_path = "/" + o.name;
    so.node = int(i);
    so.mesh = int(i);
    so.primitive = 0;
    so.material = o.material < 0 ? default_material : o.material;
    so.first_triangle = uint32_t(scene.triangle_count());
    so.triangle_count = uint32_t(o.indices.size() / 3);
    for (size_t t = 0; t + 2 < o.indices.size(); t += 3) {
      const glm::vec3 a = o.positions[o.indices[t]], b = o.positions[o.indices[t + 1]],
                      c = o.positions[o.indices[t + 2]];
      const glm::vec3 n = flat_normal(a, b, c);
      for (const glm::vec3& q : {a, b, c}) {
        scene.positions.push_back(q);
        scene.normals.push_back(n);
        scene.bounds.extend(q);
      }
    }
    scene.objects.push_back(so);
  }
  scene.stats.triangles_read = scene.triangle_count();
  scene.stats.nodes = objects_.size();
  scene.stats.instances = objects_.size();
  return scene;
}

std::vector<TriMesh> SceneBuilder::meshes() const {
  const int default_material = int(materials_.size());
  std::vector<TriMesh> out;
  out.reserve(objects_.size());
  for (const BuilderObject& o : objects_) {
    TriMesh mesh;
    mesh.name = o.name;
    mesh.material = o.material < 0 ? default_material : o.material;
    // Split vertices where the flat normal differs (normals quantized to 1e-4
    // so the two triangles of a planar quad share their corners).
    std::map<std::tuple<uint32_t, int, int, int>, uint32_t> split;
    for (size_t t = 0; t + 2 < o.indices.size(); t += 3) {
      const glm::vec3 n = flat_normal(o.positions[o.indices[t]], o.positions[o.indices[t + 1]],
                                      o.positions[o.indices[t + 2]]);
      const auto key_n = std::make_tuple(int(std::lround(n.x * 1e4f)), int(std::lround(n.y * 1e4f)),
                                         int(std::lround(n.z * 1e4f)));
      for (int c = 0; c < 3; ++c) {
        const uint32_t v = o.indices[t + c];
        const auto key =
            std::make_tuple(v, std::get<0>(key_n), std::get<1>(key_n), std::get<2>(key_n));
        auto it = split.find(key);
        if (it == split.end()) {
          it = split.emplace(key, uint32_t(mesh.positions.size())).first;
          mesh.positions.push_back(o.positions[v]);
          mesh.normals.push_back(n);
        }
        mesh.indices.push_back(it->second);
      }
    }
    out.push_back(std::move(mesh));
  }
  return out;
}

// --- Topology checks ------------------------------------------------------------

TopologyReport check_topology(const std::vector<glm::vec3>& positions,
                              const std::vector<uint32_t>& indices) {
  TopologyReport r;
  std::map<std::tuple<float, float, float>, uint32_t> weld;
  std::vector<uint32_t> id(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    const glm::vec3& p = positions[i];
    id[i] = weld.emplace(std::make_tuple(p.x, p.y, p.z), uint32_t(weld.size())).first->second;
  }
  r.vertices = weld.size();
  r.triangles = indices.size() / 3;
  // Undirected edge (lo, hi) -> uses in direction lo->hi and hi->lo.
  std::map<std::pair<uint32_t, uint32_t>, std::pair<int, int>> edges;
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    uint32_t v[3];
    for (int c = 0; c < 3; ++c) v[c] = indices[t + c] < id.size() ? id[indices[t + c]] : 0;
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
      ++r.degenerate_triangles;
      continue;
    }
    for (int c = 0; c < 3; ++c) {
      const uint32_t a = v[c], b = v[(c + 1) % 3];
      auto& e = edges[{std::min(a, b), std::max(a, b)}];
      (a < b ? e.first : e.second)++;
    }
  }
  r.edges = edges.size();
  for (const auto& [key, use] : edges) {
    const int total = use.first + use.second;
    if (total == 1)
      ++r.boundary_edges;
    else if (total > 2)
      ++r.nonmanifold_edges;
    else if (use.first != 1)
      ++r.misoriented_edges;
  }
  return r;
}

namespace {
const SceneObject& object_at(const Scene& scene, int object) {
  if (object < 0 || object >= int(scene.objects.size()))
    throw InputError("scene: object " + std::to_string(object) + " does not exist");
  return scene.objects[size_t(object)];
}

void object_soup(const Scene& scene, int object, std::vector<glm::vec3>& positions,
                 std::vector<uint32_t>& indices) {
  const SceneObject& o = object_at(scene, object);
  const size_t first = size_t(o.first_triangle) * 3, count = size_t(o.triangle_count) * 3;
  positions.assign(scene.positions.begin() + long(first),
                   scene.positions.begin() + long(first + count));
  indices.resize(count);
  for (size_t i = 0; i < count; ++i) indices[i] = uint32_t(i);
}
}  // namespace

TopologyReport check_object_topology(const Scene& scene, int object) {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  object_soup(scene, object, positions, indices);
  return check_topology(positions, indices);
}

double signed_volume(const std::vector<glm::vec3>& positions,
                     const std::vector<uint32_t>& indices) {
  double volume = 0.0;
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const glm::dvec3 a(positions[indices[t]]), b(positions[indices[t + 1]]),
        c(positions[indices[t + 2]]);
    volume += glm::dot(a, glm::cross(b, c));
  }
  return volume / 6.0;
}

double object_signed_volume(const Scene& scene, int object) {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  object_soup(scene, object, positions, indices);
  return signed_volume(positions, indices);
}

int find_object(const Scene& scene, const std::string& name) {
  for (size_t i = 0; i < scene.objects.size(); ++i)
    if (scene.objects[i].name == name) return int(i);
  return -1;
}

// --- Canned scenes ----------------------------------------------------------------

namespace {
const glm::vec4 kFloorColor{0.5f, 0.5f, 0.5f, 1.0f};

int add_floor(SceneBuilder& b, float size) {
  const int m = b.add_material("Floor", kFloorColor);
  const float h = 0.5f * size;
  return b.add_plane("Floor", 0.0f, glm::vec2(-h), glm::vec2(h), m);
}

/// Table centred at (cx, cz): top slab and four legs named prefix+"Top",
/// prefix+"Leg0..3".
void add_table(SceneBuilder& b, const std::string& prefix, float cx, float cz, float size_x,
               float size_z, float height, float top_thickness, float leg_width, int material) {
  const float hx = 0.5f * size_x, hz = 0.5f * size_z;
  b.add_box(prefix + "Top", glm::vec3(cx - hx, height - top_thickness, cz - hz),
            glm::vec3(cx + hx, height, cz + hz), material);
  for (int k = 0; k < 4; ++k) {
    const float x = (k & 1) ? cx + hx - leg_width : cx - hx;
    const float z = (k & 2) ? cz + hz - leg_width : cz - hz;
    b.add_box(prefix + "Leg" + std::to_string(k), glm::vec3(x, 0.0f, z),
              glm::vec3(x + leg_width, height - top_thickness, z + leg_width), material);
  }
}

/// House walls, slab, gable prisms and roof over x in [x0, x1], z in [z0, z1].
void add_house(SceneBuilder& b, const std::string& prefix, float x0, float x1, float z0, float z1,
               float wall_height, float wall_thickness, float pitch_deg, float overhang,
               float roof_thickness, float slab_thickness, int wall_material, int slab_material,
               int roof_material) {
  const float t = wall_thickness;
  b.add_wall_ring(prefix + "Walls", glm::vec3(x0, 0.0f, z0), glm::vec3(x1, wall_height, z1), t,
                  wall_material);
  b.add_box(prefix + "Slab", glm::vec3(x0 + t, 0.0f, z0 + t),
            glm::vec3(x1 - t, slab_thickness, z1 - t), slab_material);
  const float ridge = wall_height + 0.5f * (z1 - z0) * std::tan(radians(pitch_deg));
  const glm::vec2 a(z0, wall_height), c(z1, wall_height), apex(0.5f * (z0 + z1), ridge);
  for (int end = 0; end < 2; ++end) {
    Shape s;
    if (end == 0)
      prism_x_faces(s, x0, x0 + t, a, c, apex);
    else
      prism_x_faces(s, x1 - t, x1, a, c, apex);
    b.add_mesh(prefix + (end ? "GableEast" : "GableWest"), s.positions, s.indices, wall_material);
  }
  b.add_gable_roof(prefix + "Roof", glm::vec3(x0, wall_height, z0), glm::vec3(x1, ridge, z1),
                   pitch_deg, overhang, roof_thickness, roof_material);
}
}  // namespace

Scene make_open_plane(float size) {
  SceneBuilder b;
  add_floor(b, size);
  return b.build();
}

Scene make_table_scene(const TableDims& d) {
  SceneBuilder b;
  add_floor(b, d.floor_size);
  const int wood = b.add_material("Table", glm::vec4(0.45f, 0.3f, 0.18f, 1.0f));
  add_table(b, "Table", 0.0f, 0.0f, d.table_size, d.table_size, d.table_height, d.top_thickness,
            d.leg_width, wood);
  return b.build();
}

Scene make_table_scene(float table_height, float table_size, float floor_size) {
  TableDims d;
  d.table_height = table_height;
  d.table_size = table_size;
  d.floor_size = floor_size;
  return make_table_scene(d);
}

Scene make_closed_box_scene(const ClosedBoxDims& d) {
  SceneBuilder b;
  add_floor(b, d.floor_size);
  const int m = b.add_material("Box", glm::vec4(0.7f, 0.4f, 0.2f, 1.0f));
  const float h = 0.5f * d.size;
  if (!(d.wall > 0.0f && 2.0f * d.wall < d.size))
    throw InputError("scene builder: object 'Box': needs 0 < 2 * wall < size");
  Shape s;
  box_faces(s, glm::vec3(-h, 0.0f, -h), glm::vec3(h, d.size, h));
  box_faces(s, glm::vec3(-h + d.wall, d.wall, -h + d.wall),
            glm::vec3(h - d.wall, d.size - d.wall, h - d.wall), /*inward=*/true);
  b.add_mesh("Box", s.positions, s.indices, m);
  return b.build();
}

Scene make_closed_box_scene(float size) {
  ClosedBoxDims d;
  d.size = size;
  d.wall = std::min(d.wall, 0.1f * size);
  d.floor_size = std::max(d.floor_size, 4.0f * size);
  return make_closed_box_scene(d);
}

Scene make_wall_scene(const WallDims& d) {
  SceneBuilder b;
  add_floor(b, d.floor_size);
  const int m = b.add_material("Wall", glm::vec4(0.8f, 0.75f, 0.65f, 1.0f));
  b.add_box("Wall", glm::vec3(-0.5f * d.wall_length, 0.0f, -0.5f * d.wall_thickness),
            glm::vec3(0.5f * d.wall_length, d.wall_height, 0.5f * d.wall_thickness), m);
  return b.build();
}

Scene make_wall_scene(float wall_height, float wall_length, float floor_size) {
  WallDims d;
  d.wall_height = wall_height;
  d.wall_length = wall_length;
  d.floor_size = floor_size;
  return make_wall_scene(d);
}

Scene make_house_scene(const HouseDims& d) {
  SceneBuilder b;
  add_floor(b, d.floor_size);
  const int walls = b.add_material("Walls", glm::vec4(0.8f, 0.75f, 0.65f, 1.0f));
  const int slab = b.add_material("Slab", glm::vec4(0.5f, 0.45f, 0.4f, 1.0f));
  const int roof = b.add_material("Roof", glm::vec4(0.55f, 0.18f, 0.12f, 1.0f));
  add_house(b, "House", -0.5f * d.width, 0.5f * d.width, -0.5f * d.depth, 0.5f * d.depth,
            d.wall_height, d.wall_thickness, d.roof_pitch_deg, d.eaves_overhang, d.roof_thickness,
            d.slab_thickness, walls, slab, roof);
  return b.build();
}

Scene make_house_scene(float roof_pitch_deg, float eaves_overhang) {
  HouseDims d;
  d.roof_pitch_deg = roof_pitch_deg;
  d.eaves_overhang = eaves_overhang;
  return make_house_scene(d);
}

Scene make_stairs_scene(const StairsDims& d) {
  SceneBuilder b;
  add_floor(b, d.floor_size);
  const int m = b.add_material("Stairs", glm::vec4(0.6f, 0.6f, 0.58f, 1.0f));
  b.add_stairs("Stairs", glm::vec3(-0.5f * d.step_width, 0.0f, -0.5f * float(d.steps) * d.tread),
               d.steps, d.step_width, d.tread, d.riser, m);
  return b.build();
}

Scene make_bowl_scene(const BowlDims& d) {
  SceneBuilder b;
  add_floor(b, d.floor_size);
  const int m = b.add_material("Bowl", glm::vec4(0.6f, 0.6f, 0.58f, 1.0f));
  b.add_bowl("Bowl", glm::vec3(0.0f), d.radius, d.depth, d.wall, d.segments, m);
  return b.build();
}

SceneBuilder make_wind_yard() {
  SceneBuilder b;
  add_floor(b, 40.0f);
  const int stone = b.add_material("Stone", glm::vec4(0.62f, 0.6f, 0.56f, 1.0f));
  const int wood = b.add_material("Wood", glm::vec4(0.45f, 0.3f, 0.18f, 1.0f));
  const int brick = b.add_material("Brick", glm::vec4(0.6f, 0.28f, 0.2f, 1.0f));
  b.add_box("Cube", glm::vec3(-9.0f, 0.0f, -9.0f), glm::vec3(-7.0f, 2.0f, -7.0f), stone);
  b.add_box("Fence", glm::vec3(2.0f, 0.0f, -14.0f), glm::vec3(2.2f, 1.5f, -2.0f), wood);
  b.add_box("LowerRoof", glm::vec3(4.0f, 0.0f, 4.0f), glm::vec3(12.0f, 3.0f, 12.0f), brick);
  b.add_box("HigherBlock", glm::vec3(12.0f, 0.0f, 4.0f), glm::vec3(18.0f, 6.0f, 12.0f), brick);
  return b;
}

// --- The courtyard ----------------------------------------------------------------

SceneBuilder make_truck() {
  SceneBuilder b;
  add_floor(b, 12.0f);
  const int paint = b.add_material("Paint", glm::vec4(0.75f, 0.1f, 0.08f, 1.0f), 0.4f, 0.3f);
  const int box = b.add_material("CargoPanels", glm::vec4(0.85f, 0.85f, 0.82f, 1.0f), 0.6f);
  const int dark = b.add_material("Rubber", glm::vec4(0.03f, 0.03f, 0.03f, 1.0f), 0.9f);
  const int glass = b.add_material("Glass", glm::vec4(0.2f, 0.25f, 0.3f, 1.0f), 0.1f);
  b.add_box("Chassis", glm::vec3(-1.0f, 0.5f, -3.5f), glm::vec3(1.0f, 0.9f, 3.2f), dark);
  b.add_box("CargoBox", glm::vec3(-1.2f, 0.9f, -1.0f), glm::vec3(1.2f, 3.4f, 3.2f), box);
  b.add_box("Cab", glm::vec3(-1.15f, 0.9f, -2.6f), glm::vec3(1.15f, 2.8f, -1.1f), paint);
  b.add_box("Hood", glm::vec3(-1.15f, 0.9f, -3.5f), glm::vec3(1.15f, 1.7f, -2.6f), paint);
  // The windscreen: a wedge from the cab's front top edge down to the hood.
  const float x0 = -1.15f, x1 = 1.15f, zb = -2.6f, zf = -3.1f, yb = 1.7f, yt = 2.8f;
  const std::vector<glm::vec3> wedge = {{x0, yb, zb}, {x1, yb, zb}, {x1, yt, zb},
                                        {x0, yt, zb}, {x0, yb, zf}, {x1, yb, zf}};
  const std::vector<uint32_t> faces = {0, 2, 1, 0, 3, 2,   // back, facing +z
                                       4, 5, 2, 4, 2, 3,   // sloped front
                                       0, 1, 5, 0, 5, 4,   // bottom
                                       0, 4, 3, 1, 2, 5};  // sides
  b.add_mesh("Windscreen", wedge, faces, glass);
  int k = 0;
  for (const float z : {-2.6f, 2.2f}) {
    for (const float x : {-1.15f, 0.85f}) {
      b.add_beam("Wheel" + std::to_string(k++), glm::vec3(x, 0.45f, z),
                 glm::vec3(x + 0.3f, 0.45f, z), 0.9f, 0.9f, dark);
    }
  }
  return b;
}

SceneBuilder make_courtyard() {
  SceneBuilder b;
  const int ground = b.add_material("Paving", glm::vec4(0.36f, 0.38f, 0.33f, 1.0f), 0.9f);
  const int plaster = b.add_material("Plaster", glm::vec4(0.82f, 0.76f, 0.64f, 1.0f), 0.9f);
  const int tiles = b.add_material("RoofTiles", glm::vec4(0.55f, 0.17f, 0.11f, 1.0f), 0.7f);
  const int boards = b.add_material("FloorBoards", glm::vec4(0.52f, 0.40f, 0.28f, 1.0f), 0.7f);
  const int wood = b.add_material("Wood", glm::vec4(0.40f, 0.25f, 0.13f, 1.0f), 0.75f);
  const int sheet = b.add_material("SheetMetal", glm::vec4(0.28f, 0.34f, 0.40f, 1.0f), 0.5f, 0.6f);
  const int stone = b.add_material("Stone", glm::vec4(0.62f, 0.61f, 0.57f, 1.0f), 0.85f);
  const int iron = b.add_material("Iron", glm::vec4(0.08f, 0.08f, 0.09f, 1.0f), 0.45f, 0.9f);
  const int glass = b.add_material("LampGlass", glm::vec4(1.0f, 0.88f, 0.55f, 1.0f), 0.2f);

  // Ground slab: 24 x 24 m, top at y = 0.
  b.add_box("Ground", glm::vec3(-12.0f, -0.3f, -12.0f), glm::vec3(12.0f, 0.0f, 12.0f), ground);

  // House: 7 x 5 m, walls 3 m high and 0.25 m thick, roof 42 deg with 0.5 m
  // eaves, ridge along x.
  add_house(b, "House", -10.0f, -3.0f, -10.0f, -5.0f, 3.0f, 0.25f, 42.0f, 0.5f, 0.2f, 0.12f,
            plaster, boards, tiles);

  // Shed: 3 x 2.5 m, walls 2.2 m, flat roof slab with 0.2 m overhang.
  b.add_wall_ring("ShedWalls", glm::vec3(6.0f, 0.0f, -10.0f), glm::vec3(9.0f, 2.2f, -7.5f), 0.15f,
                  wood);
  b.add_box("ShedRoof", glm::vec3(5.8f, 2.2f, -10.2f), glm::vec3(9.2f, 2.35f, -7.3f), sheet);
  b.add_box("ShedSlab", glm::vec3(6.15f, 0.0f, -9.85f), glm::vec3(8.85f, 0.1f, -7.65f), boards);

  // Table: top 1.5 x 1 m at y = 0.75, centred at (2, 3).
  add_table(b, "Table", 2.0f, 3.0f, 1.5f, 1.0f, 0.75f, 0.05f, 0.07f, wood);

  // Bench: seat 1.6 x 0.4 m at y = 0.45, centred at (-6, 0), backrest on -z.
  b.add_box("BenchSeat", glm::vec3(-6.8f, 0.4f, -0.2f), glm::vec3(-5.2f, 0.45f, 0.2f), wood);
  b.add_box("BenchLeg0", glm::vec3(-6.7f, 0.0f, -0.18f), glm::vec3(-6.62f, 0.4f, 0.18f), iron);
  b.add_box("BenchLeg1", glm::vec3(-5.38f, 0.0f, -0.18f), glm::vec3(-5.3f, 0.4f, 0.18f), iron);
  b.add_box("BenchBack", glm::vec3(-6.8f, 0.45f, -0.2f), glm::vec3(-5.2f, 0.9f, -0.16f), wood);

  // Stairs: 5 steps (riser 0.18 m, tread 0.3 m, 1.2 m wide) rising along +z
  // from z = 2 to the terrace, whose top (y = 1.08) is the landing.
  const float riser = 0.18f, tread = 0.3f;
  const int steps = 5;
  const float landing = float(steps + 1) * riser;
  const float sx0 = 8.0f, sx1 = 9.2f, sz0 = 2.0f, sz1 = sz0 + float(steps) * tread;
  b.add_stairs("Stairs", glm::vec3(sx0, 0.0f, sz0), steps, sx1 - sx0, tread, riser, stone);
  const float tx0 = 7.5f, tx1 = 11.0f, tz1 = 7.0f;
  b.add_box("Terrace", glm::vec3(tx0, 0.0f, sz1), glm::vec3(tx1, landing, tz1), stone);

  // Railing along the stairs' east edge and the terrace's north and east
  // edges: 0.05 m square posts, 0.9 m above what they stand on, 0.06 x 0.05 m
  // top rails.
  const float post = 0.05f, rail_h = 0.9f, rail_w = 0.06f, rail_t = 0.05f;
  auto add_post = [&](const std::string& name, float x, float y, float z) {
    b.add_box(name, glm::vec3(x - 0.5f * post, y, z - 0.5f * post),
              glm::vec3(x + 0.5f * post, y + rail_h, z + 0.5f * post), iron);
  };
  const float rx = sx1 - 0.1f;  // stair railing line
  // Posts on the first and last tread (centres), then along the terrace.
  const float p0z = sz0 + 0.5f * tread, p1z = sz0 + (float(steps) - 0.5f) * tread;
  add_post("RailPost0", rx, riser, p0z);
  add_post("RailPost1", rx, float(steps) * riser, p1z);
  b.add_beam("StairRail", glm::vec3(rx, riser + rail_h + 0.5f * rail_t, p0z),
             glm::vec3(rx, float(steps) * riser + rail_h + 0.5f * rail_t, p1z), rail_w, rail_t,
             iron);
  // Terrace railing: east edge (x = tx1 - 0.1) from z = sz1 + 0.1 to tz1 - 0.1,
  // north edge (z = tz1 - 0.1) from x = tx1 - 0.1 to tx0 + 0.1.
  const float ex = tx1 - 0.1f, nz = tz1 - 0.1f, ez0 = sz1 + 0.1f, wx = tx0 + 0.1f;
  const float top = landing + rail_h + 0.5f * rail_t;
  add_post("RailPost2", ex, landing, ez0);
  add_post("RailPost3", ex, landing, 0.5f * (ez0 + nz));
  add_post("RailPost4", ex, landing, nz);
  add_post("RailPost5", 0.5f * (ex + wx), landing, nz);
  add_post("RailPost6", wx, landing, nz);
  b.add_beam("TerraceRailEast", glm::vec3(ex, top, ez0), glm::vec3(ex, top, nz), rail_w, rail_t,
             iron);
  b.add_beam("TerraceRailNorth", glm::vec3(ex, top, nz), glm::vec3(wx, top, nz), rail_w, rail_t,
             iron);

  // Fountain: basin 1.5 m radius, rim 0.5 m high, centred at (-5, 6), with a
  // column in the middle.
  b.add_bowl("FountainBasin", glm::vec3(-5.0f, 0.0f, 6.0f), 1.5f, 0.5f, 0.15f, 48, stone);
  b.add_cylinder("FountainColumn", glm::vec3(-5.0f, 0.15f, 6.0f), 0.15f, 1.0f, 16, stone);

  // Lamp post at (4, -4): pole 3 m, lamp head 0.3 m cube-ish on top.
  b.add_cylinder("LampPole", glm::vec3(4.0f, 0.0f, -4.0f), 0.06f, 3.0f, 12, iron);
  b.add_box("LampHead", glm::vec3(3.82f, 3.0f, -4.18f), glm::vec3(4.18f, 3.35f, -3.82f), glass);
  return b;
}

SceneBuilder make_terrain(int triangles) {
  SceneBuilder builder;
  const int quads_side = std::max(2, int(std::sqrt(double(std::max(triangles, 300) - 200) / 2.0)));
  const float size = 100.0f;
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  positions.reserve(size_t(quads_side + 1) * size_t(quads_side + 1));
  for (int j = 0; j <= quads_side; ++j) {
    for (int i = 0; i <= quads_side; ++i) {
      const float x = -size / 2 + size * float(i) / float(quads_side);
      const float z = -size / 2 + size * float(j) / float(quads_side);
      const float y =
          1.5f * std::sin(x * 0.11f) * std::cos(z * 0.07f) + 0.3f * std::sin(x * 0.9f + z * 0.6f);
      positions.push_back({x, y, z});
    }
  }
  const uint32_t row = uint32_t(quads_side + 1);
  for (int j = 0; j < quads_side; ++j) {
    for (int i = 0; i < quads_side; ++i) {
      const uint32_t a = uint32_t(j) * row + uint32_t(i);
      indices.insert(indices.end(), {a, a + row, a + row + 1, a, a + row + 1, a + 1});
    }
  }
  builder.add_mesh("Terrain", positions, indices);
  for (int k = 0; k < 8; ++k) {
    const float x = -40.0f + 11.0f * float(k), z = 10.0f * std::sin(float(k));
    builder.add_box("Table" + std::to_string(k), {x - 1.5f, 2.5f, z - 1.0f},
                    {x + 1.5f, 2.6f, z + 1.0f});
    builder.add_box("Wall" + std::to_string(k), {x - 3.0f, -2.0f, z + 4.0f},
                    {x + 3.0f, 4.0f, z + 4.3f});
  }
  return builder;
}

}  // namespace snow
