// The input policy (scene/input_policy.h) through the glTF loader: JSON
// nesting, files outside the scene's folder (by "..", percent-encoding,
// absolute paths and symlinks), files that are not regular files, buffer
// files read only as far as declared, and the memory budget summed over the
// scene's data and decoded images. The same files through the CLI, the
// combined writer included, are in test_hostile.cpp and test_export.cpp.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <future>
#include <iterator>
#include <string>
#include <vector>

#include "scene/input_policy.h"
#include "support/gltf_scene.h"

namespace snow::test {
namespace {

std::string nested_arrays(size_t levels) {
  return std::string(levels, '[') + std::string(levels, ']');
}

/// The one-triangle scene of `g` as `name`.gltf + .bin in `dir`, with `extra`
/// (raw JSON text, e.g. `"extras": ...`) added to its top-level object.
fs::path write_with_raw_member(Gltf g, const fs::path& dir, const std::string& name,
                               const std::string& extra) {
  const fs::path path = g.write_gltf(dir, name);
  std::ifstream in(path);
  std::string text{std::istreambuf_iterator<char>(in), {}};
  text.insert(text.rfind('}'), "," + extra);
  write_text(path, text);
  return path;
}

/// A PPM (binary, 8 bits) image of `side` x `side` grey pixels, which
/// stb_image decodes without a compressor in the test.
std::vector<uint8_t> ppm(int side) {
  const std::string header = "P6\n" + std::to_string(side) + " " + std::to_string(side) + "\n255\n";
  std::vector<uint8_t> bytes(header.begin(), header.end());
  bytes.resize(bytes.size() + size_t(side) * size_t(side) * 3, 128);
  return bytes;
}

TEST(InputPolicy, JsonDepthCountsBracketsOutsideStrings) {
  EXPECT_NO_THROW(check_json_depth(nested_arrays(kMaxJsonDepth), "f.gltf"));
  try {
    check_json_depth(nested_arrays(kMaxJsonDepth + 1), "f.gltf");
    ADD_FAILURE() << "not refused";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "f.gltf: JSON nested deeper than 512 levels");
  }
  // Brackets in strings, after escaped quotes and backslashes, do not count.
  const std::string in_string = "[\"\\\\\\\"" + std::string(2000, '[') + "\"]";
  EXPECT_NO_THROW(check_json_depth(in_string, "f.gltf"));
  EXPECT_THROW(check_json_depth("[\"\\\\\"" + nested_arrays(600) + "]", "f.gltf"), InputError);
}

TEST(InputPolicy, SceneJsonTextIsTheGlbJsonChunk) {
  const std::vector<uint8_t> glb = triangle_gltf().glb_bytes();
  const std::string_view text = scene_json_text(glb.data(), glb.size());
  EXPECT_EQ(text.front(), '{');
  EXPECT_EQ(json::parse(text)["asset"]["version"], "2.0");
  const std::string plain = "{\"asset\":{}}";
  EXPECT_EQ(scene_json_text(reinterpret_cast<const uint8_t*>(plain.data()), plain.size()), plain);
}

TEST_F(SceneLoad, DeeplyNestedJsonIsRefusedBeforeParsing) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  EXPECT_NO_THROW(
      load_scene(write_with_raw_member(g, dir_, "shallow", "\"extras\":" + nested_arrays(400))));
  expect_input_error(write_with_raw_member(g, dir_, "deep", "\"extras\":" + nested_arrays(30000)),
                     "JSON nested deeper than 512 levels");
}

TEST_F(SceneLoad, SymlinksOutOfTheSceneFolderAreRefused) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  const fs::path folder = dir_ / "scene", elsewhere = dir_ / "elsewhere";
  fs::create_directories(folder);
  fs::create_directories(elsewhere);
  g.write_gltf(elsewhere, "secret");
  const auto scene_with_buffer = [&](const std::string& name, const std::string& uri) {
    json d = g.doc;
    d["buffers"] = json::array({{{"byteLength", g.bin.size()}, {"uri", uri}}});
    write_text(folder / (name + ".gltf"), d.dump());
    return folder / (name + ".gltf");
  };
  fs::create_symlink(elsewhere / "secret.bin", folder / "link.bin");
  expect_input_error(scene_with_buffer("file_link", "link.bin"), "symlink");
  fs::create_directory_symlink(elsewhere, folder / "sub");
  expect_input_error(scene_with_buffer("folder_link", "sub/secret.bin"), "symlink");
  // Symlinks that stay inside the folder are followed.
  fs::copy_file(elsewhere / "secret.bin", folder / "real.bin");
  fs::create_symlink("real.bin", folder / "inner.bin");
  EXPECT_EQ(load_scene(scene_with_buffer("inner_link", "inner.bin")).triangle_count(), 1u);
}

TEST_F(SceneLoad, ImageUrisOutsideTheFolderAreRefusedWhetherOrNotImagesLoad) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  const fs::path folder = dir_ / "scene";
  fs::create_directories(folder);
  write_bytes(dir_ / "x.png", ppm(2));
  fs::create_symlink(dir_ / "x.png", folder / "link.png");
  for (const std::string& uri : std::vector<std::string>{
           "../x.png", "%2e%2e/x.png", "%2E%2E%2Fx.png", (dir_ / "x.png").string(), "link.png"}) {
    SCOPED_TRACE(uri);
    // An image no material uses is refused too: the combined writer would copy it.
    Gltf bad = g;
    bad.doc["images"] = json::array({{{"uri", uri}}});
    const fs::path path = bad.write_gltf(folder, "image");
    for (const bool images : {false, true}) {
      LoadSettings settings;
      settings.load_images = images;
      expect_input_error(path, "refused", settings);
    }
  }
}

TEST_F(SceneLoad, FifosAreRefusedWithoutWaiting) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  ASSERT_EQ(mkfifo((dir_ / "pipe.gltf").c_str(), 0600), 0);
  ASSERT_EQ(mkfifo((dir_ / "pipe.bin").c_str(), 0600), 0);
  json d = g.doc;
  d["buffers"] = json::array({{{"byteLength", g.bin.size()}, {"uri", "pipe.bin"}}});
  write_text(dir_ / "buffer_pipe.gltf", d.dump());
  for (const char* name : {"pipe.gltf", "buffer_pipe.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path path = dir_ / name;
    auto done = std::async(std::launch::async, [path] { expect_input_error(path, "regular"); });
    if (done.wait_for(std::chrono::seconds(20)) != std::future_status::ready) {
      ADD_FAILURE() << "the loader waits on a FIFO";
      // A writer lets the blocked open return.
      for (const char* fifo : {"pipe.gltf", "pipe.bin"})
        ::close(::open((dir_ / fifo).c_str(), O_WRONLY | O_NONBLOCK));
    }
    done.get();
  }
}

TEST_F(SceneLoad, BufferFilesAreReadOnlyAsFarAsTheirByteLength) {
  int mesh = 0;
  Gltf g = triangle_gltf(&mesh);
  g.scene({g.node({{"mesh", mesh}})});
  const fs::path path = g.write_gltf(dir_, "big");
  // 5 GiB (sparse: no disk) behind a byteLength of a few dozen bytes.
  std::error_code ec;
  fs::resize_file(dir_ / "big.bin", uint64_t(5) << 30, ec);
  if (ec) GTEST_SKIP() << "cannot make a sparse 5 GiB file here: " << ec.message();
  LoadSettings settings;
  settings.limits.memory_budget = uint64_t(1) << 20;  // the whole file would be far over
  EXPECT_EQ(load_scene(path, settings).triangle_count(), 1u);
}

/// A triangle scene with `images` materials, each with its own PPM image of
/// 256 x 256 pixels (256 KiB decoded), each used by one primitive.
fs::path write_textured(const fs::path& dir, int images) {
  Gltf g;
  const int positions = g.positions(kUpTriangle);
  json primitives = json::array();
  for (int i = 0; i < images; ++i) {
    const std::string name = "image" + std::to_string(i) + ".ppm";
    write_bytes(dir / name, ppm(256));
    g.doc["images"].push_back({{"uri", name}});
    g.doc["textures"].push_back({{"source", i}});
    g.doc["materials"].push_back(
        {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", i}}}}}});
    primitives.push_back({{"attributes", {{"POSITION", positions}}}, {"material", i}});
  }
  g.scene({g.node({{"mesh", g.mesh(primitives)}})});
  return g.write_gltf(dir, "textured");
}

TEST_F(SceneLoad, DecodedImagesAreSummedAgainstTheMemoryBudget) {
  const fs::path path = write_textured(dir_, 3);
  LoadSettings settings;
  EXPECT_EQ(load_scene(path, settings).images.size(), 3u);
  // Three decoded images (768 KiB) and one file being decoded fit in 1 MiB...
  settings.limits.memory_budget = uint64_t(1) << 20;
  EXPECT_EQ(load_scene(path, settings).images.size(), 3u);
  // ... not in 600 KiB, though each one alone would.
  settings.limits.memory_budget = 600 << 10;
  expect_input_error(path, "over the memory budget of 0.000572 GiB (--memory-budget)", settings);
  expect_input_error(path, "image 1", settings);
  // Without images (snow without --preview) they take nothing.
  settings.load_images = false;
  EXPECT_NO_THROW(load_scene(path, settings));
}

}  // namespace
}  // namespace snow::test
