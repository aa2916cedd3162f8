// Tests for scenes built in code (src/scene/builder.h) and the glTF writer
// (src/mesh/gltf_writer.h): primitives are closed with outward normals and
// the documented volumes and bounds; canned scenes match their documented
// dimensions; the courtyard round-trips through GLB and .gltf.
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>

#include "core/error.h"
#include "mesh/gltf_writer.h"
#include "scene/builder.h"

namespace fs = std::filesystem;
using snow::Bounds;
using snow::Scene;
using snow::SceneBuilder;

namespace {

constexpr float kPi = 3.14159265358979323846f;
constexpr double kTol = 1e-4;

fs::path temp_dir(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("snow_test_builder_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<uint8_t> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void expect_vec3_near(const glm::vec3& a, const glm::vec3& b, float tol, const std::string& what) {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

void expect_bounds(const Bounds& b, const glm::vec3& min, const glm::vec3& max,
                   const std::string& what) {
  expect_vec3_near(b.min, min, 1e-4f, what + " min");
  expect_vec3_near(b.max, max, 1e-4f, what + " max");
}

/// The one object of a builder: closed, positive volume `volume`.
void expect_closed_volume(const SceneBuilder& b, int object, double volume) {
  const snow::BuilderObject& o = b.objects().at(size_t(object));
  const snow::TopologyReport r = snow::check_topology(o.positions, o.indices);
  EXPECT_TRUE(o.closed) << o.name;
  EXPECT_TRUE(r.closed()) << o.name << ": boundary " << r.boundary_edges << ", non-manifold "
                          << r.nonmanifold_edges << ", misoriented " << r.misoriented_edges
                          << ", degenerate " << r.degenerate_triangles;
  EXPECT_EQ(r.vertices, o.positions.size()) << o.name << ": vertices are welded";
  EXPECT_NEAR(snow::signed_volume(o.positions, o.indices), volume, kTol * std::max(1.0, volume))
      << o.name;
}

/// Every object of a Scene except those named in `open` is closed with
/// positive volume; the open ones are not closed.
void expect_scene_closed(const Scene& scene, const std::set<std::string>& open) {
  for (int i = 0; i < int(scene.objects.size()); ++i) {
    const std::string& name = scene.objects[size_t(i)].name;
    const snow::TopologyReport r = snow::check_object_topology(scene, i);
    if (open.count(name)) {
      EXPECT_FALSE(r.closed()) << name;
      continue;
    }
    EXPECT_TRUE(r.closed()) << name << ": boundary " << r.boundary_edges << ", non-manifold "
                            << r.nonmanifold_edges << ", misoriented " << r.misoriented_edges;
    EXPECT_GT(snow::object_signed_volume(scene, i), 0.0) << name;
  }
}

/// Flat normals: each triangle's three normals are unit, equal, and agree
/// with its counter-clockwise winding.
void expect_flat_normals(const Scene& scene) {
  ASSERT_EQ(scene.normals.size(), scene.positions.size());
  for (size_t t = 0; t < scene.triangle_count(); ++t) {
    const glm::vec3 a = scene.positions[3 * t], b = scene.positions[3 * t + 1],
                    c = scene.positions[3 * t + 2];
    const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(glm::length(scene.normals[3 * t + k]), 1.0f, 1e-5f);
      ASSERT_GT(glm::dot(scene.normals[3 * t + k], n), 0.9999f) << "triangle " << t;
    }
  }
}

/// Ray/triangle hit distance (Moeller-Trumbore), or -1.
float ray_hit(const glm::vec3& o, const glm::vec3& d, const glm::vec3& a, const glm::vec3& b,
              const glm::vec3& c) {
  const glm::vec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
  const float det = glm::dot(e1, p);
  if (std::abs(det) < 1e-12f) return -1.0f;
  const glm::vec3 s = o - a;
  const float u = glm::dot(s, p) / det;
  if (u < -1e-6f || u > 1.0f + 1e-6f) return -1.0f;
  const glm::vec3 q = glm::cross(s, e1);
  const float v = glm::dot(d, q) / det;
  if (v < -1e-6f || u + v > 1.0f + 1e-6f) return -1.0f;
  const float t = glm::dot(e2, q) / det;
  return t > 1e-6f ? t : -1.0f;
}

/// Fraction of `n` rays from `origin` over the whole sphere of directions
/// that hit some triangle of `scene`.
double enclosed_fraction(const Scene& scene, const glm::vec3& origin, int n) {
  int hits = 0;
  for (int i = 0; i < n; ++i) {
    // Fibonacci sphere, slightly rotated so no ray runs along a seam.
    const float z = 1.0f - 2.0f * (float(i) + 0.5f) / float(n);
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    const float phi = float(i) * 2.39996323f + 0.1234f;
    const glm::vec3 d(r * std::cos(phi), z, r * std::sin(phi));
    for (size_t t = 0; t < scene.triangle_count(); ++t) {
      if (ray_hit(origin, d, scene.positions[3 * t], scene.positions[3 * t + 1],
                  scene.positions[3 * t + 2]) > 0.0f) {
        ++hits;
        break;
      }
    }
  }
  return double(hits) / double(n);
}

}  // namespace

// --- Primitives -----------------------------------------------------------------

TEST(Primitives, BoxIsClosedWithOutwardNormals) {
  SceneBuilder b;
  const int box = b.add_box("Box", glm::vec3(-1, 0, 2), glm::vec3(2, 0.5f, 3));
  EXPECT_EQ(box, 0);
  EXPECT_EQ(b.objects()[0].indices.size(), 36u);
  expect_closed_volume(b, box, 3.0 * 0.5 * 1.0);
  const Scene scene = b.build();
  expect_flat_normals(scene);
  const glm::vec3 center(0.5f, 0.25f, 2.5f);
  for (size_t t = 0; t < scene.triangle_count(); ++t) {
    const glm::vec3 centroid =
        (scene.positions[3 * t] + scene.positions[3 * t + 1] + scene.positions[3 * t + 2]) / 3.0f;
    EXPECT_GT(glm::dot(scene.normals[3 * t], centroid - center), 0.0f) << "triangle " << t;
  }
  expect_bounds(scene.bounds, glm::vec3(-1, 0, 2), glm::vec3(2, 0.5f, 3), "box");
}

TEST(Primitives, PlaneIsOneSidedFacingUp) {
  SceneBuilder b;
  b.add_plane("Ground", 1.5f, glm::vec2(-2, -1), glm::vec2(3, 4));
  const Scene scene = b.build();
  ASSERT_EQ(scene.triangle_count(), 2u);
  for (const glm::vec3& n : scene.normals) expect_vec3_near(n, glm::vec3(0, 1, 0), 1e-6f, "normal");
  const snow::TopologyReport r = snow::check_object_topology(scene, 0);
  EXPECT_FALSE(r.closed());
  EXPECT_EQ(r.boundary_edges, 4u);
  EXPECT_FALSE(b.objects()[0].closed);
  expect_bounds(scene.bounds, glm::vec3(-2, 1.5f, -1), glm::vec3(3, 1.5f, 4), "plane");
}

TEST(Primitives, CylinderVolumeMatchesPrism) {
  SceneBuilder b;
  const int n = 24;
  const float r = 0.5f, h = 2.0f;
  b.add_cylinder("Pole", glm::vec3(1, 0.5f, -1), r, h, n);
  const double area = 0.5 * n * r * r * std::sin(2.0 * kPi / n);
  expect_closed_volume(b, 0, area * h);
  const Scene scene = b.build();
  expect_bounds(scene.bounds, glm::vec3(0.5f, 0.5f, -1.0f - r * std::sin(2 * kPi * 6 / n)),
                glm::vec3(1.5f, 2.5f, -1.0f + r * std::sin(2 * kPi * 6 / n)), "cylinder");
}

TEST(Primitives, BowlIsAClosedCupOpenAtTheTop) {
  SceneBuilder b;
  const int n = 32;
  const float r = 1.0f, depth = 0.5f, wall = 0.1f;
  b.add_bowl("Basin", glm::vec3(0, 0.2f, 0), r, depth, wall, n);
  const double k = 0.5 * n * std::sin(2.0 * kPi / n);  // polygon area / r^2
  const double ri = r - wall;
  expect_closed_volume(b, 0, k * r * r * depth - k * ri * ri * (depth - wall));
  // Straight down into the basin the first surface is its floor at y = 0.2 + wall.
  const Scene scene = b.build();
  float nearest = 1e9f;
  for (size_t t = 0; t < scene.triangle_count(); ++t) {
    const float d = ray_hit(glm::vec3(0.1f, 5, 0.2f), glm::vec3(0, -1, 0), scene.positions[3 * t],
                            scene.positions[3 * t + 1], scene.positions[3 * t + 2]);
    if (d > 0.0f) nearest = std::min(nearest, d);
  }
  EXPECT_NEAR(5.0f - nearest, 0.2f + wall, 1e-5f);
  EXPECT_NEAR(scene.bounds.max.y, 0.2f + depth, 1e-6f);
}

TEST(Primitives, StairsAreSolidSteps) {
  SceneBuilder b;
  const int steps = 5;
  const float width = 1.2f, tread = 0.3f, riser = 0.18f;
  b.add_stairs("Stairs", glm::vec3(1, 0, 2), steps, width, tread, riser);
  double volume = 0.0;
  for (int k = 0; k < steps; ++k) volume += double(width) * tread * riser * (k + 1);
  expect_closed_volume(b, 0, volume);
  const Scene scene = b.build();
  expect_bounds(scene.bounds, glm::vec3(1, 0, 2),
                glm::vec3(1 + width, steps * riser, 2 + steps * tread), "stairs");
  // Tread k is the first surface seen from above at its middle.
  for (int k = 0; k < steps; ++k) {
    const glm::vec3 o(1.6f, 10.0f, 2.0f + (float(k) + 0.5f) * tread);
    float nearest = 1e9f;
    for (size_t t = 0; t < scene.triangle_count(); ++t) {
      const float d = ray_hit(o, glm::vec3(0, -1, 0), scene.positions[3 * t],
                              scene.positions[3 * t + 1], scene.positions[3 * t + 2]);
      if (d > 0.0f) nearest = std::min(nearest, d);
    }
    EXPECT_NEAR(10.0f - nearest, float(k + 1) * riser, 1e-5f) << "step " << k;
  }
  EXPECT_THROW(b.add_stairs("Bad", glm::vec3(0), 0, 1, 1, 1), snow::InputError);
}

TEST(Primitives, GableRoofMatchesPitchAndOverhang) {
  SceneBuilder b;
  const glm::vec3 min(-3, 3, -2), max(3, 99, 2);
  const float pitch = 40.0f, overhang = 0.5f, thickness = 0.2f;
  b.add_gable_roof("Roof", min, max, pitch, overhang, thickness);
  const float slope = std::tan(pitch * kPi / 180.0f);
  const float rise = thickness / std::cos(pitch * kPi / 180.0f);
  // Cross-section: two parallelograms of vertical side `rise` and horizontal
  // width half-depth + overhang.
  const double area = 2.0 * rise * (2.0 + overhang);
  expect_closed_volume(b, 0, area * (6.0 + 2.0 * overhang));
  const Scene scene = b.build();
  const float ridge = SceneBuilder::gable_roof_ridge_y(min, max, pitch, thickness);
  EXPECT_NEAR(ridge, 3.0f + 2.0f * slope + rise, 1e-5f);
  expect_bounds(scene.bounds, glm::vec3(-3.5f, 3.0f - overhang * slope, -2.5f),
                glm::vec3(3.5f, ridge, 2.5f), "roof");
  // Every upward-facing triangle slopes at the pitch.
  int up = 0;
  for (size_t t = 0; t < scene.triangle_count(); ++t) {
    const glm::vec3 n = scene.normals[3 * t];
    if (n.y > 0.1f) {
      ++up;
      EXPECT_NEAR(std::acos(n.y) * 180.0f / kPi, pitch, 1e-3f);
    }
  }
  EXPECT_EQ(up, 4);
  EXPECT_THROW(b.add_gable_roof("Flat", min, max, 0.0f, 0.5f, 0.2f), snow::InputError);
}

TEST(Primitives, BeamAndWallRing) {
  SceneBuilder b;
  const glm::vec3 from(0, 1, 0), to(3, 2, 4);  // horizontal length 5
  b.add_beam("Rail", from, to, 0.1f, 0.2f);
  expect_closed_volume(b, 0, 0.1 * 0.2 * 5.0);
  b.add_wall_ring("Walls", glm::vec3(0, 0, 0), glm::vec3(4, 3, 5), 0.25f);
  expect_closed_volume(b, 1, (4.0 * 5.0 - 3.5 * 4.5) * 3.0);
  // Genus 1: V - E + F = 0.
  const snow::BuilderObject& ring = b.objects()[1];
  const snow::TopologyReport r = snow::check_topology(ring.positions, ring.indices);
  EXPECT_EQ(long(r.vertices) - long(r.edges) + long(r.triangles), 0);
  EXPECT_THROW(b.add_beam("Vertical", from, from + glm::vec3(0, 1, 0), 0.1f, 0.1f),
               snow::InputError);
  EXPECT_THROW(b.add_wall_ring("Thick", glm::vec3(0), glm::vec3(1), 0.5f), snow::InputError);
}

TEST(Primitives, AddMeshChecksInputAndClosedness) {
  SceneBuilder b;
  const std::vector<glm::vec3> tet{{0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}};
  const int t = b.add_mesh("Tet", tet, {0, 1, 2, 0, 3, 1, 1, 3, 2, 2, 3, 0});
  EXPECT_TRUE(b.objects()[size_t(t)].closed);
  EXPECT_NEAR(snow::signed_volume(tet, b.objects()[size_t(t)].indices), 1.0 / 6.0, 1e-9);
  const int open = b.add_mesh("Open", tet, {0, 1, 2});
  EXPECT_FALSE(b.objects()[size_t(open)].closed);
  EXPECT_THROW(b.add_mesh("Bad", tet, {0, 1, 4}), snow::InputError);
  EXPECT_THROW(b.add_mesh("Bad", tet, {0, 1}), snow::InputError);
  EXPECT_THROW(b.add_box("Bad", glm::vec3(0), glm::vec3(1), /*material=*/3), snow::InputError);
  EXPECT_THROW(b.add_box("Bad", glm::vec3(1), glm::vec3(0)), snow::InputError);
  EXPECT_EQ(b.find_object("Open"), open);
  EXPECT_EQ(b.find_object("Nope"), -1);
}

TEST(Primitives, TopologyReportFindsDefects) {
  const std::vector<glm::vec3> p{{0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}};
  // One face flipped: three edges used twice in the same direction.
  const auto flipped = snow::check_topology(p, {0, 1, 2, 0, 3, 1, 1, 3, 2, 0, 3, 2});
  EXPECT_EQ(flipped.misoriented_edges, 3u);
  EXPECT_FALSE(flipped.closed());
  // A fin: edge 0-1 used by three triangles.
  const auto fin = snow::check_topology(p, {0, 1, 2, 1, 0, 3, 0, 1, 3});
  EXPECT_EQ(fin.nonmanifold_edges, 1u);
  // Duplicate positions weld: two separate vertices at the same point.
  const std::vector<glm::vec3> dup{{0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {0, 0, 0}};
  const auto welded = snow::check_topology(dup, {0, 1, 2, 3, 2, 1});
  EXPECT_EQ(welded.vertices, 3u);
  EXPECT_EQ(welded.boundary_edges, 0u);  // a two-sided triangle closes
}

TEST(Builder, SceneObjectsMaterialsAndStats) {
  SceneBuilder b;
  const int red = b.add_material("Red", glm::vec4(1, 0, 0, 1), 0.5f, 0.25f);
  b.add_box("A", glm::vec3(0), glm::vec3(1), red);
  b.add_plane("B", 0.0f, glm::vec2(-1), glm::vec2(1));  // default material
  const Scene scene = b.build();
  ASSERT_EQ(scene.objects.size(), 2u);
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[1].name, "Default");
  EXPECT_EQ(scene.objects[0].material, 0);
  EXPECT_EQ(scene.objects[1].material, 1);
  EXPECT_EQ(scene.objects[1].node_path, "/B");
  EXPECT_EQ(scene.objects[0].first_triangle, 0u);
  EXPECT_EQ(scene.objects[0].triangle_count, 12u);
  EXPECT_EQ(scene.objects[1].first_triangle, 12u);
  EXPECT_EQ(scene.stats.triangles_read, 14u);
  EXPECT_EQ(scene.object_of_triangle(13), 1);
  EXPECT_TRUE(scene.uvs.empty());
  EXPECT_EQ(snow::find_object(scene, "B"), 1);

  const auto materials = b.materials();
  ASSERT_EQ(materials.size(), 2u);
  EXPECT_FLOAT_EQ(materials[0].roughness, 0.5f);
  EXPECT_FLOAT_EQ(materials[0].metallic, 0.25f);
  const auto meshes = b.meshes();
  ASSERT_EQ(meshes.size(), 2u);
  EXPECT_EQ(meshes[0].name, "A");
  EXPECT_EQ(meshes[1].material, 1);
  // A box splits into 6 faces x 4 corners with flat normals.
  EXPECT_EQ(meshes[0].positions.size(), 24u);
  ASSERT_EQ(meshes[0].normals.size(), 24u);
  for (size_t t = 0; t < meshes[0].indices.size(); t += 3) {
    const auto& m = meshes[0];
    const glm::vec3 n =
        glm::normalize(glm::cross(m.positions[m.indices[t + 1]] - m.positions[m.indices[t]],
                                  m.positions[m.indices[t + 2]] - m.positions[m.indices[t]]));
    for (int k = 0; k < 3; ++k) EXPECT_GT(glm::dot(m.normals[m.indices[t + k]], n), 0.9999f);
  }
}

// --- Canned scenes ----------------------------------------------------------------

TEST(CannedScenes, OpenPlane) {
  const Scene s = snow::make_open_plane(8.0f);
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].name, "Floor");
  expect_bounds(s.bounds, glm::vec3(-4, 0, -4), glm::vec3(4, 0, 4), "plane");
  expect_flat_normals(s);
}

TEST(CannedScenes, Table) {
  snow::TableDims d;
  d.table_height = 0.8f;
  d.table_size = 1.2f;
  d.floor_size = 5.0f;
  const Scene s = snow::make_table_scene(d);
  ASSERT_EQ(s.objects.size(), 6u);
  expect_scene_closed(s, {"Floor"});
  expect_flat_normals(s);
  expect_bounds(snow::object_bounds(s, 0), glm::vec3(-2.5f, 0, -2.5f), glm::vec3(2.5f, 0, 2.5f),
                "floor");
  EXPECT_EQ(s.objects[1].name, "TableTop");
  expect_bounds(snow::object_bounds(s, 1), glm::vec3(-0.6f, 0.8f - d.top_thickness, -0.6f),
                glm::vec3(0.6f, 0.8f, 0.6f), "top");
  const float lw = d.leg_width, lh = 0.8f - d.top_thickness;
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(s.objects[size_t(2 + k)].name, "TableLeg" + std::to_string(k));
    const float x = (k & 1) ? 0.6f - lw : -0.6f, z = (k & 2) ? 0.6f - lw : -0.6f;
    expect_bounds(snow::object_bounds(s, 2 + k), glm::vec3(x, 0, z), glm::vec3(x + lw, lh, z + lw),
                  "leg " + std::to_string(k));
  }
  // The positional overload gives the same scene.
  const Scene s2 = snow::make_table_scene(0.8f, 1.2f, 5.0f);
  EXPECT_EQ(s2.positions, s.positions);
}

TEST(CannedScenes, ClosedBoxIsSealed) {
  snow::ClosedBoxDims d;
  d.size = 1.0f;
  d.wall = 0.1f;
  const Scene s = snow::make_closed_box_scene(d);
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[1].name, "Box");
  expect_scene_closed(s, {"Floor"});
  EXPECT_NEAR(snow::object_signed_volume(s, 1), 1.0 - 0.8 * 0.8 * 0.8, 1e-5);
  expect_bounds(snow::object_bounds(s, 1), glm::vec3(-0.5f, 0, -0.5f), glm::vec3(0.5f, 1, 0.5f),
                "box");
  // Every ray from the inside hits the box.
  EXPECT_EQ(enclosed_fraction(s, glm::vec3(0.05f, 0.5f, -0.03f), 400), 1.0);
  EXPECT_LT(enclosed_fraction(s, glm::vec3(0, 1.5f, 0), 400), 0.6);
}

TEST(CannedScenes, Wall) {
  const Scene s = snow::make_wall_scene(2.5f, 8.0f, 12.0f);
  ASSERT_EQ(s.objects.size(), 2u);
  expect_scene_closed(s, {"Floor"});
  expect_bounds(snow::object_bounds(s, 1), glm::vec3(-4, 0, -0.1f), glm::vec3(4, 2.5f, 0.1f),
                "wall");
  expect_bounds(snow::object_bounds(s, 0), glm::vec3(-6, 0, -6), glm::vec3(6, 0, 6), "floor");
}

TEST(CannedScenes, HouseIsSealedUnderItsRoof) {
  snow::HouseDims d;
  d.roof_pitch_deg = 45.0f;
  const Scene s = snow::make_house_scene(d);
  const std::vector<std::string> names{"Floor",          "HouseWalls",     "HouseSlab",
                                       "HouseGableWest", "HouseGableEast", "HouseRoof"};
  ASSERT_EQ(s.objects.size(), names.size());
  for (size_t i = 0; i < names.size(); ++i) EXPECT_EQ(s.objects[i].name, names[i]);
  expect_scene_closed(s, {"Floor"});
  expect_flat_normals(s);
  const float hw = 0.5f * d.width, hd = 0.5f * d.depth, o = d.eaves_overhang;
  const float slope = std::tan(d.roof_pitch_deg * kPi / 180.0f);
  expect_bounds(snow::object_bounds(s, 1), glm::vec3(-hw, 0, -hd), glm::vec3(hw, d.wall_height, hd),
                "walls");
  const glm::vec3 roof_min(-hw, d.wall_height, -hd), roof_max(hw, 0, hd);
  expect_bounds(snow::object_bounds(s, 5), glm::vec3(-hw - o, d.wall_height - o * slope, -hd - o),
                glm::vec3(hw + o,
                          SceneBuilder::gable_roof_ridge_y(roof_min, roof_max, d.roof_pitch_deg,
                                                           d.roof_thickness),
                          hd + o),
                "roof");
  // Gables reach the roof's underside ridge.
  EXPECT_NEAR(snow::object_bounds(s, 3).max.y, d.wall_height + hd * slope, 1e-5f);
  // From inside, every direction hits the house (no gap to the sky or sideways).
  EXPECT_EQ(enclosed_fraction(s, glm::vec3(0.3f, 1.5f, 0.2f), 600), 1.0);
  EXPECT_EQ(enclosed_fraction(s, glm::vec3(-2.1f, 3.6f, -0.3f), 600), 1.0);  // in the attic
  // The pitch overload.
  const Scene steep = snow::make_house_scene(60.0f);
  EXPECT_GT(steep.bounds.max.y, s.bounds.max.y);
}

TEST(CannedScenes, StairsAndBowl) {
  snow::StairsDims sd;
  const Scene stairs = snow::make_stairs_scene(sd);
  ASSERT_EQ(stairs.objects.size(), 2u);
  expect_scene_closed(stairs, {"Floor"});
  const float half_run = 0.5f * float(sd.steps) * sd.tread;
  expect_bounds(snow::object_bounds(stairs, 1), glm::vec3(-0.5f * sd.step_width, 0, -half_run),
                glm::vec3(0.5f * sd.step_width, float(sd.steps) * sd.riser, half_run), "stairs");

  snow::BowlDims bd;
  const Scene bowl = snow::make_bowl_scene(bd);
  ASSERT_EQ(bowl.objects.size(), 2u);
  EXPECT_EQ(bowl.objects[1].name, "Bowl");
  expect_scene_closed(bowl, {"Floor"});
  const Bounds bb = snow::object_bounds(bowl, 1);
  EXPECT_NEAR(bb.max.x, bd.radius, 1e-5f);
  EXPECT_NEAR(bb.min.y, 0.0f, 1e-6f);
  EXPECT_NEAR(bb.max.y, bd.depth, 1e-6f);
}

// --- Courtyard ----------------------------------------------------------------------

namespace {
/// Footprint (xz bounds) of all objects whose name starts with one of `prefixes`.
Bounds group_bounds(const Scene& s, const std::vector<std::string>& prefixes) {
  Bounds b;
  for (int i = 0; i < int(s.objects.size()); ++i)
    for (const std::string& p : prefixes)
      if (s.objects[size_t(i)].name.rfind(p, 0) == 0) {
        const Bounds o = snow::object_bounds(s, i);
        b.extend(o.min);
        b.extend(o.max);
      }
  return b;
}
}  // namespace

TEST(Courtyard, ObjectsAreClosedNamedAndSpreadOut) {
  const SceneBuilder c = snow::make_courtyard();
  const Scene s = c.build();
  std::set<std::string> names;
  for (const auto& o : c.objects()) {
    EXPECT_TRUE(names.insert(o.name).second) << "duplicate name " << o.name;
    EXPECT_FALSE(o.name.empty());
    EXPECT_GE(o.material, 0) << o.name;
  }
  expect_scene_closed(s, {});
  expect_flat_normals(s);
  for (const char* name : {"Ground", "HouseWalls", "HouseSlab", "HouseRoof", "ShedWalls",
                           "ShedRoof", "TableTop", "TableLeg3", "BenchSeat", "Stairs", "Terrace",
                           "StairRail", "FountainBasin", "LampPole", "LampHead"})
    EXPECT_GE(snow::find_object(s, name), 0) << name;

  // Materials have distinct colours.
  const auto materials = c.materials();
  EXPECT_GE(materials.size(), 6u);
  for (size_t i = 0; i < materials.size(); ++i)
    for (size_t j = i + 1; j < materials.size(); ++j)
      EXPECT_GT(glm::length(glm::vec3(materials[i].base_color - materials[j].base_color)), 0.05f)
          << materials[i].name << " vs " << materials[j].name;

  // About 24 x 24 m, ground top at y = 0.
  EXPECT_NEAR(s.bounds.size().x, 24.0f, 1e-4f);
  EXPECT_NEAR(s.bounds.size().z, 24.0f, 1e-4f);
  EXPECT_NEAR(snow::object_bounds(s, snow::find_object(s, "Ground")).max.y, 0.0f, 1e-6f);

  // Table top at 0.75 m, 1.5 x 1 m.
  const Bounds top = snow::object_bounds(s, snow::find_object(s, "TableTop"));
  EXPECT_NEAR(top.max.y, 0.75f, 1e-5f);
  EXPECT_NEAR(top.size().x, 1.5f, 1e-5f);
  EXPECT_NEAR(top.size().z, 1.0f, 1e-5f);

  // House roof: pitched with eaves beyond the walls.
  const Bounds walls = snow::object_bounds(s, snow::find_object(s, "HouseWalls"));
  const Bounds roof = snow::object_bounds(s, snow::find_object(s, "HouseRoof"));
  EXPECT_NEAR(walls.max.y, 3.0f, 1e-5f);
  EXPECT_NEAR(walls.min.z - roof.min.z, 0.5f, 1e-5f);
  EXPECT_NEAR(roof.max.x - walls.max.x, 0.5f, 1e-5f);
  EXPECT_GT(roof.max.y, walls.max.y + 2.0f);

  // Stairs: 5 steps up to the terrace top.
  const Bounds stairs = snow::object_bounds(s, snow::find_object(s, "Stairs"));
  const Bounds terrace = snow::object_bounds(s, snow::find_object(s, "Terrace"));
  EXPECT_NEAR(stairs.max.z, terrace.min.z, 1e-5f);
  EXPECT_NEAR(terrace.max.y - stairs.max.y, 0.18f, 1e-5f);

  // Groups do not overlap or shelter each other: footprints at least 1 m apart.
  const std::vector<std::vector<std::string>> groups{
      {"House"},    {"Shed"}, {"Table"}, {"Bench"}, {"Stairs", "Terrace", "Rail", "StairRail"},
      {"Fountain"}, {"Lamp"}};
  std::vector<Bounds> boxes;
  for (const auto& g : groups) {
    boxes.push_back(group_bounds(s, g));
    ASSERT_FALSE(boxes.back().empty()) << g[0];
  }
  for (size_t i = 0; i < boxes.size(); ++i)
    for (size_t j = i + 1; j < boxes.size(); ++j) {
      const float gap_x =
          std::max(boxes[i].min.x - boxes[j].max.x, boxes[j].min.x - boxes[i].max.x);
      const float gap_z =
          std::max(boxes[i].min.z - boxes[j].max.z, boxes[j].min.z - boxes[i].max.z);
      EXPECT_GE(std::max(gap_x, gap_z), 1.0f) << groups[i][0] << " vs " << groups[j][0];
    }
}

// --- glTF writer -------------------------------------------------------------------

namespace {
tinygltf::Model courtyard_model(const SceneBuilder& c) {
  tinygltf::Model model;
  snow::append_meshes(model, c.meshes(), c.materials(), "Courtyard");
  return model;
}

/// Reads accessor `index` of `model` as floats (tightly packed VEC3).
std::vector<glm::vec3> read_vec3(const tinygltf::Model& model, int index) {
  const tinygltf::Accessor& a = model.accessors.at(size_t(index));
  const tinygltf::BufferView& v = model.bufferViews.at(size_t(a.bufferView));
  const auto& data = model.buffers.at(size_t(v.buffer)).data;
  std::vector<glm::vec3> out(a.count);
  EXPECT_LE(v.byteOffset + a.byteOffset + a.count * 12, data.size());
  std::memcpy(out.data(), data.data() + v.byteOffset + a.byteOffset, a.count * 12);
  return out;
}

void expect_courtyard_model(const tinygltf::Model& model, const SceneBuilder& c) {
  const auto meshes = c.meshes();
  const auto materials = c.materials();
  ASSERT_EQ(model.meshes.size(), meshes.size());
  ASSERT_EQ(model.nodes.size(), meshes.size() + 1);
  ASSERT_EQ(model.materials.size(), materials.size());
  ASSERT_EQ(model.buffers.size(), 1u);
  ASSERT_EQ(model.scenes.size(), 1u);
  ASSERT_EQ(model.defaultScene, 0);
  ASSERT_EQ(model.scenes[0].nodes.size(), 1u);
  const tinygltf::Node& root = model.nodes.at(size_t(model.scenes[0].nodes[0]));
  EXPECT_EQ(root.name, "Courtyard");
  ASSERT_EQ(root.children.size(), meshes.size());
  for (size_t i = 0; i < meshes.size(); ++i) {
    const tinygltf::Node& node = model.nodes.at(size_t(root.children[i]));
    EXPECT_EQ(node.name, meshes[i].name);
    const tinygltf::Mesh& mesh = model.meshes.at(size_t(node.mesh));
    ASSERT_EQ(mesh.primitives.size(), 1u);
    const tinygltf::Primitive& p = mesh.primitives[0];
    EXPECT_EQ(p.mode, TINYGLTF_MODE_TRIANGLES);
    EXPECT_EQ(p.material, meshes[i].material);
    ASSERT_EQ(p.attributes.count("POSITION"), 1u);
    ASSERT_EQ(p.attributes.count("NORMAL"), 1u);
    EXPECT_EQ(p.attributes.count("TEXCOORD_0"), 0u);
    const tinygltf::Accessor& pos = model.accessors.at(size_t(p.attributes.at("POSITION")));
    EXPECT_EQ(pos.count, meshes[i].positions.size());
    ASSERT_EQ(pos.minValues.size(), 3u);
    ASSERT_EQ(pos.maxValues.size(), 3u);
    EXPECT_EQ(model.accessors.at(size_t(p.attributes.at("NORMAL"))).count,
              meshes[i].normals.size());
    const tinygltf::Accessor& idx = model.accessors.at(size_t(p.indices));
    EXPECT_EQ(idx.count, meshes[i].indices.size());
    EXPECT_EQ(idx.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    EXPECT_EQ(read_vec3(model, p.attributes.at("POSITION")), meshes[i].positions) << mesh.name;
  }
  for (size_t i = 0; i < materials.size(); ++i) {
    const auto& pbr = model.materials[i].pbrMetallicRoughness;
    EXPECT_EQ(model.materials[i].name, materials[i].name);
    ASSERT_EQ(pbr.baseColorFactor.size(), 4u);
    EXPECT_NEAR(pbr.baseColorFactor[0], materials[i].base_color.r, 1e-6);
    EXPECT_NEAR(pbr.roughnessFactor, materials[i].roughness, 1e-6);
    EXPECT_NEAR(pbr.metallicFactor, materials[i].metallic, 1e-6);
  }
}
}  // namespace

TEST(GltfWriter, CourtyardRoundTripsThroughGlb) {
  const SceneBuilder c = snow::make_courtyard();
  const fs::path dir = temp_dir("glb");
  snow::save_gltf(courtyard_model(c), dir / "courtyard.glb");
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, (dir / "courtyard.glb").string()))
      << err;
  EXPECT_TRUE(warn.empty()) << warn;
  expect_courtyard_model(model, c);
  // Only the file itself is left in the folder (no temporaries).
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  // Deterministic: the same model writes the same bytes.
  snow::save_gltf(courtyard_model(c), dir / "again.glb");
  EXPECT_EQ(read_bytes(dir / "courtyard.glb"), read_bytes(dir / "again.glb"));
  EXPECT_LT(fs::file_size(dir / "courtyard.glb"), 1u << 20);
}

TEST(GltfWriter, CourtyardRoundTripsThroughGltfAndBin) {
  const SceneBuilder c = snow::make_courtyard();
  const fs::path dir = temp_dir("gltf");
  snow::save_gltf(courtyard_model(c), dir / "yard.gltf");
  ASSERT_TRUE(fs::exists(dir / "yard.bin"));
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadASCIIFromFile(&model, &err, &warn, (dir / "yard.gltf").string())) << err;
  EXPECT_EQ(model.buffers.at(0).uri, "yard.bin");
  EXPECT_EQ(model.buffers.at(0).data.size(), fs::file_size(dir / "yard.bin"));
  expect_courtyard_model(model, c);
}

TEST(GltfWriter, AppendsToAnExistingModel) {
  SceneBuilder a;
  const int white = a.add_material("White", glm::vec4(1));
  a.add_box("BoxA", glm::vec3(0), glm::vec3(1), white);
  SceneBuilder b;
  b.add_plane("PlaneB", 0.0f, glm::vec2(-1), glm::vec2(1));
  auto mb = b.meshes();
  mb[0].uvs.assign(mb[0].positions.size(), glm::vec2(0.5f));  // with TEXCOORD_0

  tinygltf::Model model;
  snow::append_meshes(model, a.meshes(), a.materials(), "First");
  const size_t bytes_after_first = model.buffers.at(0).data.size();
  snow::append_meshes(model, mb, b.materials(), "Second");
  ASSERT_EQ(model.buffers.size(), 1u);
  EXPECT_GT(model.buffers[0].data.size(), bytes_after_first);
  ASSERT_EQ(model.scenes.size(), 1u);
  ASSERT_EQ(model.scenes[0].nodes.size(), 2u);
  EXPECT_EQ(model.nodes.at(size_t(model.scenes[0].nodes[1])).name, "Second");
  ASSERT_EQ(model.materials.size(), 2u);
  EXPECT_EQ(model.meshes.at(1).primitives.at(0).material, 1);  // offset by the first call
  EXPECT_EQ(model.meshes.at(1).primitives.at(0).attributes.count("TEXCOORD_0"), 1u);
  for (const auto& view : model.bufferViews) EXPECT_EQ(view.byteOffset % 4, 0u);

  // Large meshes get 32-bit indices.
  snow::TriMesh big;
  big.name = "Big";
  for (uint32_t i = 0; i < 70000; ++i)
    big.positions.push_back(glm::vec3(float(i), 0, float(i % 7)));
  big.indices = {0, 1, 69999};
  snow::append_meshes(model, {big}, {snow::MeshMaterial{}}, "Third");
  EXPECT_EQ(model.accessors.at(size_t(model.meshes.back().primitives[0].indices)).componentType,
            TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
}

TEST(GltfWriter, RejectsBadInputAndReportsPaths) {
  tinygltf::Model model;
  snow::TriMesh bad;
  bad.name = "Bad";
  bad.positions = {glm::vec3(0), glm::vec3(1, 0, 0), glm::vec3(0, 0, 1)};
  bad.indices = {0, 1, 3};
  EXPECT_THROW(snow::append_meshes(model, {bad}, {snow::MeshMaterial{}}, "Root"), snow::InputError);
  bad.indices = {0, 1, 2};
  bad.material = 2;
  EXPECT_THROW(snow::append_meshes(model, {bad}, {snow::MeshMaterial{}}, "Root"), snow::InputError);
  bad.material = 0;
  snow::append_meshes(model, {bad}, {snow::MeshMaterial{}}, "Root");
  EXPECT_THROW(snow::save_gltf(model, temp_dir("ext") / "x.obj"), snow::InputError);
  try {
    snow::save_gltf(model, "/nonexistent_snow_dir/x.glb");
    FAIL() << "expected IOError";
  } catch (const snow::IOError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent_snow_dir/x.glb"), std::string::npos)
        << e.what();
  }
}

TEST(GltfWriter, CommittedCourtyardAssetMatchesTheBuilder) {
  const fs::path path = fs::path(SNOW_SOURCE_DIR) / "assets/scenes/courtyard.glb";
  if (!fs::exists(path)) GTEST_SKIP() << path << " not generated yet";
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, path.string())) << err;
  expect_courtyard_model(model, snow::make_courtyard());
}
