// Tests of the --maps writer (src/mesh/write_maps.h): EXR values, 16-bit
// PNG previews and the manifest, read back with tinyexr, stb_image and
// nlohmann::json.
#include <gtest/gtest.h>
#include <stb_image.h>
#include <tinyexr.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"
#include "mesh/write_maps.h"
#include "support/exr.h"

namespace snow {
namespace {
namespace fs = std::filesystem;
using snow::test::read_exr;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("snow_test_write_maps_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

// A 13 x 7 grid, 3 layers: layer 0 everywhere (a slope), layer 1 under a
// shelf in the middle, layer 2 empty.
SnowMaps make_maps() {
  MapGrid grid;
  grid.origin = {-1.0f, 2.0f};
  grid.texel = 0.25f;
  grid.width = 13;
  grid.height = 7;
  SnowMaps maps;
  maps.allocate(grid, 3);
  for (int j = 0; j < grid.height; ++j) {
    for (int i = 0; i < grid.width; ++i) {
      maps.ground[maps.index(0, i, j)] = 0.1f * i + 0.01f * j;
      if (i >= 4 && i < 8) maps.ground[maps.index(1, i, j)] = -0.5f;
    }
  }
  maps.overflow_columns = 3;
  return maps;
}

std::vector<uint16_t> read_png16(const fs::path& path, int* width, int* height) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  int channels = 0;
  stbi_us* data =
      stbi_load_16_from_memory(bytes.data(), int(bytes.size()), width, height, &channels, 1);
  EXPECT_NE(data, nullptr) << stbi_failure_reason();
  EXPECT_EQ(channels, 1);
  std::vector<uint16_t> out;
  if (data) out.assign(data, data + size_t(*width) * size_t(*height));
  stbi_image_free(data);
  return out;
}

TEST(EncodePng16, RoundTripsExactly) {
  std::mt19937 rng(7);
  std::vector<uint16_t> grey(37 * 11);
  for (auto& v : grey) v = uint16_t(rng());
  grey[0] = 0;
  grey[1] = 65535;
  const std::vector<uint8_t> png = encode_png16(grey, 37, 11);
  int w = 0, h = 0, c = 0;
  stbi_us* data = stbi_load_16_from_memory(png.data(), int(png.size()), &w, &h, &c, 1);
  ASSERT_NE(data, nullptr) << stbi_failure_reason();
  EXPECT_EQ(w, 37);
  EXPECT_EQ(h, 11);
  EXPECT_EQ(c, 1);
  EXPECT_TRUE(std::equal(grey.begin(), grey.end(), data));
  stbi_image_free(data);
  EXPECT_THROW(encode_png16(grey, 36, 11), InputError);
}

TEST(WriteMaps, WritesExrPngAndManifest) {
  const SnowMaps maps = make_maps();
  std::vector<float> coverage(maps.ground.size(), 0.0f), depth(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < coverage.size(); ++k) {
    if (std::isnan(maps.ground[k])) continue;
    coverage[k] = float(k % 5) / 4.0f;
    depth[k] = 0.02f * float(k % 7);
  }
  const fs::path dir = fresh_dir("full");
  write_maps(dir, maps, &coverage, &depth);

  std::ifstream in(dir / "manifest.json");
  const nlohmann::json m = nlohmann::json::parse(in);
  EXPECT_EQ(m["format"], "snowmodel-maps");
  EXPECT_EQ(m["up_axis"], "+Y");
  EXPECT_EQ(m["units"], "metres");
  EXPECT_EQ(m["width"], 13);
  EXPECT_EQ(m["height"], 7);
  EXPECT_FLOAT_EQ(m["texel_size"].get<float>(), 0.25f);
  EXPECT_FLOAT_EQ(m["origin"][0].get<float>(), -1.0f);
  EXPECT_FLOAT_EQ(m["origin"][1].get<float>(), 2.0f);
  EXPECT_EQ(m["layers"], 2);  // layer 2 is empty: not written
  EXPECT_EQ(m["map_layers"], 3);
  EXPECT_EQ(m["overflow_columns"], 3);
  ASSERT_EQ(m["files"].size(), 6u);
  for (const auto& f : m["files"]) {
    EXPECT_TRUE(fs::exists(dir / f["exr"].get<std::string>()));
    EXPECT_TRUE(fs::exists(dir / f["png"].get<std::string>()));
  }
  EXPECT_FALSE(fs::exists(dir / "layer2_height.exr"));

  // Heights: exact floats, NaN where no surface; row r is grid row j = r.
  int w = 0, h = 0;
  const std::vector<float> h1 = read_exr(dir / "layer1_height.exr", &w, &h);
  ASSERT_EQ(w, 13);
  ASSERT_EQ(h, 7);
  for (int j = 0; j < 7; ++j) {
    for (int i = 0; i < 13; ++i) {
      const float expected = maps.ground[maps.index(1, i, j)];
      const float got = h1[size_t(j) * 13 + size_t(i)];
      if (std::isnan(expected)) {
        EXPECT_TRUE(std::isnan(got));
      } else {
        EXPECT_EQ(got, expected);
      }
    }
  }
  const std::vector<float> c0 = read_exr(dir / "layer0_coverage.exr", &w, &h);
  const std::vector<float> d1 = read_exr(dir / "layer1_depth.exr", &w, &h);
  for (size_t t = 0; t < maps.grid.texels(); ++t) {
    EXPECT_EQ(c0[t], coverage[t]);
    EXPECT_EQ(d1[t], depth[maps.grid.texels() + t]);
  }

  // Previews: heights scaled over [min, max] of all layers, 0 where none.
  const float lo = m["ranges"]["height"]["png_black"].get<float>();
  const float hi = m["ranges"]["height"]["png_white"].get<float>();
  EXPECT_FLOAT_EQ(lo, -0.5f);
  EXPECT_NEAR(hi, 1.26f, 1e-6);
  const std::vector<uint16_t> p0 = read_png16(dir / "layer0_height.png", &w, &h);
  ASSERT_EQ(p0.size(), maps.grid.texels());
  for (size_t t = 0; t < p0.size(); ++t) {
    const float v = lo + float(p0[t]) / 65535.0f * (hi - lo);
    EXPECT_NEAR(v, maps.ground[t], (hi - lo) / 65535.0f);
  }
  const std::vector<uint16_t> pc = read_png16(dir / "layer0_coverage.png", &w, &h);
  for (size_t t = 0; t < pc.size(); ++t) EXPECT_NEAR(pc[t] / 65535.0f, coverage[t], 1e-5f);
  const std::vector<uint16_t> p1 = read_png16(dir / "layer1_height.png", &w, &h);
  EXPECT_EQ(p1[0], 0);  // (0, 0) has no layer-1 surface
  fs::remove_all(dir);
}

TEST(WriteMaps, HeightsOnlyWithoutCoverageOrDepth) {
  const SnowMaps maps = make_maps();
  const fs::path dir = fresh_dir("heights");
  write_maps(dir / "nested" / "maps", maps);  // folders are created
  std::ifstream in(dir / "nested" / "maps" / "manifest.json");
  const nlohmann::json m = nlohmann::json::parse(in);
  EXPECT_EQ(m["files"].size(), 2u);
  EXPECT_FALSE(m["ranges"].contains("coverage"));
  fs::remove_all(dir);
}

TEST(WriteMaps, RejectsBadInput) {
  const SnowMaps maps = make_maps();
  std::vector<float> short_coverage(5, 0.0f);
  const fs::path dir = fresh_dir("bad");
  EXPECT_THROW(write_maps(dir, maps, &short_coverage), InputError);
  // A file where the folder should be.
  fs::create_directories(dir);
  write_text_atomically(dir / "file", "x");
  EXPECT_THROW(write_maps(dir / "file", maps), IOError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace snow
