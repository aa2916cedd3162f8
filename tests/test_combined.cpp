// Tests of the combined writer's buffers (mesh/export.h,
// write_combined_gltf; mesh/glb_stream.h): every input buffer merged into
// one output buffer, buffer files read no further than their byteLength,
// and the input policy for buffers the scene does not use (the loader never
// looks at those). Crafted inputs are built in a temporary folder.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/log.h"
#include "mesh/export.h"
#include "scene/load_gltf.h"
#include "support/base64.h"
#include "support/files.h"
#include "support/validator.h"

namespace snow {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// A fresh folder for one test, removed afterwards.
struct Folder {
  fs::path path;
  Folder() {
    path = fs::temp_directory_path() /
           ("snow_test_combined_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(getpid()));
    fs::remove_all(path);
    fs::create_directories(path / "out");
  }
  ~Folder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

std::string bytes_of(const void* data, size_t size) {
  return std::string(static_cast<const char*>(data), size);
}

/// Three triangles, each with its positions in its own buffer: buffer 0 a
/// .bin whose byteLength (37) is not a multiple of 8, buffer 1 a .bin whose
/// view starts 4 bytes in, buffer 2 a data URI. Each a mesh, node, root.
json three_buffer_gltf(const fs::path& folder) {
  const float a[9] = {0, 0, 0, 0, 0, 1, 1, 0, 0};
  const float b[9] = {2, 0, 0, 2, 0, 1, 3, 0, 0};
  const float c[9] = {4, 1, 0, 4, 1, 1, 5, 1, 0};
  test::write_all(folder / "a.bin", bytes_of(a, 36) + "x");
  test::write_all(folder / "b.bin", "junk" + bytes_of(b, 36));
  const std::string c_bytes = bytes_of(c, 36);
  json g;
  g["asset"] = {{"version", "2.0"}};
  g["buffers"] = {{{"uri", "a.bin"}, {"byteLength", 37}},
                  {{"uri", "b.bin"}, {"byteLength", 40}},
                  {{"uri", "data:application/octet-stream;base64," +
                               test::base64(std::vector<uint8_t>(c_bytes.begin(), c_bytes.end()))},
                   {"byteLength", 36}}};
  g["bufferViews"] = {{{"buffer", 0}, {"byteLength", 36}},
                      {{"buffer", 1}, {"byteOffset", 4}, {"byteLength", 36}},
                      {{"buffer", 2}, {"byteLength", 36}}};
  for (int i = 0; i < 3; ++i) {
    const float* p = i == 0 ? a : i == 1 ? b : c;
    g["accessors"].push_back({{"bufferView", i},
                              {"componentType", 5126},
                              {"count", 3},
                              {"type", "VEC3"},
                              {"min", {p[0], p[1], p[2]}},
                              {"max", {p[6], p[1], p[5]}}});
    g["meshes"].push_back({{"primitives", {{{"attributes", {{"POSITION", i}}}}}}});
    g["nodes"].push_back({{"mesh", i}});
  }
  g["scenes"] = {{{"nodes", {0, 1, 2}}}};
  g["scene"] = 0;
  return g;
}

/// The scene at `path` as the batch job loads it for the combined writer.
std::shared_ptr<const SourceGltf> source_of(const fs::path& path) {
  LoadSettings settings;
  settings.load_images = settings.shading = false;
  settings.keep_source = true;
  return load_scene(path, settings).source;
}

/// The JSON of a .glb or .gltf output.
json json_of(const fs::path& out) {
  const std::string bytes = test::read_all(out);
  if (out.extension() == ".gltf") return json::parse(bytes);
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return json::parse(bytes.substr(20, length));
}

/// A snow patch: one upward triangle above the scene.
std::vector<SnowPatch> one_patch() {
  SnowPatch p;
  p.mesh.name = "snow/x";
  p.mesh.positions = {{0, 2, 0}, {0, 2, 1}, {1, 2, 0}};
  p.mesh.normals = {{0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
  p.mesh.indices = {0, 1, 2};
  return {p};
}

// Two .bin buffers and a data-URI buffer become one buffer in a .glb and in
// a .gltf (with its one "<stem>.bin"); every view points into it, from
// 8-byte boundaries, and the loader reads the same positions back.
TEST(Combined, MergesEveryBufferIntoOne) {
  set_log_level(LogLevel::Quiet);
  const Folder folder;
  const fs::path& dir = folder.path;
  test::write_all(dir / "three.gltf", three_buffer_gltf(dir).dump());
  const Scene before = load_scene(dir / "three.gltf");
  const auto source = source_of(dir / "three.gltf");
  for (const char* name : {"out.glb", "out.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path out = dir / "out" / name;
    write_combined_gltf(*source, one_patch(), out);
    const json g = json_of(out);
    ASSERT_EQ(g["buffers"].size(), 1u) << g.dump();
    for (const json& view : g["bufferViews"]) EXPECT_EQ(view["buffer"], 0);
    EXPECT_EQ(g["bufferViews"][0].value("byteOffset", 0), 0);
    EXPECT_EQ(g["bufferViews"][1]["byteOffset"], 40 + 4);  // buffer 1 from 40 (37 to 8 bytes)
    EXPECT_EQ(g["bufferViews"][2]["byteOffset"], 80);      // buffer 2 from 80
    const Scene after = load_scene(out);
    ASSERT_EQ(after.positions.size(), before.positions.size() + 3);  // the snow's triangle
    for (size_t i = 0; i < before.positions.size(); ++i)
      EXPECT_EQ(after.positions[i], before.positions[i]) << "position " << i;
  }
  EXPECT_EQ(json_of(dir / "out" / "out.gltf")["buffers"][0]["uri"], "out.bin");
  EXPECT_TRUE(fs::exists(dir / "out" / "out.bin"));
  test::expect_valid_gltf({dir / "out" / "out.glb", dir / "out" / "out.gltf"});
}

// EXT_meshopt_compression's bufferView extension names a buffer and an
// offset in it: both follow the merge.
TEST(Combined, PointsMeshoptViewsIntoTheOneBuffer) {
  set_log_level(LogLevel::Quiet);
  const Folder folder;
  const fs::path& dir = folder.path;
  json g = three_buffer_gltf(dir);
  g["extensionsUsed"] = {"EXT_meshopt_compression"};
  g["bufferViews"].push_back({{"buffer", 0},
                              {"byteLength", 36},
                              {"extensions",
                               {{"EXT_meshopt_compression",
                                 {{"buffer", 2},
                                  {"byteOffset", 8},
                                  {"byteLength", 28},
                                  {"count", 1},
                                  {"byteStride", 4},
                                  {"mode", "ATTRIBUTES"}}}}}});
  test::write_all(dir / "meshopt.gltf", g.dump());
  write_combined_gltf(*source_of(dir / "meshopt.gltf"), {}, dir / "out" / "x.glb");
  const json view = json_of(dir / "out" / "x.glb")["bufferViews"][3];
  EXPECT_EQ(view["extensions"]["EXT_meshopt_compression"]["buffer"], 0);
  EXPECT_EQ(view["extensions"]["EXT_meshopt_compression"]["byteOffset"], 80 + 8);
}

// A buffer file far larger than its byteLength (a sparse 64 MiB file behind
// byteLength 37) is copied only as far as byteLength: the output is small.
TEST(Combined, ReadsBufferFilesOnlyAsFarAsTheirByteLength) {
  set_log_level(LogLevel::Quiet);
  const Folder folder;
  const fs::path& dir = folder.path;
  test::write_all(dir / "three.gltf", three_buffer_gltf(dir).dump());
  const std::string a = test::read_all(dir / "a.bin");
  fs::resize_file(dir / "a.bin", uint64_t(64) << 20);
  const auto source = source_of(dir / "three.gltf");
  for (const char* name : {"big.glb", "big.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path out = dir / "out" / name;
    write_combined_gltf(*source, {}, out);
    const fs::path buffer = out.extension() == ".glb" ? out : dir / "out" / "big.bin";
    EXPECT_LT(fs::file_size(buffer), uint64_t(1) << 20);
    const json g = json_of(out);
    EXPECT_EQ(g["buffers"][0]["byteLength"], 116);  // 37, 40 from 40, 36 from 80
    const std::string bytes = test::read_all(buffer);
    const size_t bin = out.extension() == ".glb" ? bytes.size() - 116 : 0;
    EXPECT_EQ(bytes.substr(bin, 37), a);
  }
  test::expect_valid_gltf({dir / "out" / "big.glb", dir / "out" / "big.gltf"});
}

// A buffer the scene does not use (the loader never reads it) that the
// input cannot fill, or that the input policy refuses, is refused with one
// line naming the input and the buffer; nothing is written.
TEST(Combined, RefusesABufferTheInputCannotFill) {
  set_log_level(LogLevel::Quiet);
  const Folder folder;
  const fs::path& dir = folder.path;
  fs::create_directories(dir / "scene");
  test::write_all(dir / "outside.bin", std::string(64, 'x'));
  const json good = three_buffer_gltf(dir / "scene");
  test::write_all(dir / "scene" / "short.bin", "1234");
  fs::create_directories(dir / "scene" / "folder.bin");
  ASSERT_EQ(mkfifo((dir / "scene" / "fifo.bin").c_str(), 0600), 0);
  fs::create_symlink(dir / "outside.bin", dir / "scene" / "link.bin");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"missing.bin", "does not exist"},
      {"short.bin", "holds 4 bytes, but byteLength is 16"},
      {"folder.bin", "is a folder"},
      {"fifo.bin", "not a regular file"},
      {"link.bin", "symlink"},
      {"data:application/octet-stream;base64,AAAA", "holds 3 bytes, but byteLength is 16"},
  };
  for (const auto& [uri, needle] : cases) {
    SCOPED_TRACE(uri);
    json g = good;
    g["buffers"].push_back({{"uri", uri}, {"byteLength", 16}});
    test::write_all(dir / "scene" / "unused.gltf", g.dump());
    try {
      // The loader refuses a symlink out of the folder itself.
      write_combined_gltf(*source_of(dir / "scene" / "unused.gltf"), {}, dir / "out" / "x.glb");
      ADD_FAILURE() << "not refused";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("unused.gltf: buffer 3"), std::string::npos) << message;
      EXPECT_NE(message.find(needle), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
    EXPECT_TRUE(fs::is_empty(dir / "out"));
  }
}

}  // namespace
}  // namespace snow
