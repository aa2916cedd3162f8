// Tests of the glTF loader (scene/load_gltf.h). Every scene is built here in
// code (JSON + binary buffer), written to a temporary folder and loaded.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#if __has_include(<draco/compression/encode.h>)
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#define SNOW_TEST_DRACO_ENCODER 1
#endif

#include "core/error.h"
#include "core/log.h"
#include "scene/load_gltf.h"
#include "support/base64.h"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr int kUByte = 5121;
constexpr int kShort = 5122;
constexpr int kUShort = 5123;
constexpr int kUInt = 5125;
constexpr int kFloat = 5126;

fs::path temp_dir(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("snow_test_scene_load_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

using snow::test::base64;

void write_bytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

/// Builds a glTF document and its single binary buffer in memory.
struct Gltf {
  json doc;
  std::vector<uint8_t> bin;

  Gltf() {
    doc["asset"] = {{"version", "2.0"}};
    for (const char* key : {"buffers", "bufferViews", "accessors", "meshes", "nodes", "scenes"})
      doc[key] = json::array();
  }

  /// Appends raw bytes (4-byte aligned) as a bufferView; returns its index.
  int view(const void* data, size_t size, int stride = 0) {
    while (bin.size() % 4) bin.push_back(0);
    const size_t offset = bin.size();
    bin.insert(bin.end(), static_cast<const uint8_t*>(data),
               static_cast<const uint8_t*>(data) + size);
    json v = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", size}};
    if (stride) v["byteStride"] = stride;
    doc["bufferViews"].push_back(v);
    return int(doc["bufferViews"].size() - 1);
  }
  template <typename T>
  int view(const std::vector<T>& values, int stride = 0) {
    return view(values.data(), values.size() * sizeof(T), stride);
  }

  int accessor(json a) {
    doc["accessors"].push_back(std::move(a));
    return int(doc["accessors"].size() - 1);
  }
  int accessor(int view_index, int component_type, size_t count, const char* type,
               bool normalized = false, size_t byte_offset = 0) {
    json a = {{"componentType", component_type}, {"count", count}, {"type", type}};
    if (view_index >= 0) a["bufferView"] = view_index;
    if (normalized) a["normalized"] = true;
    if (byte_offset) a["byteOffset"] = byte_offset;
    return accessor(a);
  }

  int positions(const std::vector<glm::vec3>& p) {
    return accessor(view(p), kFloat, p.size(), "VEC3");
  }
  int vec3s(const std::vector<glm::vec3>& p) { return positions(p); }
  int vec2s(const std::vector<glm::vec2>& p) { return accessor(view(p), kFloat, p.size(), "VEC2"); }
  int indices32(const std::vector<uint32_t>& i) {
    return accessor(view(i), kUInt, i.size(), "SCALAR");
  }
  int indices16(const std::vector<uint16_t>& i) {
    return accessor(view(i), kUShort, i.size(), "SCALAR");
  }
  int indices8(const std::vector<uint8_t>& i) {
    return accessor(view(i), kUByte, i.size(), "SCALAR");
  }

  int mesh(json primitives, const std::string& name = "") {
    json m = {{"primitives", std::move(primitives)}};
    if (!name.empty()) m["name"] = name;
    doc["meshes"].push_back(m);
    return int(doc["meshes"].size() - 1);
  }
  int node(json n) {
    doc["nodes"].push_back(std::move(n));
    return int(doc["nodes"].size() - 1);
  }
  void scene(const std::vector<int>& roots) {
    doc["scenes"] = json::array({{{"nodes", roots}}});
    doc["scene"] = 0;
  }

  /// .gltf + external .bin
  fs::path write_gltf(const fs::path& dir, const std::string& name) {
    json d = doc;
    d["buffers"] = json::array({{{"byteLength", bin.size()}, {"uri", name + ".bin"}}});
    write_bytes(dir / (name + ".bin"), bin);
    write_text(dir / (name + ".gltf"), d.dump());
    return dir / (name + ".gltf");
  }
  /// .gltf with the buffer as a data URI
  fs::path write_data_uri(const fs::path& dir, const std::string& name) {
    json d = doc;
    d["buffers"] = json::array({{{"byteLength", bin.size()},
                                 {"uri", "data:application/octet-stream;base64," + base64(bin)}}});
    write_text(dir / (name + ".gltf"), d.dump());
    return dir / (name + ".gltf");
  }
  std::vector<uint8_t> glb_bytes() const {
    json d = doc;
    d["buffers"] = json::array({{{"byteLength", bin.size()}}});
    std::string text = d.dump();
    while (text.size() % 4) text += ' ';
    std::vector<uint8_t> body = bin;
    while (body.size() % 4) body.push_back(0);
    std::vector<uint8_t> out;
    auto u32 = [&out](uint32_t v) {
      for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
    };
    u32(0x46546C67);
    u32(2);
    u32(uint32_t(12 + 8 + text.size() + 8 + body.size()));
    u32(uint32_t(text.size()));
    u32(0x4E4F534A);
    out.insert(out.end(), text.begin(), text.end());
    u32(uint32_t(body.size()));
    u32(0x004E4942);
    out.insert(out.end(), body.begin(), body.end());
    return out;
  }
  fs::path write_glb(const fs::path& dir, const std::string& name) {
    write_bytes(dir / (name + ".glb"), glb_bytes());
    return dir / (name + ".glb");
  }
};

/// A right triangle in the XZ plane facing +Y (counter-clockwise from above).
const std::vector<glm::vec3> kUpTriangle = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}};

/// Gltf with one mesh (one TRIANGLES primitive: kUpTriangle, with normals).
Gltf triangle_gltf(int* mesh_out = nullptr, bool normals = true) {
  Gltf g;
  json attributes = {{"POSITION", g.positions(kUpTriangle)}};
  if (normals) attributes["NORMAL"] = g.vec3s({{0, 1, 0}, {0, 1, 0}, {0, 1, 0}});
  const int mesh = g.mesh(json::array({{{"attributes", attributes}}}), "Tri");
  if (mesh_out) *mesh_out = mesh;
  return g;
}

glm::vec3 corner(const snow::Scene& s, size_t triangle, int k) {
  return s.positions[3 * triangle + size_t(k)];
}

glm::vec3 face_normal(const snow::Scene& s, size_t t) {
  return glm::normalize(
      glm::cross(corner(s, t, 1) - corner(s, t, 0), corner(s, t, 2) - corner(s, t, 0)));
}

void expect_near(const glm::vec3& a, const glm::vec3& b, float tolerance = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

double total_area(const snow::Scene& s) {
  double area = 0;
  for (size_t t = 0; t < s.triangle_count(); ++t)
    area += 0.5 * glm::length(glm::cross(corner(s, t, 1) - corner(s, t, 0),
                                         corner(s, t, 2) - corner(s, t, 0)));
  return area;
}

/// Expects load_scene to throw InputError whose message contains `needle`.
void expect_input_error(const fs::path& path, const std::string& needle,
                        snow::LoadSettings settings = {}) {
  try {
    snow::load_scene(path, settings);
    ADD_FAILURE() << "no InputError for " << path << " (expected '" << needle << "')";
  } catch (const snow::InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(needle), std::string::npos) << "message: " << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << "message is not one line: " << message;
    EXPECT_NE(message.find(path.filename().string()), std::string::npos) << "message: " << message;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type for " << path << ": " << e.what();
  }
}

class SceneLoad : public ::testing::Test {
 protected:
  void SetUp() override {
    snow::set_log_level(snow::LogLevel::Quiet);
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override {
    snow::set_log_level(snow::LogLevel::Info);
    fs::remove_all(dir_);
  }
  fs::path dir_;
};

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
  // Two triangles of a unit quad facing +Y, encoded with Draco.
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(2);
  const int pos_att =
      builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const float q[4][3] = {{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}};
  builder.SetAttributeValuesForFace(pos_att, draco::FaceIndex(0), q[0], q[1], q[2]);
  builder.SetAttributeValuesForFace(pos_att, draco::FaceIndex(1), q[0], q[2], q[3]);
  std::unique_ptr<draco::Mesh> draco_mesh = builder.Finalize();
  ASSERT_TRUE(draco_mesh);
  const int unique_id =
      int(draco_mesh->attribute(draco_mesh->GetNamedAttributeId(draco::GeometryAttribute::POSITION))
              ->unique_id());
  draco::Encoder encoder;
  encoder.SetSpeedOptions(5, 5);
  draco::EncoderBuffer encoded;
  ASSERT_TRUE(encoder.EncodeMeshToBuffer(*draco_mesh, &encoded).ok());
  Gltf g;
  const int view = g.view(encoded.data(), encoded.size());
  const int pos = g.accessor(-1, kFloat, 4, "VEC3");
  const int mesh = g.mesh(
      json::array({{{"attributes", {{"POSITION", pos}}},
                    {"extensions",
                     {{"KHR_draco_mesh_compression",
                       {{"bufferView", view}, {"attributes", {{"POSITION", unique_id}}}}}}}}}));
  g.scene({g.node({{"mesh", mesh}, {"translation", {0, 1, 0}}})});
  g.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  g.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
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

// --- bad input ----------------------------------------------------------------------------

TEST_F(SceneLoad, BadContainerAndJson) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  std::vector<uint8_t> glb = g.glb_bytes();

  std::vector<uint8_t> truncated(glb.begin(), glb.begin() + long(glb.size() / 2));
  write_bytes(dir_ / "truncated.glb", truncated);
  expect_input_error(dir_ / "truncated.glb", "truncated GLB");
  write_bytes(dir_ / "tiny.glb", {'g', 'l', 'T', 'F', 2, 0});
  expect_input_error(dir_ / "tiny.glb", "truncated GLB");

  std::vector<uint8_t> magic = glb;
  magic[3] = 'X';
  write_bytes(dir_ / "magic.glb", magic);
  expect_input_error(dir_ / "magic.glb", "magic");

  std::vector<uint8_t> chunk = glb;
  chunk[12] = 0xFF;  // JSON chunk length far beyond the file
  chunk[13] = 0xFF;
  write_bytes(dir_ / "chunk.glb", chunk);
  expect_input_error(dir_ / "chunk.glb", "chunk 0");

  write_text(dir_ / "broken.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [");
  expect_input_error(dir_ / "broken.gltf", "broken JSON");
  write_text(dir_ / "array.gltf", "[1, 2]");
  expect_input_error(dir_ / "array.gltf", "broken JSON");
  write_text(dir_ / "overflow.gltf",
             "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [{\"scale\": [1e999, 1, 1]}]}");
  expect_input_error(dir_ / "overflow.gltf", "broken JSON");
  write_text(dir_ / "v1.gltf", "{\"asset\": {\"version\": \"1.0\"}}");
  expect_input_error(dir_ / "v1.gltf", "version");

  // The scene file itself missing is an IOError.
  EXPECT_THROW(snow::load_scene(dir_ / "nonexistent.glb"), snow::IOError);
}

TEST_F(SceneLoad, BadBuffers) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  // Missing .bin
  const fs::path missing = g.write_gltf(dir_, "missing");
  fs::remove(dir_ / "missing.bin");
  expect_input_error(missing, "buffer 0");
  expect_input_error(missing, "does not exist");
  // .bin shorter than byteLength
  const fs::path short_bin = g.write_gltf(dir_, "short");
  write_bytes(dir_ / "short.bin", std::vector<uint8_t>(10, 0));
  expect_input_error(short_bin, "byteLength");
  // bad base64
  json d = g.doc;
  d["buffers"] = json::array(
      {{{"byteLength", g.bin.size()}, {"uri", "data:application/octet-stream;base64,@@@@"}}});
  write_text(dir_ / "b64.gltf", d.dump());
  expect_input_error(dir_ / "b64.gltf", "base64");
  // bufferView out of range of its buffer
  Gltf v = g;
  v.doc["bufferViews"][0]["byteLength"] = 4000;
  expect_input_error(v.write_glb(dir_, "view"), "bufferView 0");
  // bufferView referring to a missing buffer
  Gltf w = g;
  w.doc["bufferViews"][0]["buffer"] = 3;
  expect_input_error(w.write_glb(dir_, "viewbuf"), "out of range");
}

TEST_F(SceneLoad, UrisOutsideTheSceneFolderAreRefused) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  fs::create_directories(dir_ / "sub");
  write_bytes(dir_ / "outside.bin", g.bin);
  for (const std::string& uri : std::vector<std::string>{
           "../outside.bin", "a/../../outside.bin", (dir_ / "outside.bin").string(),
           std::string("%2E%2E/outside.bin"), std::string("file:///etc/passwd"),
           std::string("..\\outside.bin")}) {
    json d = g.doc;
    d["buffers"] = json::array({{{"byteLength", g.bin.size()}, {"uri", uri}}});
    write_text(dir_ / "sub" / "escape.gltf", d.dump());
    expect_input_error(dir_ / "sub" / "escape.gltf", "refused");
  }
  // Images too.
  Gltf i = g;
  i.doc["images"] = json::array({{{"uri", "../../secret.png"}}});
  i.doc["textures"] = json::array({{{"source", 0}}});
  i.doc["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
  i.doc["meshes"][0]["primitives"][0]["material"] = 0;
  expect_input_error(i.write_gltf(dir_, "image_escape"), "refused");
  // A subfolder is fine.
  json d = g.doc;
  write_bytes(dir_ / "sub" / "data.bin", g.bin);
  d["buffers"] = json::array({{{"byteLength", g.bin.size()}, {"uri", "sub/data.bin"}}});
  write_text(dir_ / "inside.gltf", d.dump());
  EXPECT_EQ(snow::load_scene(dir_ / "inside.gltf").triangle_count(), 1u);
}

TEST_F(SceneLoad, BadAccessorsAndIndices) {
  Gltf g;
  const int pos = g.positions(kUpTriangle);
  const int idx = g.indices16({0, 1, 2, 0, 1, 7});
  const int mesh =
      g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}}), "Bad");
  g.scene({g.node({{"mesh", mesh}})});
  expect_input_error(g.write_glb(dir_, "index"), "index 7");

  Gltf a = g;
  a.doc["meshes"][0]["primitives"][0].erase("indices");
  a.doc["accessors"][size_t(pos)]["byteOffset"] = 8;  // runs past the view's end
  expect_input_error(a.write_glb(dir_, "range"), "accessor 0");

  // Absurd count over a tiny buffer: fails fast, before allocating.
  Gltf c = g;
  c.doc["meshes"][0]["primitives"][0].erase("indices");
  c.doc["accessors"][size_t(pos)]["count"] = 1000000000;
  const auto start = std::chrono::steady_clock::now();
  expect_input_error(c.write_glb(dir_, "count"), "accessor 0");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 30.0);
  // Absurd count without any bufferView: the limit refuses it.
  Gltf z = c;
  z.doc["accessors"][size_t(pos)].erase("bufferView");
  expect_input_error(z.write_glb(dir_, "zeros"), "limit");
  // Count over 2^32
  Gltf h = c;
  h.doc["accessors"][size_t(pos)]["count"] = 10000000000000ull;
  expect_input_error(h.write_glb(dir_, "huge"), "accessor 0");

  Gltf r = g;
  r.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 99;
  expect_input_error(r.write_glb(dir_, "acc_index"), "out of range");

  Gltf t = g;
  t.doc["accessors"][size_t(pos)]["type"] = "VEC2";
  expect_input_error(t.write_glb(dir_, "type"), "VEC3");

  Gltf n = g;
  n.doc["accessors"][size_t(pos)]["count"] = -3;
  expect_input_error(n.write_glb(dir_, "negative"), "non-negative integer");

  Gltf s = g;
  s.doc["bufferViews"][0]["byteStride"] = 4;  // smaller than a VEC3 of floats
  expect_input_error(s.write_glb(dir_, "stride"), "byteStride");

  Gltf m = g;
  m.doc["meshes"][0]["primitives"][0]["material"] = 5;
  expect_input_error(m.write_glb(dir_, "material"), "material");

  // Sparse index out of range.
  Gltf sp = g;
  const int si = sp.view(std::vector<uint32_t>{9});
  const int sv = sp.view(std::vector<glm::vec3>{{1, 1, 1}});
  sp.doc["accessors"][size_t(pos)]["sparse"] = {
      {"count", 1},
      {"indices", {{"bufferView", si}, {"componentType", kUInt}}},
      {"values", {{"bufferView", sv}}}};
  expect_input_error(sp.write_glb(dir_, "sparse"), "sparse index 9");
}

TEST_F(SceneLoad, NonFiniteValues) {
  Gltf g;
  const int pos = g.positions({{0, 0, 0}, {0, 0, 1}, {std::nanf(""), 0, 0}});
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}));
  g.scene({g.node({{"mesh", mesh}})});
  expect_input_error(g.write_glb(dir_, "nan"), "not finite");

  Gltf inf = triangle_gltf();
  const int child = inf.node({{"mesh", 0}, {"scale", {1e200, 1, 1}}});
  inf.scene({inf.node({{"scale", {1e200, 1, 1}}, {"children", {child}}})});
  expect_input_error(inf.write_glb(dir_, "inf"), "not finite");

  // A world transform fine in double but overflowing float coordinates.
  Gltf big = triangle_gltf();
  big.scene({big.node({{"mesh", 0}, {"scale", {1e39, 1, 1}}})});
  expect_input_error(big.write_glb(dir_, "big"), "not finite");

  Gltf q = triangle_gltf();
  q.scene({q.node({{"mesh", 0}, {"rotation", {0, 0, 0, 0}}})});
  expect_input_error(q.write_glb(dir_, "quat"), "rotation");

  Gltf mat = triangle_gltf();
  mat.scene({mat.node({{"mesh", 0}, {"matrix", {1, 0, 0}}})});
  expect_input_error(mat.write_glb(dir_, "matrix"), "matrix");
}

TEST_F(SceneLoad, BadHierarchies) {
  Gltf cycle = triangle_gltf();
  cycle.node({{"mesh", 0}, {"children", {1}}});
  cycle.node({{"children", {2}}});
  cycle.node({{"children", {1}}});
  cycle.scene({0});
  expect_input_error(cycle.write_glb(dir_, "cycle"), "node");

  Gltf loop = triangle_gltf();
  loop.node({{"mesh", 0}, {"children", {1}}});
  loop.node({{"children", {0}}});
  loop.scene({0});
  expect_input_error(loop.write_glb(dir_, "loop"), "cycle");

  Gltf self = triangle_gltf();
  self.node({{"mesh", 0}, {"children", {0}}});
  self.scene({0});
  expect_input_error(self.write_glb(dir_, "self"), "cycle");

  Gltf shared = triangle_gltf();
  shared.node({{"mesh", 0}});
  shared.node({{"children", {0}}});
  shared.node({{"children", {0}}});
  shared.scene({1, 2});
  expect_input_error(shared.write_glb(dir_, "shared"), "more than one");

  Gltf twice = triangle_gltf();
  twice.node({{"mesh", 0}});
  twice.scene({0, 0});
  expect_input_error(twice.write_glb(dir_, "twice"), "twice");

  Gltf child = triangle_gltf();
  child.node({{"mesh", 0}, {"children", {42}}});
  child.scene({0});
  expect_input_error(child.write_glb(dir_, "child"), "child 42");

  // A huge cycle without a root must not hang either.
  Gltf ring = triangle_gltf();
  for (int i = 0; i < 100000; ++i) ring.node({{"children", {(i + 1) % 100000}}});
  ring.scene({0});
  expect_input_error(ring.write_glb(dir_, "ring"), "cycle");
}

TEST_F(SceneLoad, EmptyScenesAreErrors) {
  Gltf empty;
  empty.scene({});
  expect_input_error(empty.write_glb(dir_, "empty"), "no triangles");

  Gltf no_mesh = triangle_gltf();
  no_mesh.scene({no_mesh.node({{"name", "lonely"}})});
  expect_input_error(no_mesh.write_glb(dir_, "nomesh"), "no triangles");

  Gltf points;
  const int pos = points.positions(kUpTriangle);
  points.scene({points.node(
      {{"mesh", points.mesh(json::array({{{"attributes", {{"POSITION", pos}}}, {"mode", 0}}}))}})});
  expect_input_error(points.write_glb(dir_, "points"), "no triangles");

  Gltf flat;
  const int line = flat.positions({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}});
  flat.scene(
      {flat.node({{"mesh", flat.mesh(json::array({{{"attributes", {{"POSITION", line}}}}}))}})});
  expect_input_error(flat.write_glb(dir_, "flat"), "degenerate");
}

TEST_F(SceneLoad, Extensions) {
  Gltf meshopt = triangle_gltf();
  meshopt.scene({meshopt.node({{"mesh", 0}})});
  meshopt.doc["extensionsUsed"] = {"EXT_meshopt_compression"};
  meshopt.doc["extensionsRequired"] = {"EXT_meshopt_compression"};
  expect_input_error(meshopt.write_glb(dir_, "meshopt"), "EXT_meshopt_compression");

  Gltf unknown = triangle_gltf();
  unknown.scene({unknown.node({{"mesh", 0}})});
  unknown.doc["extensionsUsed"] = {"VENDOR_warp_drive"};
  unknown.doc["extensionsRequired"] = {"VENDOR_warp_drive"};
  expect_input_error(unknown.write_glb(dir_, "unknown"), "VENDOR_warp_drive");
}

TEST_F(SceneLoad, TriangleLimit) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  std::vector<int> roots;
  for (int i = 0; i < 5; ++i) roots.push_back(g.node({{"mesh", mesh}}));
  g.scene(roots);
  snow::LoadSettings settings;
  settings.limits.max_triangles = 4;
  expect_input_error(g.write_glb(dir_, "limit"), "max_triangles", settings);
  settings.limits.max_triangles = 5;
  EXPECT_EQ(snow::load_scene(dir_ / "limit.glb", settings).triangle_count(), 5u);
  settings.limits.max_file_bytes = 16;
  expect_input_error(dir_ / "limit.glb", "max_file_bytes", settings);
}

TEST_F(SceneLoad, MutatedFilesNeverCrash) {
  // Flip bytes all over a valid GLB; every outcome must be a scene or an InputError.
  Gltf g;
  const int pos = g.positions({{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {1, 0, 1}});
  const int idx = g.indices16({0, 1, 2, 2, 1, 3});
  const int n = g.vec3s({{0, 1, 0}, {0, 1, 0}, {0, 1, 0}, {0, 1, 0}});
  const int mesh = g.mesh(
      json::array(
          {{{"attributes", {{"POSITION", pos}, {"NORMAL", n}}}, {"indices", idx}, {"mode", 4}}}),
      "M");
  g.scene({g.node({{"mesh", mesh}, {"translation", {1, 2, 3}}})});
  const std::vector<uint8_t> glb = g.glb_bytes();
  uint32_t seed = 12345;
  auto next = [&seed] {
    seed = seed * 1664525u + 1013904223u;
    return seed >> 8;
  };
  // Each file is loaded with and without shading (the batch job's load,
  // which reads no NORMAL).
  snow::LoadSettings geometry_only;
  geometry_only.shading = false;
  int loaded = 0, refused = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::vector<uint8_t> bytes = glb;
    const int flips = 1 + int(next() % 4);
    for (int f = 0; f < flips; ++f) bytes[next() % bytes.size()] = uint8_t(next());
    write_bytes(dir_ / "m.glb", bytes);
    for (const bool shading : {true, false}) {
      try {
        const snow::Scene s =
            snow::load_scene(dir_ / "m.glb", shading ? snow::LoadSettings{} : geometry_only);
        EXPECT_EQ(s.normals.size(), shading ? s.positions.size() : 0u);
        for (const glm::vec3& p : s.positions) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
        ++loaded;
      } catch (const snow::InputError&) {
        ++refused;
      }
    }
  }
  EXPECT_EQ(loaded + refused, 800);
  EXPECT_GT(refused, 0);
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
