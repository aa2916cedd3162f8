// Tests of the glTF loader (scene/load_gltf.h) on broken and hostile input:
// every file is refused with one InputError that names the file and the
// element at fault, and never crashes. Each scene is built here in code
// (support/gltf_scene.h) and then broken.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "scene/load_gltf.h"
#include "support/gltf_scene.h"

namespace snow::test {
namespace {

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

// An accessor of count 0 (found by fuzz_load): no elements to convert, no
// copy from or to a null pointer: the scene has no triangle, said in one line.
TEST_F(SceneLoad, AnEmptyPositionAccessorGivesNoTriangles) {
  Gltf g;
  const int pos = g.positions(kUpTriangle);
  const int mesh = g.mesh(json::array({{{"attributes", {{"POSITION", pos}}}}}), "Empty");
  g.scene({g.node({{"mesh", mesh}})});
  g.doc["accessors"][size_t(pos)]["count"] = 0;
  expect_input_error(g.write_glb(dir_, "empty"), "the scene has no triangles");
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

}  // namespace
}  // namespace snow::test
