// Tests of the glTF loader's opt-in parts (scene/load_gltf.h): line
// primitives (LoadSettings::lines) and node motions from animations
// (LoadSettings::motions), in the file's frame and after to_metres_y_up;
// and their broken or hostile forms, each one InputError. Every scene is
// built here in code (support/gltf_scene.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "scene/flat_ground.h"
#include "scene/frame.h"
#include "scene/load_gltf.h"
#include "support/gltf_scene.h"

namespace snow::test {
namespace {

constexpr float kStep = 1.0f / 60.0f;  // the longest step between motion samples (s)

snow::LoadSettings with_lines() {
  snow::LoadSettings settings;
  settings.lines = true;
  return settings;
}

snow::LoadSettings with_motions() {
  snow::LoadSettings settings;
  settings.motions = true;
  return settings;
}

glm::vec3 moved(const glm::mat4& m, const glm::vec3& p) { return glm::vec3(m * glm::vec4(p, 1)); }

/// The motion of `node` in `s`; fails the test when there is none.
const snow::NodeMotion& motion_of(const snow::Scene& s, int node) {
  for (const snow::NodeMotion& m : s.motions)
    if (m.node == node) return m;
  ADD_FAILURE() << "no motion for node " << node;
  static const snow::NodeMotion none{-1, {0.0f}, {glm::mat4(1.0f)}};
  return none;
}

/// The move of `m` at time `t` (s), which must be one of its sample times.
glm::mat4 move_at(const snow::NodeMotion& m, float t) {
  const auto it = std::min_element(m.times.begin(), m.times.end(), [&](float a, float b) {
    return std::abs(a - t) < std::abs(b - t);
  });
  EXPECT_NEAR(*it, t, 1e-6f) << "no sample at " << t << " s";
  return m.moves[size_t(it - m.times.begin())];
}

/// Expects times strictly ascending, from `first` to `last`, no step over kStep.
void expect_sampled(const snow::NodeMotion& m, float first, float last) {
  ASSERT_FALSE(m.times.empty());
  ASSERT_EQ(m.times.size(), m.moves.size());
  EXPECT_FLOAT_EQ(m.times.front(), first);
  EXPECT_FLOAT_EQ(m.times.back(), last);
  for (size_t k = 1; k < m.times.size(); ++k) {
    EXPECT_GT(m.times[k], m.times[k - 1]);
    EXPECT_LE(m.times[k] - m.times[k - 1], kStep + 1e-6f) << "at " << m.times[k];
  }
}

/// A quaternion (x, y, z, w) turning `degrees` about +Y.
glm::vec4 about_y(double degrees) {
  const double half = degrees * M_PI / 360.0;
  return glm::vec4(0.0f, float(std::sin(half)), 0.0f, float(std::cos(half)));
}

/// Gltf with the triangle mesh on a node (index in *node) animated by one
/// LINEAR translation channel from x = 0 to x = 4 over 2 s.
Gltf translated_gltf(int* node, const std::string& interpolation = "LINEAR") {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  *node = g.node({{"name", "Mover"}, {"mesh", mesh}});
  g.scene({*node});
  g.animation(*node, "translation", g.scalars({0.0f, 2.0f}), g.vec3s({{0, 0, 0}, {4, 0, 0}}),
              interpolation);
  return g;
}

// --- lines -------------------------------------------------------------------------

/// Gltf with one mesh: a triangle, then LINES, LINE_LOOP, LINE_STRIP
/// primitives over the square (0,0,0) (3,0,0) (3,0,3) (0,0,3), then a
/// POINTS primitive; on a node translated by (10, 0, 0) and scaled by 2.
Gltf lines_gltf(int* node) {
  Gltf g;
  const int square = g.positions({{0, 0, 0}, {3, 0, 0}, {3, 0, 3}, {0, 0, 3}});
  const int triangle = g.positions(kUpTriangle);
  json primitives = json::array();
  primitives.push_back({{"attributes", {{"POSITION", triangle}}}});
  for (int mode : {1, 2, 3, 0})
    primitives.push_back({{"attributes", {{"POSITION", square}}}, {"mode", mode}});
  const int mesh = g.mesh(primitives, "Fence");
  *node =
      g.node({{"name", "Yard"}, {"mesh", mesh}, {"translation", {10, 0, 0}}, {"scale", {2, 2, 2}}});
  g.scene({*node});
  return g;
}

TEST_F(SceneLoad, LinesOfEachModeInWorldSpace) {
  int node = 0;
  Gltf g = lines_gltf(&node);
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "lines"), with_lines());
  EXPECT_EQ(s.triangle_count(), 1u);
  ASSERT_EQ(s.lines.size(), 3u);  // POINTS still skipped
  EXPECT_EQ(s.stats.primitives_skipped, 1u);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("POINTS"), std::string::npos) << s.warnings[0];
  // LINES: 2 segments; LINE_LOOP: 4 (closed); LINE_STRIP: 3.
  EXPECT_EQ(s.lines[0].segments.size(), 2u * 2);
  EXPECT_EQ(s.lines[1].segments.size(), 4u * 2);
  EXPECT_EQ(s.lines[2].segments.size(), 3u * 2);
  for (const snow::SceneLines& l : s.lines) {
    EXPECT_EQ(l.node, node);
    EXPECT_EQ(l.name, "Yard");
    EXPECT_EQ(l.node_path, "/Yard");
  }
  // World space: p * 2 + (10, 0, 0).
  expect_near(s.lines[0].segments[0], {10, 0, 0});
  expect_near(s.lines[0].segments[1], {16, 0, 0});
  expect_near(s.lines[0].segments[3], {10, 0, 6});
  // The loop closes: its last segment runs from the last point to the first.
  expect_near(s.lines[1].segments[6], {10, 0, 6});
  expect_near(s.lines[1].segments[7], {10, 0, 0});
  // The strip does not.
  expect_near(s.lines[2].segments[5], {10, 0, 6});
  // Lines do not count in the bounds (the triangle's only).
  expect_near(s.bounds.max, {12, 0, 2});
}

TEST_F(SceneLoad, LinesAreSkippedWithAWarningByDefault) {
  int node = 0;
  Gltf g = lines_gltf(&node);
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "lines"));
  EXPECT_TRUE(s.lines.empty());
  EXPECT_EQ(s.triangle_count(), 1u);
  EXPECT_EQ(s.stats.primitives_skipped, 4u);
  ASSERT_EQ(s.warnings.size(), 4u);
  for (const char* mode : {"(LINES)", "(LINE_LOOP)", "(LINE_STRIP)", "(POINTS)"}) {
    const bool warned =
        std::any_of(s.warnings.begin(), s.warnings.end(), [&](const std::string& w) {
          return w.find(mode) != std::string::npos && w.find("Fence") != std::string::npos;
        });
    EXPECT_TRUE(warned) << mode;
  }
}

TEST_F(SceneLoad, LinesDropZeroLengthSegmentsAndShortStrips) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int points = g.positions({{0, 0, 0}, {0, 0, 0}, {1, 0, 0}});
  json& primitives = g.doc["meshes"][size_t(mesh)]["primitives"];
  // LINES: one zero-length segment (repeated point), one real; odd count.
  primitives.push_back({{"attributes", {{"POSITION", points}}},
                        {"indices", g.indices8({0, 1, 1, 2, 2})},
                        {"mode", 1}});
  // LINE_STRIP and LINE_LOOP of one point: nothing.
  primitives.push_back(
      {{"attributes", {{"POSITION", points}}}, {"indices", g.indices8({2})}, {"mode", 3}});
  primitives.push_back(
      {{"attributes", {{"POSITION", points}}}, {"indices", g.indices8({2})}, {"mode", 2}});
  // LINE_LOOP of two points: one segment, not two.
  primitives.push_back(
      {{"attributes", {{"POSITION", points}}}, {"indices", g.indices8({1, 2})}, {"mode", 2}});
  // Two nodes instance the mesh: one SceneLines each.
  g.scene({g.node({{"mesh", mesh}}), g.node({{"mesh", mesh}, {"translation", {0, 5, 0}}})});
  const snow::Scene s = snow::load_scene(g.write_gltf(dir_, "short"), with_lines());
  ASSERT_EQ(s.lines.size(), 4u);
  EXPECT_EQ(s.lines[0].segments.size(), 2u);
  expect_near(s.lines[0].segments[0], {0, 0, 0});
  expect_near(s.lines[0].segments[1], {1, 0, 0});
  EXPECT_EQ(s.lines[1].segments.size(), 2u);
  expect_near(s.lines[2].segments[1], {1, 5, 0});
  EXPECT_EQ(s.lines[2].node, 1);
  const bool odd_warned =
      std::any_of(s.warnings.begin(), s.warnings.end(),
                  [](const std::string& w) { return w.find("is odd") != std::string::npos; });
  EXPECT_TRUE(odd_warned);
}

TEST_F(SceneLoad, LinesHostileInput) {
  {
    int mesh = 0;
    Gltf g = triangle_gltf(&mesh);
    const int points = g.positions({{0, 0, 0}, {1, 0, 0}});
    g.doc["meshes"][size_t(mesh)]["primitives"].push_back(
        {{"attributes", {{"POSITION", points}}}, {"indices", g.indices8({0, 7})}, {"mode", 1}});
    g.scene({g.node({{"mesh", mesh}})});
    const fs::path path = g.write_glb(dir_, "index");
    expect_input_error(path, "index 7", with_lines());
    expect_input_error(path, "out of range (2 vertices)", with_lines());
    EXPECT_NO_THROW(snow::load_scene(path));  // skipped without LoadSettings::lines
  }
  {
    int mesh = 0;
    Gltf g = triangle_gltf(&mesh);
    const float inf = std::numeric_limits<float>::infinity();
    const int points = g.positions({{0, 0, 0}, {inf, 0, 0}});
    g.doc["meshes"][size_t(mesh)]["primitives"].push_back(
        {{"attributes", {{"POSITION", points}}}, {"mode", 3}});
    g.scene({g.node({{"mesh", mesh}})});
    expect_input_error(g.write_glb(dir_, "inf"), "not finite", with_lines());
  }
  {
    // Finite in the file, not in world space.
    int mesh = 0;
    Gltf g = triangle_gltf(&mesh);
    const int points = g.positions({{0, 0, 0}, {3e38f, 0, 0}});
    g.doc["meshes"][size_t(mesh)]["primitives"].push_back(
        {{"attributes", {{"POSITION", points}}}, {"mode", 3}});
    g.scene({g.node({{"mesh", mesh}, {"scale", {10, 1, 1}}})});
    expect_input_error(g.write_glb(dir_, "overflow"), "not finite in world space", with_lines());
  }
  {
    Gltf g = triangle_gltf();
    g.scene({g.node({{"mesh", 0}})});
    snow::LoadSettings settings = with_lines();
    settings.limits.max_line_segments = 1;
    const int points = g.positions({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}});
    g.doc["meshes"][0]["primitives"].push_back(
        {{"attributes", {{"POSITION", points}}}, {"mode", 3}});
    expect_input_error(g.write_glb(dir_, "many"), "max_line_segments", settings);
  }
}

// --- motions -----------------------------------------------------------------------

TEST_F(SceneLoad, MotionLinearTranslation) {
  int node = 0;
  Gltf g = translated_gltf(&node);
  const int still = g.node({{"mesh", 0}, {"translation", {0, 0, 9}}});
  g.scene({node, still});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "linear"), with_motions());
  ASSERT_EQ(s.motions.size(), 1u);  // the node without animation has none
  const snow::NodeMotion& m = motion_of(s, node);
  expect_sampled(m, 0.0f, 2.0f);
  EXPECT_GE(m.times.size(), 121u);
  expect_near(moved(move_at(m, 0.0f), {0, 0, 0}), {0, 0, 0});
  expect_near(moved(move_at(m, 1.0f), {0, 0, 0}), {2, 0, 0});
  expect_near(moved(move_at(m, 1.0f), {1, 2, 3}), {3, 2, 3});
  expect_near(moved(move_at(m, 0.5f), {0, 0, 0}), {1, 0, 0});
  expect_near(moved(move_at(m, 2.0f), {0, 0, 0}), {4, 0, 0});
  // Without LoadSettings::motions, no motions.
  EXPECT_TRUE(snow::load_scene(g.write_glb(dir_, "off")).motions.empty());
}

TEST_F(SceneLoad, MotionRotationSlerpsOnTheShorterArc) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int node = g.node({{"mesh", mesh}});
  g.scene({node});
  // 0 to 90 degrees about +Y over 1 s; the second key negated (the same
  // rotation, the other hemisphere): still the short way.
  g.animation(node, "rotation", g.scalars({0.0f, 1.0f}), g.vec4s({about_y(0), -about_y(90)}));
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "slerp"), with_motions());
  const snow::NodeMotion& m = motion_of(s, node);
  expect_sampled(m, 0.0f, 1.0f);
  const float h = std::sqrt(0.5f);
  expect_near(moved(move_at(m, 0.5f), {1, 0, 0}), {h, 0, -h});  // 45 degrees
  expect_near(moved(move_at(m, 1.0f), {1, 0, 0}), {0, 0, -1});
  // A quarter of the way: 22.5 degrees (slerp, not lerp of the quaternion).
  const float a = float(22.5 * M_PI / 180.0);
  expect_near(moved(move_at(m, 0.25f), {1, 0, 0}), {std::cos(a), 0, -std::sin(a)});
}

TEST_F(SceneLoad, MotionStepHolds) {
  int node = 0;
  Gltf g = translated_gltf(&node, "STEP");
  g.doc["animations"].clear();
  g.animation(node, "translation", g.scalars({0.0f, 1.0f, 2.0f}),
              g.vec3s({{0, 0, 0}, {5, 0, 0}, {7, 0, 0}}), "STEP");
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "step"), with_motions());
  const snow::NodeMotion& m = motion_of(s, node);
  expect_sampled(m, 0.0f, 2.0f);
  expect_near(moved(move_at(m, 0.5f), {0, 0, 0}), {0, 0, 0});
  expect_near(moved(move_at(m, 1.0f), {0, 0, 0}), {5, 0, 0});
  expect_near(moved(move_at(m, 1.5f), {0, 0, 0}), {5, 0, 0});
  expect_near(moved(move_at(m, 2.0f), {0, 0, 0}), {7, 0, 0});
}

TEST_F(SceneLoad, MotionCubicSplinePassesThroughItsKeys) {
  int node = 0;
  Gltf g = translated_gltf(&node);
  g.doc["animations"].clear();
  // Keys x = 0, 3, 1 at 0, 1, 2 s; zero tangents.
  const glm::vec3 z(0);
  g.animation(node, "translation", g.scalars({0.0f, 1.0f, 2.0f}),
              g.vec3s({z, {0, 0, 0}, z, z, {3, 0, 0}, z, z, {1, 0, 0}, z}), "CUBICSPLINE");
  // A rotation channel, 0 to 90 degrees with zero tangents: the result is
  // normalized (a pure rotation), though the spline's quaternion is shorter.
  const glm::vec4 q0(0);
  g.animation(node, "rotation", g.scalars({0.0f, 2.0f}),
              g.vec4s({q0, about_y(0), q0, q0, about_y(90), q0}), "CUBICSPLINE");
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "cubic"), with_motions());
  const snow::NodeMotion& m = motion_of(s, node);
  expect_sampled(m, 0.0f, 2.0f);
  expect_near(moved(move_at(m, 1.0f), {0, 0, 0}), {3, 0, 0});
  expect_near(moved(move_at(m, 2.0f), {0, 0, 0}), {1, 0, 0});
  // Between keys, Hermite with zero tangents: x = 3 (3u^2 - 2u^3); u = 0.25.
  expect_near(moved(move_at(m, 0.25f), {0, 0, 0}), {3 * 0.15625f, 0, 0});
  expect_near(moved(move_at(m, 1.25f), {0, 0, 0}), {3 * (1 - 0.15625f) + 0.15625f, 0, 0});
  const glm::mat3 linear(move_at(m, 1.0f));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(glm::length(linear[c]), 1.0f, 1e-5f) << c;
  EXPECT_NEAR(glm::determinant(linear), 1.0f, 1e-5f);
  // At the middle, the rotation is halfway by symmetry: 45 degrees.
  const float h = std::sqrt(0.5f);
  expect_near(glm::vec3(move_at(m, 1.0f) * glm::vec4(1, 0, 0, 0)), {h, 0, -h});
}

TEST_F(SceneLoad, MotionOfAChildComposesItsParents) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int child = g.node({{"name", "Wheel"}, {"mesh", mesh}, {"translation", {2, 0, 0}}});
  const int middle = g.node({{"name", "Axle"}, {"scale", {1, 1, 1}}, {"children", {child}}});
  const int parent = g.node({{"name", "Car"}, {"children", {middle}}});
  g.scene({parent});
  // The parent turns 90 degrees about +Y over 1 s; the child rises by 1.
  g.animation(parent, "rotation", g.scalars({0.0f, 1.0f}), g.vec4s({about_y(0), about_y(90)}));
  g.animation(child, "translation", g.scalars({0.0f, 1.0f}), g.vec3s({{2, 0, 0}, {2, 1, 0}}));
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "child"), with_motions());
  ASSERT_EQ(s.motions.size(), 1u);  // only the node with a mesh
  const snow::NodeMotion& m = motion_of(s, child);
  expect_sampled(m, 0.0f, 1.0f);
  // The child's origin, (2, 0, 0) at rest, is at R90 (2, 1, 0) at 1 s.
  expect_near(moved(move_at(m, 1.0f), {2, 0, 0}), {0, 1, -2});
  expect_near(moved(move_at(m, 0.0f), {2, 0, 0}), {2, 0, 0});
  const float h = std::sqrt(0.5f);
  expect_near(moved(move_at(m, 0.5f), {2, 0, 0}), {2 * h, 0.5f, -2 * h});
}

TEST_F(SceneLoad, MotionIsRelativeToTheRestPose) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  // At rest at x = 10; the animation runs from the origin to z = 5.
  const int node = g.node({{"mesh", mesh}, {"translation", {10, 0, 0}}});
  g.scene({node});
  g.animation(node, "translation", g.scalars({1.0f, 2.0f}), g.vec3s({{0, 0, 0}, {0, 0, 5}}));
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "rest"), with_motions());
  expect_near(corner(s, 0, 0), {10, 0, 0});  // the geometry stays at rest
  const snow::NodeMotion& m = motion_of(s, node);
  expect_sampled(m, 1.0f, 2.0f);
  expect_near(moved(m.moves.front(), {10, 0, 0}), {0, 0, 0});
  expect_near(moved(m.moves.front(), {11, 0, 1}), {1, 0, 1});
  expect_near(moved(m.moves.back(), {10, 0, 0}), {0, 0, 5});
}

TEST_F(SceneLoad, MotionOfGpuInstancesIsTheirNodes) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int t = g.vec3s({{0, 0, 0}, {5, 0, 0}, {0, 0, 5}});
  const int node = g.node(
      {{"mesh", mesh},
       {"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", t}}}}}}}});
  g.scene({node});
  g.doc["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  g.animation(node, "scale", g.scalars({0.0f, 1.0f}), g.vec3s({{1, 1, 1}, {2, 2, 2}}));
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "gpu"), with_motions());
  EXPECT_EQ(s.objects.size(), 3u);
  ASSERT_EQ(s.motions.size(), 1u);
  // The instance at (5, 0, 0) is scaled with its node, about the node's origin.
  expect_near(moved(move_at(s.motions[0], 1.0f), {5, 0, 0}), {10, 0, 0});
}

TEST_F(SceneLoad, MotionsAndLinesFollowTheFrame) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int points = g.positions({{0, 0, 0}, {100, 0, 300}});
  g.doc["meshes"][size_t(mesh)]["primitives"].push_back(
      {{"attributes", {{"POSITION", points}}}, {"mode", 1}});
  const int node = g.node({{"mesh", mesh}, {"translation", {50, 0, 0}}});
  g.scene({node});
  // Centimetres, +Z up: the node turns about the file's +Z and moves along it.
  const glm::vec4 about_z(0.0f, 0.0f, std::sin(0.3f), std::cos(0.3f));
  g.animation(node, "rotation", g.scalars({0.0f, 1.0f}), g.vec4s({about_z, about_z}));
  g.animation(node, "translation", g.scalars({0.0f, 1.0f}), g.vec3s({{50, 0, 0}, {50, 20, 200}}));
  snow::LoadSettings settings = with_motions();
  settings.lines = true;
  snow::Scene s = snow::load_scene(g.write_glb(dir_, "frame"), settings);
  const snow::Scene file = s;
  const snow::FileFrame frame{0.01f, true};
  snow::to_metres_y_up(s, frame);
  const auto to_run = [](const glm::vec3& p) { return glm::vec3(p.x, p.z, -p.y) * 0.01f; };
  ASSERT_EQ(s.lines.size(), 1u);
  expect_near(s.lines[0].segments[1], to_run(file.lines[0].segments[1]));
  expect_near(s.lines[0].segments[1], {1.5f, 3.0f, 0.0f});
  ASSERT_EQ(s.motions.size(), 1u);
  ASSERT_EQ(s.motions[0].times, file.motions[0].times);
  for (const float t : {0.0f, 0.5f, 1.0f}) {
    for (const glm::vec3& p : {glm::vec3(50, 0, 0), glm::vec3(150, 40, 300)}) {
      const glm::vec3 moved_then_framed = to_run(moved(move_at(file.motions[0], t), p));
      const glm::vec3 framed_then_moved = moved(move_at(s.motions[0], t), to_run(p));
      expect_near(framed_then_moved, moved_then_framed, 1e-4f);
    }
  }
  // At 1 s the node has risen by 2 m (+Z in the file is +Y in the run).
  expect_near(moved(move_at(s.motions[0], 1.0f), to_run({50, 0, 0})), {0.5f, 2.0f, -0.2f}, 1e-4f);
}

TEST_F(SceneLoad, MotionsAndLinesPassThroughSceneFilters) {
  int node = 0;
  Gltf g = translated_gltf(&node);
  const int points = g.positions({{0, 0, 0}, {1, 0, 0}});
  g.doc["meshes"][0]["primitives"].push_back({{"attributes", {{"POSITION", points}}}, {"mode", 1}});
  snow::LoadSettings settings = with_motions();
  settings.lines = true;
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "filters"), settings);
  ASSERT_EQ(s.lines.size(), 1u);
  ASSERT_EQ(s.motions.size(), 1u);
  const snow::Scene bare = snow::without_geometry(s);
  EXPECT_EQ(bare.triangle_count(), 0u);
  ASSERT_EQ(bare.lines.size(), 1u);
  EXPECT_EQ(bare.lines[0].segments, s.lines[0].segments);
  ASSERT_EQ(bare.motions.size(), 1u);
  EXPECT_EQ(bare.motions[0].times, s.motions[0].times);
  snow::FlatGround ground;
  ground.object = 0;
  snow::Bounds region;
  region.extend({0, 0, 0});
  region.extend({0.5f, 0, 0.5f});
  const snow::Scene clipped = snow::with_ground_clipped(s, ground, region);
  EXPECT_EQ(clipped.triangle_count(), 2u);
  ASSERT_EQ(clipped.lines.size(), 1u);
  EXPECT_EQ(clipped.lines[0].segments, s.lines[0].segments);
  ASSERT_EQ(clipped.motions.size(), 1u);
  EXPECT_EQ(clipped.motions[0].moves, s.motions[0].moves);
}

// --- broken and hostile animations ----------------------------------------------------

/// The file of translated_gltf with `edit` applied to it, written as .glb.
template <class Edit>
fs::path broken_motion(const fs::path& dir, const std::string& name, Edit edit) {
  int node = 0;
  Gltf g = translated_gltf(&node);
  edit(g);
  return g.write_glb(dir, name);
}

TEST_F(SceneLoad, MotionHostileAccessors) {
  const auto sampler = [](Gltf& g) -> json& { return g.doc["animations"][0]["samplers"][0]; };
  expect_input_error(broken_motion(dir_, "input_range", [&](Gltf& g) { sampler(g)["input"] = 99; }),
                     "accessor 99 is out of range", with_motions());
  expect_input_error(broken_motion(dir_, "input_type",
                                   [&](Gltf& g) {
                                     sampler(g)["input"] = g.vec3s({{0, 0, 0}});
                                   }),
                     "must be SCALAR float", with_motions());
  expect_input_error(broken_motion(dir_, "output_type",
                                   [&](Gltf& g) {
                                     sampler(g)["output"] = g.vec4s({glm::vec4(0), glm::vec4(1)});
                                   }),
                     "must be VEC3 float", with_motions());
  expect_input_error(broken_motion(dir_, "output_count",
                                   [&](Gltf& g) {
                                     sampler(g)["output"] = g.vec3s({{0, 0, 0}});
                                   }),
                     "has 1 elements, not 2", with_motions());
  expect_input_error(broken_motion(dir_, "cubic_count",
                                   [&](Gltf& g) { sampler(g)["interpolation"] = "CUBICSPLINE"; }),
                     "not 6", with_motions());
  expect_input_error(
      broken_motion(dir_, "short_view", [&](Gltf& g) { g.doc["accessors"][2]["count"] = 1000; }),
      "need", with_motions());
}

TEST_F(SceneLoad, MotionHostileValues) {
  const auto sampler = [](Gltf& g) -> json& { return g.doc["animations"][0]["samplers"][0]; };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  expect_input_error(broken_motion(dir_, "order",
                                   [&](Gltf& g) {
                                     sampler(g)["input"] = g.scalars({1.0f, 1.0f});
                                   }),
                     "not strictly increasing", with_motions());
  expect_input_error(broken_motion(dir_, "backward",
                                   [&](Gltf& g) {
                                     sampler(g)["input"] = g.scalars({2.0f, 1.0f});
                                   }),
                     "not strictly increasing", with_motions());
  expect_input_error(broken_motion(dir_, "time_nan",
                                   [&](Gltf& g) {
                                     sampler(g)["input"] = g.scalars({0.0f, nan});
                                   }),
                     "not finite", with_motions());
  expect_input_error(broken_motion(dir_, "value_inf",
                                   [&](Gltf& g) {
                                     sampler(g)["output"] = g.vec3s({{0, 0, 0}, {inf, 0, 0}});
                                   }),
                     "element 1 is not finite", with_motions());
  expect_input_error(
      broken_motion(dir_, "zero_quaternion",
                    [&](Gltf& g) {
                      g.doc["animations"][0]["channels"][0]["target"]["path"] = "rotation";
                      sampler(g)["output"] = g.vec4s({glm::vec4(0, 0, 0, 1), glm::vec4(0)});
                    }),
      "zero quaternion", with_motions());
  // Finite values that overflow relative to a tiny rest scale.
  expect_input_error(broken_motion(dir_, "overflow",
                                   [&](Gltf& g) {
                                     g.doc["nodes"][0]["scale"] = {1e-30, 1e-30, 1e-30};
                                     g.doc["animations"][0]["channels"][0]["target"]["path"] =
                                         "scale";
                                     sampler(g)["output"] = g.vec3s({{1, 1, 1}, {3e38f, 1, 1}});
                                   }),
                     "s is not finite (a singular", with_motions());
}

TEST_F(SceneLoad, MotionHostileChannels) {
  const auto channel = [](Gltf& g) -> json& { return g.doc["animations"][0]["channels"][0]; };
  expect_input_error(
      broken_motion(dir_, "node", [&](Gltf& g) { channel(g)["target"]["node"] = 99; }),
      "'node' = 99 is out of range", with_motions());
  expect_input_error(broken_motion(dir_, "sampler", [&](Gltf& g) { channel(g)["sampler"] = 5; }),
                     "'sampler' = 5 is out of range", with_motions());
  expect_input_error(
      broken_motion(
          dir_, "interpolation",
          [&](Gltf& g) { g.doc["animations"][0]["samplers"][0]["interpolation"] = "BEZIER"; }),
      "unknown interpolation 'BEZIER'", with_motions());
  expect_input_error(broken_motion(dir_, "target", [&](Gltf& g) { channel(g).erase("target"); }),
                     "has no 'target'", with_motions());
  expect_input_error(broken_motion(dir_, "matrix",
                                   [&](Gltf& g) {
                                     g.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0,
                                                                    0, 0, 1, 0, 0, 0, 0, 1};
                                   }),
                     "has a 'matrix'", with_motions());
  // Without LoadSettings::motions the animations are not read at all.
  const fs::path broken = broken_motion(dir_, "unread", [&](Gltf& g) {
    channel(g)["sampler"] = 5;
    g.doc["animations"][0]["samplers"][0]["input"] = 99;
  });
  EXPECT_NO_THROW(snow::load_scene(broken));
  // Weights channels, and channels without a node, are ignored.
  const snow::Scene s = snow::load_scene(
      broken_motion(dir_, "ignored",
                    [&](Gltf& g) {
                      g.animation(0, "weights", g.scalars({0.0f, 9.0f}), g.scalars({0.0f, 1.0f}));
                      g.doc["animations"][1]["channels"].push_back(
                          {{"sampler", 0}, {"target", {{"path", "translation"}}}});
                    }),
      with_motions());
  ASSERT_EQ(s.motions.size(), 1u);
  EXPECT_FLOAT_EQ(s.motions[0].times.back(), 2.0f);
}

TEST_F(SceneLoad, MotionSampleLimit) {
  snow::LoadSettings settings = with_motions();
  settings.limits.max_motion_samples = 100;  // 2 s need 121 samples
  const fs::path path = broken_motion(dir_, "limit", [](Gltf&) {});
  expect_input_error(path, "max_motion_samples (100", settings);
  expect_input_error(path, "node 0 ('Mover')", settings);
  // Keyframes too: far apart in time (no fill), but more than the limit.
  settings.limits.max_motion_samples = 3;
  const fs::path keys = broken_motion(dir_, "keys", [](Gltf& g) {
    g.doc["animations"][0]["samplers"][0]["input"] = g.scalars({0, 1e-3f, 2e-3f, 3e-3f});
    g.doc["animations"][0]["samplers"][0]["output"] =
        g.vec3s({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}});
  });
  expect_input_error(keys, "more than 3 keyframes", settings);
  // Times far apart fail before any sample is stored.
  settings.limits.max_motion_samples = 1'000'000;
  const fs::path far = broken_motion(dir_, "far", [](Gltf& g) {
    g.doc["animations"][0]["samplers"][0]["input"] = g.scalars({0.0f, 1e30f});
  });
  expect_input_error(far, "max_motion_samples", settings);
}

}  // namespace
}  // namespace snow::test
