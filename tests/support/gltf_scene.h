#pragma once
// What the tests of the glTF loader share (test_scene_load*.cpp): a builder
// of glTF documents with one binary buffer, written as .gltf + .bin, .gltf
// with a data URI or .glb; small scene helpers; and the SceneLoad fixture,
// which gives each test an empty temporary folder and a quiet log.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "base64.h"  // tests/support/base64.h
#include "core/error.h"
#include "core/log.h"
#include "scene/load_gltf.h"

namespace snow::test {

namespace fs = std::filesystem;
using json = nlohmann::json;

inline constexpr int kUByte = 5121;
inline constexpr int kShort = 5122;
inline constexpr int kUShort = 5123;
inline constexpr int kUInt = 5125;
inline constexpr int kFloat = 5126;

inline fs::path temp_dir(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / ("snow_test_scene_load_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

inline void write_bytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

inline void write_text(const fs::path& path, const std::string& text) {
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
  int scalars(const std::vector<float>& v) { return accessor(view(v), kFloat, v.size(), "SCALAR"); }
  int vec4s(const std::vector<glm::vec4>& v) { return accessor(view(v), kFloat, v.size(), "VEC4"); }
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
  /// Appends an animation of one channel, on `node`'s `path`, with one
  /// sampler (accessors `input`, `output`); returns its index.
  int animation(int node, const std::string& path, int input, int output,
                const std::string& interpolation = "LINEAR") {
    if (!doc.contains("animations")) doc["animations"] = json::array();
    doc["animations"].push_back(
        {{"channels",
          json::array({{{"sampler", 0}, {"target", {{"node", node}, {"path", path}}}}})},
         {"samplers",
          json::array(
              {{{"input", input}, {"output", output}, {"interpolation", interpolation}}})}});
    return int(doc["animations"].size() - 1);
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
inline const std::vector<glm::vec3> kUpTriangle = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}};

/// Gltf with one mesh (one TRIANGLES primitive: kUpTriangle, with normals).
inline Gltf triangle_gltf(int* mesh_out = nullptr, bool normals = true) {
  Gltf g;
  json attributes = {{"POSITION", g.positions(kUpTriangle)}};
  if (normals) attributes["NORMAL"] = g.vec3s({{0, 1, 0}, {0, 1, 0}, {0, 1, 0}});
  const int mesh = g.mesh(json::array({{{"attributes", attributes}}}), "Tri");
  if (mesh_out) *mesh_out = mesh;
  return g;
}

inline glm::vec3 corner(const snow::Scene& s, size_t triangle, int k) {
  return s.positions[3 * triangle + size_t(k)];
}

inline glm::vec3 face_normal(const snow::Scene& s, size_t t) {
  return glm::normalize(
      glm::cross(corner(s, t, 1) - corner(s, t, 0), corner(s, t, 2) - corner(s, t, 0)));
}

inline void expect_near(const glm::vec3& a, const glm::vec3& b, float tolerance = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

inline double total_area(const snow::Scene& s) {
  double area = 0;
  for (size_t t = 0; t < s.triangle_count(); ++t)
    area += 0.5 * glm::length(glm::cross(corner(s, t, 1) - corner(s, t, 0),
                                         corner(s, t, 2) - corner(s, t, 0)));
  return area;
}

/// Expects load_scene to throw InputError whose message contains `needle`.
inline void expect_input_error(const fs::path& path, const std::string& needle,
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

}  // namespace snow::test
