// Tests of the glTF loader (scene/load_gltf.h) on valid input: transforms and
// instancing, topologies and index types, accessors, materials and images,
// Draco, summaries, and the real scenes in ../shared/scenes. Every scene
// except those is built here in code (support/gltf_scene.h), written to a
// temporary folder and loaded. Broken and hostile input:
// test_scene_load_errors.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "scene/load_gltf.h"
#include "support/draco_quad.h"
#include "support/gltf_scene.h"

namespace snow::test {
namespace {

// --- transforms and instancing --------------------------------------------------

TEST_F(SceneLoad, NestedMatrixAndTrsTransforms) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  // child: matrix = uniform scale 2 then translate (10, 0, 0) (column-major)
  const int child = g.node({{"name", "Child"},
                            {"mesh", mesh},
                            {"matrix", {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 10, 0, 0, 1}}});
  // grandchild of root via TRS: rotate 90 degrees about +Y, translate (0, 5, 0)
  const double h = std::sqrt(0.5);
  const int rotated = g.node({{"name", "Rotated"},
                              {"mesh", mesh},
                              {"translation", {0, 5, 0}},
                              {"rotation", {0, h, 0, h}},
                              {"scale", {1, 1, 3}}});
  const int root =
      g.node({{"name", "Root"}, {"translation", {1, 2, 3}}, {"children", {child, rotated}}});
  g.scene({root});
  const snow::Scene s = snow::load_scene(g.write_gltf(dir_, "t"));
  ASSERT_EQ(s.triangle_count(), 2u);
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[0].node_path, "/Root/Child");
  EXPECT_EQ(s.objects[1].node_path, "/Root/Rotated");
  EXPECT_EQ(s.objects[0].name, "Child");
  // Child: p * 2 + (10,0,0) + (1,2,3)
  expect_near(corner(s, 0, 0), {11, 2, 3});
  expect_near(corner(s, 0, 1), {11, 2, 5});
  expect_near(corner(s, 0, 2), {13, 2, 3});
  // Rotated: scale z by 3, rotate +90 about Y (x -> -z, z -> x), + (0,5,0) + (1,2,3)
  expect_near(corner(s, 1, 0), {1, 7, 3});
  expect_near(corner(s, 1, 1), {1 + 3, 7, 3});
  expect_near(corner(s, 1, 2), {1, 7, 3 - 1});
  expect_near(face_normal(s, 0), {0, 1, 0});
  expect_near(face_normal(s, 1), {0, 1, 0});
  expect_near(s.normals[3], {0, 1, 0});  // file normals, rotated and non-uniformly scaled
  expect_near(s.bounds.min, {1, 2, 2});
  expect_near(s.bounds.max, {13, 7, 5});
  EXPECT_EQ(s.stats.nodes, 3u);
  EXPECT_EQ(s.stats.instances, 2u);
}

TEST_F(SceneLoad, InstancedMeshAppearsOncePerNode) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  std::vector<int> roots;
  for (int i = 0; i < 3; ++i)
    roots.push_back(g.node({{"mesh", mesh}, {"translation", {0, 0, 10 * i}}}));
  g.scene(roots);
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "inst"));
  ASSERT_EQ(s.triangle_count(), 3u);
  ASSERT_EQ(s.objects.size(), 3u);
  EXPECT_EQ(s.stats.instances, 3u);
  EXPECT_EQ(s.stats.triangles_read, 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(s.objects[size_t(i)].mesh, mesh);
    EXPECT_EQ(s.objects[size_t(i)].first_triangle, uint32_t(i));
    EXPECT_EQ(s.objects[size_t(i)].name, "Tri");  // unnamed node: mesh name
    EXPECT_EQ(s.objects[size_t(i)].node_path, "/node" + std::to_string(i));
    EXPECT_EQ(s.object_of_triangle(size_t(i)), i);
    expect_near(corner(s, size_t(i), 0), {0, 0, 10.0f * float(i)});
  }
}

TEST_F(SceneLoad, GpuInstancingExtension) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int t = g.vec3s({{0, 0, 0}, {5, 0, 0}, {0, 0, 5}, {5, 1, 5}});
  const int node = g.node(
      {{"mesh", mesh},
       {"translation", {0, 1, 0}},
       {"extensions", {{"EXT_mesh_gpu_instancing", {{"attributes", {{"TRANSLATION", t}}}}}}}});
  g.scene({node});
  g.doc["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "gpu"));
  ASSERT_EQ(s.triangle_count(), 4u);
  EXPECT_EQ(s.stats.instances, 4u);
  expect_near(corner(s, 3, 0), {5, 2, 5});
  EXPECT_TRUE(s.warnings.empty());
}

TEST_F(SceneLoad, MirroredNodeKeepsCounterClockwiseFacing) {
  for (bool normals : {true, false}) {
    int mesh = 0;
    Gltf g = triangle_gltf(&mesh, normals);
    const int mirrored = g.node({{"mesh", mesh}, {"scale", {-1, 1, 1}}});
    // Mirrored twice (parent and child): determinant positive again.
    const int inner =
        g.node({{"mesh", mesh}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1}}});
    const int outer = g.node({{"scale", {-1, 1, 1}}, {"children", {inner}}});
    // Mirrored in Y: the triangle now faces down, and must say so.
    const int flipped = g.node({{"mesh", mesh}, {"scale", {1, -1, 1}}});
    g.scene({mirrored, outer, flipped});
    const snow::Scene s = snow::load_scene(g.write_glb(dir_, normals ? "n" : "flat"));
    ASSERT_EQ(s.triangle_count(), 3u);
    for (size_t t = 0; t < 2; ++t) {
      expect_near(face_normal(s, t), {0, 1, 0});
      for (int k = 0; k < 3; ++k) expect_near(s.normals[3 * t + size_t(k)], {0, 1, 0});
    }
    expect_near(face_normal(s, 2), {0, -1, 0});
    for (int k = 0; k < 3; ++k) expect_near(s.normals[6 + size_t(k)], {0, -1, 0});
    // The mirrored copy really is mirrored: its corners lie at x <= 0.
    EXPECT_LE(std::max({corner(s, 0, 0).x, corner(s, 0, 1).x, corner(s, 0, 2).x}), 0.0f);
  }
}

// A primitive of many triangles is put into the scene in chunks on all
// cores: the degenerate ones (here every 1000th repeats an index, across
// the chunks' borders) are dropped, the rest keep their order and winding
// (a mirrored node flips each), and the bounds hold them all.
TEST_F(SceneLoad, LargePrimitiveKeepsItsTrianglesInOrder) {
  constexpr uint32_t kCount = 100000;
  std::vector<glm::vec3> p;
  std::vector<uint32_t> idx;
  for (uint32_t t = 0; t < kCount; ++t) {
    const float x = float(t % 400), z = float(t / 400);
    p.insert(p.end(), {{x, 0.001f * float(t), z}, {x, 0.0f, z + 1.0f}, {x + 1.0f, 0.0f, z}});
    const uint32_t v = 3 * t;
    if (t % 1000 == 999) {
      idx.insert(idx.end(), {v, v, v + 2});
    } else {
      idx.insert(idx.end(), {v, v + 1, v + 2});
    }
  }
  Gltf g;
  const int mesh = g.mesh(json::array(
      {{{"attributes", {{"POSITION", g.positions(p)}}}, {"indices", g.indices32(idx)}}}));
  g.scene({g.node({{"mesh", mesh}, {"scale", {-1, 1, 1}}})});
  for (const bool shading : {false, true}) {
    snow::LoadSettings settings;
    settings.shading = shading;
    const snow::Scene s = snow::load_scene(g.write_glb(dir_, "large"), settings);
    ASSERT_EQ(s.triangle_count(), kCount - kCount / 1000);
    EXPECT_EQ(s.stats.degenerate_dropped, kCount / 1000);
    EXPECT_EQ(s.normals.size(), shading ? s.positions.size() : 0u);
    uint32_t t = 0;
    for (size_t k = 0; k < s.triangle_count(); ++k, ++t) {
      if (t % 1000 == 999) ++t;  // dropped
      const glm::vec3 a = p[3 * t];
      ASSERT_EQ(s.positions[3 * k], glm::vec3(-a.x, a.y, a.z)) << k;
      ASSERT_EQ(s.positions[3 * k + 1].x, -(a.x + 1.0f)) << k;  // mirrored: b and c swap
    }
    EXPECT_EQ(s.bounds.min, glm::vec3(-400.0f, 0.0f, 0.0f));
    EXPECT_EQ(s.bounds.max, glm::vec3(0.0f, 0.001f * float(kCount - 2), float(kCount / 400)));
  }
}

// What a load reads, judged before it (the batch job starts a GPU's driver
// early only for large inputs): a .glb's size, a .gltf's plus the .bin files
// beside it; 0 for a missing file.
TEST(GltfInputBytes, CountsTheFileAndTheBuffersBesideAGltf) {
  const fs::path dir = temp_dir("input_bytes");
  write_text(dir / "scene.gltf", std::string(100, ' '));
  write_bytes(dir / "scene.bin", std::vector<uint8_t>(1000));
  write_bytes(dir / "more.BIN", std::vector<uint8_t>(20));
  write_bytes(dir / "texture.png", std::vector<uint8_t>(5000));
  write_bytes(dir / "other.glb", std::vector<uint8_t>(300));
  EXPECT_EQ(snow::gltf_input_bytes(dir / "scene.gltf"), 1120u);
  EXPECT_EQ(snow::gltf_input_bytes(dir / "other.glb"), 300u);
  EXPECT_EQ(snow::gltf_input_bytes(dir / "missing.glb"), 0u);
  fs::remove_all(dir);
}

TEST_F(SceneLoad, FileWithoutScenesLoadsEveryRootNode) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int child = g.node({{"mesh", mesh}, {"translation", {0, 1, 0}}});
  g.node({{"mesh", mesh}, {"children", {child}}});
  g.node({{"mesh", mesh}, {"translation", {0, 2, 0}}});
  g.doc.erase("scenes");
  const snow::Scene s = snow::load_scene(g.write_gltf(dir_, "noscene"));
  EXPECT_EQ(s.triangle_count(), 3u);
  EXPECT_EQ(s.stats.nodes, 3u);
}

TEST_F(SceneLoad, DefaultSceneIsTheSceneProperty) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int a = g.node({{"mesh", mesh}});
  const int b = g.node({{"mesh", mesh}, {"translation", {0, 3, 0}}});
  g.doc["scenes"] = json::array({{{"nodes", {a}}}, {{"nodes", {a, b}}}});
  g.doc["scene"] = 1;
  EXPECT_EQ(snow::load_scene(g.write_glb(dir_, "s1")).triangle_count(), 2u);
  g.doc.erase("scene");
  EXPECT_EQ(snow::load_scene(g.write_glb(dir_, "s0")).triangle_count(), 1u);
}

TEST_F(SceneLoad, SceneListingAChildNodeWarns) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  const int child = g.node({{"name", "Leaf"}, {"mesh", mesh}});
  g.node({{"translation", {0, 9, 0}}, {"children", {child}}});
  g.scene({child});  // invalid: scenes list root nodes only
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "child_root"));
  EXPECT_EQ(s.triangle_count(), 1u);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("'Leaf'"), std::string::npos) << s.warnings[0];
}

TEST_F(SceneLoad, VeryDeepHierarchyLoads) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  constexpr int kDepth = 100000;
  json nodes = json::array();
  for (int i = 0; i < kDepth; ++i) {
    json n = {{"translation", {0, 0.001, 0}}};
    if (i + 1 < kDepth)
      n["children"] = {i + 1};
    else
      n["mesh"] = mesh;
    nodes.push_back(n);
  }
  g.doc["nodes"] = nodes;
  g.scene({0});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "deep"));
  ASSERT_EQ(s.triangle_count(), 1u);
  EXPECT_EQ(s.stats.nodes, uint64_t(kDepth));
  EXPECT_NEAR(corner(s, 0, 0).y, 0.001 * kDepth, 1e-3);
  EXPECT_LT(s.objects[0].node_path.size(), 1000u);  // elided, not 100,000 names
  EXPECT_NE(s.objects[0].node_path.find("levels"), std::string::npos);
}

// --- topology and index types -------------------------------------------------------

TEST_F(SceneLoad, TriangleStripAndFan) {
  Gltf g;
  // Strip over a 3 x 1 row of quads in the XY plane, facing +Z: vertices
  // alternate top, bottom (t0, b0, t1, b1, ...) so the first triangle is CCW.
  std::vector<glm::vec3> strip_ccw;
  for (int i = 0; i < 4; ++i) {
    strip_ccw.push_back({float(i), 1, 0});
    strip_ccw.push_back({float(i), 0, 0});
  }
  const int strip_pos = g.positions(strip_ccw);
  // Fan: centre + 5 points on the upper half circle, counter-clockwise, in z = 2.
  std::vector<glm::vec3> fan = {{0, 0, 2}};
  for (int i = 0; i <= 4; ++i) {
    const float a = float(M_PI) * float(i) / 4;
    fan.push_back({std::cos(a), std::sin(a), 2});
  }
  const int fan_pos = g.positions(fan);
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", strip_pos}}}, {"mode", 5}},
                                       {{"attributes", {{"POSITION", fan_pos}}}, {"mode", 6}}}));
  g.scene({g.node({{"mesh", mesh}})});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "stripfan"));
  ASSERT_EQ(s.triangle_count(), 6u + 4u);
  EXPECT_EQ(s.objects.size(), 2u);
  for (size_t t = 0; t < s.triangle_count(); ++t) expect_near(face_normal(s, t), {0, 0, 1});
  // Strip covers 3 x 1; fan covers 4 triangles of the half disc (apex angle 45 degrees).
  double strip_area = 0;
  for (size_t t = 0; t < 6; ++t)
    strip_area += 0.5 * glm::length(glm::cross(corner(s, t, 1) - corner(s, t, 0),
                                               corner(s, t, 2) - corner(s, t, 0)));
  EXPECT_NEAR(strip_area, 3.0, 1e-5);
  EXPECT_NEAR(total_area(s) - strip_area, 4 * 0.5 * std::sin(M_PI / 4), 1e-5);
}

TEST_F(SceneLoad, IndexTypesAndNonIndexedAgree) {
  const std::vector<glm::vec3> quad = {{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}};
  const std::vector<uint32_t> idx = {0, 1, 2, 0, 2, 3};
  Gltf g;
  const int pos = g.positions(quad);
  const int i8 = g.indices8({0, 1, 2, 0, 2, 3});
  const int i16 = g.indices16({0, 1, 2, 0, 2, 3});
  const int i32 = g.indices32(idx);
  std::vector<glm::vec3> soup;
  for (uint32_t i : idx) soup.push_back(quad[i] + glm::vec3(0, 1, 0));
  const int soup_pos = g.positions(soup);
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", i8}},
                                       {{"attributes", {{"POSITION", pos}}}, {"indices", i16}},
                                       {{"attributes", {{"POSITION", pos}}}, {"indices", i32}},
                                       {{"attributes", {{"POSITION", soup_pos}}}}}));
  g.scene({g.node({{"mesh", mesh}})});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "idx"));
  ASSERT_EQ(s.triangle_count(), 8u);
  for (size_t t = 0; t < 2; ++t) {
    for (int k = 0; k < 3; ++k) {
      expect_near(corner(s, 2 + t, k), corner(s, t, k));
      expect_near(corner(s, 4 + t, k), corner(s, t, k));
      expect_near(corner(s, 6 + t, k), corner(s, t, k) + glm::vec3(0, 1, 0));
    }
  }
  expect_near(face_normal(s, 0), {0, 1, 0});
  EXPECT_TRUE(s.uvs.empty());
}

TEST_F(SceneLoad, QuantizedPositions) {
  Gltf g;
  // Normalized shorts: 32767 -> 1, -32767 -> -1 (KHR_mesh_quantization).
  // 6-byte elements need a 4-byte aligned stride: byteStride 8.
  std::vector<int16_t> strided = {0, 0, 0, 0, 0, 0, 32767, 0, 32767, 0, -32768, 0};
  const int view = g.view(strided, 8);
  const int acc = g.accessor(view, kShort, 3, "VEC3", true);
  // Unsigned bytes, not normalized, with a node scale (typical quantized export).
  const std::vector<uint8_t> bytes = {0, 0, 0, 0, 0, 0, 200, 0, 200, 0, 0, 0};
  const int view_b = g.view(bytes, 4);
  const int acc_b = g.accessor(view_b, kUByte, 3, "VEC3");
  const int mesh = g.mesh(json::array(
      {{{"attributes", {{"POSITION", acc}}}}, {{"attributes", {{"POSITION", acc_b}}}}}));
  const int a = g.node({{"mesh", mesh}, {"scale", {0.5, 0.5, 0.5}}});
  g.scene({a});
  g.doc["extensionsUsed"] = {"KHR_mesh_quantization"};
  g.doc["extensionsRequired"] = {"KHR_mesh_quantization"};
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "quant"));
  ASSERT_EQ(s.triangle_count(), 2u);
  expect_near(corner(s, 0, 1), {0, 0, 0.5f});
  expect_near(corner(s, 0, 2), {0.5f, 0, -0.5f});  // -32768 clamps to -1
  expect_near(corner(s, 1, 1), {0, 0, 100});
  expect_near(corner(s, 1, 2), {100, 0, 0});
  expect_near(face_normal(s, 0), {0, 1, 0});
  EXPECT_TRUE(s.warnings.empty());
}

TEST_F(SceneLoad, SparseAccessors) {
  Gltf g;
  const int base = g.view(std::vector<glm::vec3>{{0, 0, 0}, {0, 0, 1}, {9, 9, 9}});
  const int sparse_idx = g.view(std::vector<uint16_t>{2, 0});
  const int sparse_val = g.view(std::vector<glm::vec3>{{1, 0, 0}});
  json a = {{"bufferView", base},
            {"componentType", kFloat},
            {"count", 3},
            {"type", "VEC3"},
            {"sparse",
             {{"count", 1},
              {"indices", {{"bufferView", sparse_idx}, {"componentType", kUShort}}},
              {"values", {{"bufferView", sparse_val}}}}}};
  const int acc = g.accessor(a);
  // Sparse on top of zeros (no bufferView): only vertex 1 and 2 are set.
  const int idx2 = g.view(std::vector<uint8_t>{1, 2, 0, 0});
  const int val2 = g.view(std::vector<glm::vec3>{{0, 5, 1}, {1, 5, 0}});
  json b = {{"componentType", kFloat},
            {"count", 3},
            {"type", "VEC3"},
            {"sparse",
             {{"count", 2},
              {"indices", {{"bufferView", idx2}, {"componentType", kUByte}}},
              {"values", {{"bufferView", val2}}}}}};
  const int acc2 = g.accessor(b);
  const int mesh = g.mesh(
      json::array({{{"attributes", {{"POSITION", acc}}}}, {{"attributes", {{"POSITION", acc2}}}}}));
  g.scene({g.node({{"mesh", mesh}})});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "sparse"));
  ASSERT_EQ(s.triangle_count(), 2u);
  expect_near(corner(s, 0, 2), {1, 0, 0});
  expect_near(corner(s, 1, 0), {0, 0, 0});
  expect_near(corner(s, 1, 1), {0, 5, 1});
  expect_near(corner(s, 1, 2), {1, 5, 0});
}

TEST_F(SceneLoad, InterleavedByteStride) {
  // position (12) + normal (12) + uv (8) = 32 bytes per vertex
  struct Vertex {
    float p[3], n[3], uv[2];
  };
  const std::vector<Vertex> vertices = {{{0, 0, 0}, {0, 1, 0}, {0, 0}},
                                        {{0, 0, 1}, {0, 1, 0}, {0, 1}},
                                        {{1, 0, 0}, {0, 1, 0}, {1, 0}}};
  Gltf g;
  const int view = g.view(vertices, sizeof(Vertex));
  const int p = g.accessor(view, kFloat, 3, "VEC3");
  const int n = g.accessor(view, kFloat, 3, "VEC3", false, 12);
  const int uv = g.accessor(view, kFloat, 3, "VEC2", false, 24);
  const int mesh =
      g.mesh(json::array({{{"attributes", {{"POSITION", p}, {"NORMAL", n}, {"TEXCOORD_0", uv}}}}}));
  g.scene({g.node({{"mesh", mesh}, {"translation", {0, 2, 0}}})});
  const snow::Scene s = snow::load_scene(g.write_gltf(dir_, "stride"));
  ASSERT_EQ(s.triangle_count(), 1u);
  expect_near(corner(s, 0, 1), {0, 2, 1});
  expect_near(corner(s, 0, 2), {1, 2, 0});
  expect_near(s.normals[1], {0, 1, 0});
  ASSERT_EQ(s.uvs.size(), 3u);
  EXPECT_FLOAT_EQ(s.uvs[1].y, 1.0f);
  EXPECT_FLOAT_EQ(s.uvs[2].x, 1.0f);
}

TEST_F(SceneLoad, GltfBinGlbAndDataUriGiveTheSameScene) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}, {"translation", {1, 2, 3}}})});
  const snow::Scene a = snow::load_scene(g.write_gltf(dir_, "a"));
  const snow::Scene b = snow::load_scene(g.write_glb(dir_, "b"));
  const snow::Scene c = snow::load_scene(g.write_data_uri(dir_, "c"));
  ASSERT_EQ(a.triangle_count(), 1u);
  ASSERT_EQ(b.positions, a.positions);
  ASSERT_EQ(c.positions, a.positions);
  EXPECT_EQ(b.normals, a.normals);
  expect_near(corner(a, 0, 0), {1, 2, 3});
  // The format is detected by content: a GLB named .gltf still loads.
  fs::copy_file(dir_ / "b.glb", dir_ / "b_as.gltf");
  EXPECT_EQ(snow::load_scene(dir_ / "b_as.gltf").positions, a.positions);
}

TEST_F(SceneLoad, PointsAndLinesAreSkippedWithAWarning) {
  Gltf g;
  const int pos = g.positions(kUpTriangle);
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}},
                                       {{"attributes", {{"POSITION", pos}}}, {"mode", 1}},
                                       {{"attributes", {{"POSITION", pos}}}, {"mode", 3}},
                                       {{"attributes", {{"POSITION", pos}}}, {"mode", 0}}}),
                          "Lamp");
  g.scene({g.node({{"mesh", mesh}})});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "lamp"));
  EXPECT_EQ(s.triangle_count(), 1u);
  EXPECT_EQ(s.stats.primitives_skipped, 3u);
  ASSERT_EQ(s.warnings.size(), 3u);
  EXPECT_EQ(s.warnings[0], "ignoring primitive 1 of mesh 'Lamp' (LINES)");
  EXPECT_EQ(s.warnings[1], "ignoring primitive 2 of mesh 'Lamp' (LINE_STRIP)");
  EXPECT_EQ(s.warnings[2], "ignoring primitive 3 of mesh 'Lamp' (POINTS)");
}

TEST_F(SceneLoad, DegenerateTrianglesAreDroppedAndCounted) {
  Gltf g;
  const int pos = g.positions({{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}});
  // good, repeated index, collinear (zero area), good again
  const int idx = g.indices16({0, 1, 2, 0, 0, 1, 2, 3, 4, 0, 1, 2});
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}));
  // A second node squashed flat by a zero scale: every triangle degenerate.
  const int squashed = g.node({{"mesh", mesh}, {"scale", {1, 1, 0}}});
  g.scene({g.node({{"mesh", mesh}}), squashed});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "degenerate"));
  EXPECT_EQ(s.stats.triangles_read, 8u);
  EXPECT_EQ(s.stats.degenerate_dropped, 2u + 4u);
  EXPECT_EQ(s.triangle_count(), 2u);
  ASSERT_EQ(s.objects.size(), 1u);  // the all-degenerate instance yields no object
  EXPECT_EQ(s.objects[0].triangle_count, 2u);
}

// --- materials, images, uvs -----------------------------------------------------------

/// 2x1 24-bit BMP: left pixel red, right pixel blue.
std::vector<uint8_t> tiny_bmp() {
  std::vector<uint8_t> b = {'B', 'M'};
  auto u32 = [&b](uint32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(uint8_t(v >> (8 * i)));
  };
  auto u16 = [&b](uint16_t v) {
    b.push_back(uint8_t(v));
    b.push_back(uint8_t(v >> 8));
  };
  u32(14 + 40 + 8);
  u32(0);
  u32(14 + 40);
  u32(40);
  u32(2);
  u32(1);
  u16(1);
  u16(24);
  u32(0);
  u32(8);
  u32(2835);
  u32(2835);
  u32(0);
  u32(0);
  const uint8_t row[8] = {0, 0, 255, 255, 0, 0, 0, 0};  // BGR red, BGR blue, pad
  b.insert(b.end(), row, row + 8);
  return b;
}

TEST_F(SceneLoad, MaterialsImagesAndTextureTransform) {
  Gltf g;
  const int pos = g.positions(kUpTriangle);
  const int uv0 = g.vec2s({{0, 0}, {0, 1}, {1, 0}});
  const int uv1 = g.vec2s({{0.5f, 0.5f}, {0.5f, 0.5f}, {0.5f, 0.5f}});
  const int mesh = g.mesh(
      json::array({{{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv0}, {"TEXCOORD_1", uv1}}},
                    {"material", 0}},
                   {{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv0}}}, {"material", 1}},
                   {{"attributes", {{"POSITION", pos}}}, {"material", 2}},
                   {{"attributes", {{"POSITION", pos}}}}}));
  g.doc["images"] = json::array({{{"uri", "data:image/bmp;base64," + base64(tiny_bmp())}},
                                 {{"uri", "textures/missing.png"}}});
  g.doc["textures"] = json::array({{{"source", 0}}, {{"source", 1}}});
  g.doc["materials"] = json::array(
      {{{"name", "Brick"},
        {"pbrMetallicRoughness",
         {{"baseColorFactor", {0.5, 0.25, 1, 1}},
          {"baseColorTexture",
           {{"index", 0},
            {"extensions",
             {{"KHR_texture_transform", {{"offset", {0.5, 0}}, {"scale", {2, 2}}}}}}}}}}},
       {{"name", "Missing"}, {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 1}}}}}},
       {{"name", "Plain"}}});
  g.doc["extensionsUsed"] = {"KHR_texture_transform"};
  g.scene({g.node({{"mesh", mesh}})});
  fs::create_directories(dir_ / "textures");
  const snow::Scene s = snow::load_scene(g.write_gltf(dir_, "mat"));
  ASSERT_EQ(s.triangle_count(), 4u);
  ASSERT_EQ(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[0].name, "Brick");
  EXPECT_FLOAT_EQ(s.materials[0].base_color.g, 0.25f);
  EXPECT_FLOAT_EQ(s.materials[2].base_color.r, 1.0f);
  ASSERT_EQ(s.images.size(), 1u);
  ASSERT_EQ(s.materials[0].base_color_image, 0);
  EXPECT_EQ(s.materials[1].base_color_image, -1);  // missing file: warning only
  const snow::Image& image = s.images[0];
  ASSERT_EQ(image.width, 2);
  ASSERT_EQ(image.height, 1);
  ASSERT_EQ(image.rgba.size(), 8u);
  EXPECT_EQ(image.rgba[0], 255);  // red
  EXPECT_EQ(image.rgba[2], 0);
  EXPECT_EQ(image.rgba[6], 255);  // blue
  EXPECT_EQ(image.rgba[7], 255);  // opaque
  // uvs: transform (scale 2, offset 0.5) applied to TEXCOORD_0
  ASSERT_EQ(s.uvs.size(), 12u);
  EXPECT_FLOAT_EQ(s.uvs[1].x, 0.5f);
  EXPECT_FLOAT_EQ(s.uvs[1].y, 2.0f);
  EXPECT_FLOAT_EQ(s.uvs[2].x, 2.5f);
  EXPECT_FLOAT_EQ(s.uvs[4].y, 1.0f);  // material 1: no transform
  EXPECT_FLOAT_EQ(s.uvs[7].x, 0.0f);  // no TEXCOORD_0: zeros
  EXPECT_EQ(s.objects[3].material, -1);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("missing.png"), std::string::npos);

  snow::LoadSettings no_images;
  no_images.load_images = false;
  const snow::Scene t = snow::load_scene(dir_ / "mat.gltf", no_images);
  EXPECT_TRUE(t.images.empty());
  EXPECT_EQ(t.materials[0].base_color_image, -1);
  EXPECT_TRUE(t.warnings.empty());

  // Without shading (the batch job without a preview): the same triangles,
  // objects and materials, no normals and no UVs.
  no_images.shading = false;
  const snow::Scene u = snow::load_scene(dir_ / "mat.gltf", no_images);
  EXPECT_EQ(u.positions, s.positions);
  EXPECT_EQ(u.objects.size(), s.objects.size());
  EXPECT_EQ(u.materials.size(), s.materials.size());
  EXPECT_TRUE(u.normals.empty());
  EXPECT_TRUE(u.uvs.empty());
}

TEST_F(SceneLoad, UnknownOptionalExtensionWarns) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  g.doc["extensionsUsed"] = {"VENDOR_sparkles", "KHR_materials_sheen"};
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "ext"));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("VENDOR_sparkles"), std::string::npos);
}

TEST_F(SceneLoad, Draco) {
#ifdef SNOW_TEST_DRACO_ENCODER
  Gltf g = draco_quad_gltf(false);
  const fs::path path = g.write_glb(dir_, "draco");
  if (!snow::gltf_draco_supported()) {
    expect_input_error(path, "KHR_draco_mesh_compression");
    return;
  }
  const snow::Scene s = snow::load_scene(path);
  ASSERT_EQ(s.triangle_count(), 2u);
  EXPECT_NEAR(total_area(s), 1.0, 1e-5);
  for (size_t t = 0; t < 2; ++t) expect_near(face_normal(s, t), {0, 1, 0});
  expect_near(s.bounds.min, {0, 1, 0});
  expect_near(s.bounds.max, {1, 1, 1});
  // Corrupt Draco data is an InputError, not a crash.
  g.bin.assign(g.bin.size(), 0x5A);
  expect_input_error(g.write_glb(dir_, "draco_bad"), "Draco");
#else
  GTEST_SKIP() << "Draco encoder headers not available";
#endif
}

// The usual Draco file: the primitive's indices accessor has no bufferView
// (KHR_draco_mesh_compression: Draco provides the indices). It loads, as
// GLB, .gltf with a .bin and .gltf with a data URI.
TEST_F(SceneLoad, DracoWithIndices) {
#ifdef SNOW_TEST_DRACO_ENCODER
  if (!snow::gltf_draco_supported()) GTEST_SKIP() << "this build has no Draco decoder";
  Gltf g = draco_quad_gltf(true);
  for (const fs::path& path :
       {g.write_glb(dir_, "draco_indexed"), g.write_gltf(dir_, "draco_indexed"),
        g.write_data_uri(dir_, "draco_indexed_data")}) {
    const snow::Scene s = snow::load_scene(path);
    ASSERT_EQ(s.triangle_count(), 2u) << path;
    EXPECT_NEAR(total_area(s), 1.0, 1e-5) << path;
    expect_near(s.bounds.min, {0, 1, 0});
    expect_near(s.bounds.max, {1, 1, 1});
  }
#else
  GTEST_SKIP() << "Draco encoder headers not available";
#endif
}
// --- summaries -------------------------------------------------------------------------------

TEST_F(SceneLoad, Summaries) {
  Gltf g;
  const int pos = g.positions(kUpTriangle);
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"material", 0}},
                                       {{"attributes", {{"POSITION", pos}}}, {"mode", 0}}}),
                          "Roof");
  g.doc["materials"] = json::array({{{"name", "Tiles"}}});
  const int roof = g.node({{"name", "Roof"}, {"mesh", mesh}});
  g.scene({g.node({{"name", "House"}, {"children", {roof}}})});
  const snow::Scene s = snow::load_scene(g.write_glb(dir_, "summary"));
  const json j = json::parse(snow::scene_summary_json(s));
  EXPECT_EQ(j["triangles"], 1);
  EXPECT_EQ(j["stats"]["triangles_read"], 1);
  EXPECT_EQ(j["stats"]["primitives_skipped"], 1);
  EXPECT_EQ(j["objects"][0]["node_path"], "/House/Roof");
  EXPECT_EQ(j["objects"][0]["material"], 0);
  EXPECT_EQ(j["objects"][0]["triangles"], 1);
  EXPECT_EQ(j["bounds"]["unit"], "m");
  EXPECT_DOUBLE_EQ(j["bounds"]["max"][0].get<double>(), 1.0);
  EXPECT_EQ(j["warnings"].size(), 1u);
  const std::string text = snow::scene_summary_text(s);
  EXPECT_NE(text.find("triangles: 1"), std::string::npos) << text;
  EXPECT_NE(text.find("/House/Roof"), std::string::npos) << text;
  EXPECT_NE(text.find("Tiles"), std::string::npos) << text;
  EXPECT_NE(text.find("(POINTS)"), std::string::npos) << text;
  EXPECT_NE(text.find("bounds (m"), std::string::npos) << text;
}

// --- shared real-world scenes ------------------------------------------------------------------

fs::path shared_scenes() { return fs::path(SNOW_SHARED_SCENES); }

TEST_F(SceneLoad, SharedToyCar) {
  const fs::path path = shared_scenes() / "khronos/ToyCar/ToyCar.gltf";
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found";
  const snow::Scene s = snow::load_scene(path);
  EXPECT_EQ(s.stats.triangles_read, 108936u);
  EXPECT_EQ(s.objects.size(), 3u);
  // Centimetre-scale geometry (~730 units long) under a node scale of 1e-4 and
  // a +90 degree X rotation: a toy car about 7.4 cm long, 2.9 cm tall, Y up.
  const glm::vec3 size = s.bounds.size();
  EXPECT_GT(size.x, 0.05f);
  EXPECT_LT(size.x, 0.1f);
  EXPECT_GT(size.z, 0.05f);
  EXPECT_LT(size.z, 0.1f);
  EXPECT_GT(size.y, 0.02f);
  EXPECT_LT(size.y, 0.04f);
  EXPECT_LT(size.y, size.x);  // lying on its wheels, not on its side
  EXPECT_EQ(s.positions.size(), s.normals.size());
  EXPECT_EQ(s.uvs.size(), s.positions.size());
  EXPECT_GE(s.images.size(), 1u);
}

TEST_F(SceneLoad, SharedSheenChair) {
  const fs::path path = shared_scenes() / "khronos/SheenChair/SheenChair.gltf";
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found";
  snow::LoadSettings settings;
  settings.load_images = false;
  const snow::Scene s = snow::load_scene(path, settings);
  EXPECT_EQ(s.stats.triangles_read, 39936u);
  // An armchair: roughly 0.8 m wide, 0.7 m tall, standing on y = 0.
  EXPECT_NEAR(s.bounds.size().y, 0.69, 0.05);
  EXPECT_NEAR(s.bounds.min.y, 0.0, 0.01);
}

TEST_F(SceneLoad, SharedKenneyCity) {
  const fs::path folder = shared_scenes() / "kenney-city";
  if (!fs::exists(folder)) GTEST_SKIP() << folder << " not found";
  int files = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.path().extension() != ".glb") continue;
    const snow::Scene s = snow::load_scene(entry.path());
    EXPECT_GT(s.triangle_count(), 0u) << entry.path();
    EXPECT_NEAR(s.bounds.size().x, 1.0f, 0.1f) << entry.path();  // one tile = 1 m (trees overhang)
    EXPECT_EQ(s.images.size(), 1u) << entry.path();              // Textures/colormap.png
    ++files;
  }
  EXPECT_EQ(files, 15);
}

}  // namespace
}  // namespace snow::test
