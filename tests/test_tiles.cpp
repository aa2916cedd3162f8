// City scale (issue 55): `snowmodel snow --tiles` and `snowmodel merge` end
// to end on a town built in code. Tiles merged in any split give the untiled
// run's snow (within 1 %, the same patches, closed meshes, a validator-clean
// glTF); a merge refuses missing tiles; a tile run again replaces its own
// folder only; and a town too large for one run at its texel size runs as
// tiles, each within the memory budget.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "mesh/gltf_writer.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "support/command.h"
#include "support/validator.h"

namespace snow {
namespace {
namespace fs = std::filesystem;

test::CommandResult run(const std::string& args) { return test::run_snowmodel(args); }

std::string q(const fs::path& p) { return test::quoted(p); }

fs::path temp_dir(const std::string& name) { return test::fresh_dir("snow_tiles", name); }

/// A town: `n` x `n` gable-roofed houses 12 m apart on open ground, as a .glb.
fs::path save_town(const fs::path& dir, int n) {
  SceneBuilder b;
  const float half = 6.0f * float(n);
  b.add_plane("Ground", 0.0f, {-half, -half}, {half, half});
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const float x = -half + 6.0f + 12.0f * float(c), z = -half + 6.0f + 12.0f * float(r);
      const std::string name = "House" + std::to_string(r * n + c);
      b.add_box(name + "Walls", {x - 3.0f, 0.0f, z - 2.0f}, {x + 3.0f, 3.0f, z + 2.0f});
      b.add_gable_roof(name + "Roof", {x - 3.0f, 3.0f, z - 2.0f}, {x + 3.0f, 3.0f, z + 2.0f},
                       r % 2 ? 50.0f : 30.0f, 0.4f, 0.15f);
    }
  }
  tinygltf::Model model;
  append_meshes(model, b.meshes(), b.materials(), "Town");
  const fs::path path = dir / "town.glb";
  save_gltf(model, path);
  return path;
}

/// The number after `key` in `text`, after `from` where given (-1 when absent).
double number_after(const std::string& text, const std::string& key, const std::string& from = "") {
  const size_t start = from.empty() ? 0 : text.rfind(from);
  const size_t at = start == std::string::npos ? start : text.find(key, start);
  return at == std::string::npos ? -1.0 : std::atof(text.c_str() + at + key.size());
}

/// The patches of a summary line ("snow out N in P patches").
double patches_of(const std::string& text) { return number_after(text, " in ", "snow out "); }

/// Runs every tile of a `split` ("CxR", `count` tiles) of `scene`.
void run_tiles(const fs::path& scene, const std::string& split, int count, const fs::path& dir,
               const std::string& options) {
  for (int i = 0; i < count; ++i) {
    const test::CommandResult r = run("snow " + q(scene) + " --tiles " + split + " --tile " +
                                      std::to_string(i) + " --tile-dir " + q(dir) + options);
    ASSERT_EQ(r.code, 0) << r.output;
  }
}

const std::string kOptions = " --texel 0.1 --directions 16";

// The town snowed whole, and as 2 x 2 and 3 x 1 tiles merged: the same snow
// volume within 1 %, the same patches, each a closed mesh, and a merged
// scene-plus-snow glTF that the Khronos validator passes; in still air, and
// (2 x 2) in a wind that blows the snow into drifts.
class TilesMerge : public testing::TestWithParam<std::string> {};

TEST_P(TilesMerge, MergedTilesGiveTheUntiledRunsSnow) {
  const bool wind = !GetParam().empty();
  const fs::path dir = temp_dir(wind ? "wind" : "merge");
  const fs::path scene = save_town(dir, 3);
  const std::string options = kOptions + GetParam();
  const test::CommandResult whole =
      run("snow " + q(scene) + " --snow-output " + q(dir / "whole.glb") + options);
  ASSERT_EQ(whole.code, 0) << whole.output;
  const double volume = number_after(whole.output, "; snow ");
  const double patches = patches_of(whole.output);
  ASSERT_GT(volume, 10.0) << whole.output;
  const Scene untiled = load_scene(dir / "whole.glb");
  for (int o = 0; o < int(untiled.objects.size()); ++o) {
    EXPECT_TRUE(check_object_topology(untiled, o).closed()) << untiled.objects[size_t(o)].name;
  }
  std::vector<std::pair<std::string, int>> splits = {{"2x2", 4}};
  if (!wind) splits.push_back({"3x1", 3});
  for (const auto& [split, count] : splits) {
    SCOPED_TRACE(split);
    const fs::path tiles = dir / ("tiles_" + split);
    run_tiles(scene, split, count, tiles, options);
    for (int i = 0; i < count; ++i) {  // each tile's own snow, to look at
      EXPECT_TRUE(fs::exists(tiles / ("tile_000" + std::to_string(i) + ".glb"))) << i;
    }
    const fs::path merged = dir / ("merged_" + split + ".glb");
    const test::CommandResult m = run("merge " + q(tiles) + " -o " + q(merged) + " --snow-output " +
                                      q(dir / ("snow_" + split + ".glb")));
    ASSERT_EQ(m.code, 0) << m.output;
    std::printf("%s: %.3f m^3 in %.0f patches (untiled %.3f in %.0f)\n", split.c_str(),
                number_after(m.output, "; snow "), patches_of(m.output), volume, patches);
    EXPECT_NEAR(number_after(m.output, "; snow "), volume, 0.01 * volume);
    EXPECT_EQ(patches_of(m.output), patches);
    const Scene snow = load_scene(dir / ("snow_" + split + ".glb"));
    ASSERT_EQ(double(snow.objects.size()), patches);
    EXPECT_EQ(snow.stats.degenerate_dropped, 0u) << "zero-area triangles";
    for (int o = 0; o < int(snow.objects.size()); ++o) {
      const TopologyReport t = check_object_topology(snow, o);
      EXPECT_TRUE(t.closed()) << snow.objects[size_t(o)].name << ": " << t.boundary_edges
                              << " boundary, " << t.nonmanifold_edges << " non-manifold, "
                              << t.misoriented_edges << " misoriented edges, "
                              << t.degenerate_triangles << " degenerate triangles";
    }
    test::expect_valid_gltf({merged});
  }
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Tiles, TilesMerge, testing::Values("", " --wind 8,3"),
                         [](const testing::TestParamInfo<std::string>& p) {
                           return p.param.empty() ? "StillAir" : "Wind";
                         });

// A merge with a tile missing names it and writes nothing; a tile run again
// replaces its own folder and leaves the others as they were.
TEST(Tiles, MissingTilesAreNamedAndReRunsTouchOnlyTheirOwn) {
  const fs::path dir = temp_dir("missing");
  const fs::path scene = save_town(dir, 2);
  const fs::path tiles = dir / "tiles";
  run_tiles(scene, "2x2", 4, tiles, kOptions);
  fs::remove_all(tiles / "tile_0002");
  const test::CommandResult m = run("merge " + q(tiles) + " -o " + q(dir / "out.glb"));
  EXPECT_EQ(m.code, 2) << m.output;
  EXPECT_NE(m.output.find("tile 2 of 2 x 2 missing"), std::string::npos) << m.output;
  EXPECT_FALSE(fs::exists(dir / "out.glb"));

  const auto stamp = [&](int i) {
    return fs::last_write_time(tiles / ("tile_000" + std::to_string(i)) / "manifest.json");
  };
  const auto before = stamp(1);
  // What a tile run killed while writing leaves: its folder under a
  // temporary name, which neither the re-run nor the merge takes for a tile.
  fs::create_directories(tiles / ".tile_0000.tmp99_0");
  run_tiles(scene, "2x2", 1, tiles, kOptions);  // tile 0 again
  EXPECT_EQ(stamp(1), before);
  run_tiles(scene, "2x2", 3, tiles, kOptions);  // tile 2 again
  const test::CommandResult merged = run("merge " + q(tiles) + " -o " + q(dir / "out.glb"));
  EXPECT_EQ(merged.code, 0) << merged.output;
  // Tiles of another split do not mix.
  run_tiles(scene, "1x1", 1, dir / "other", kOptions);
  fs::remove_all(tiles / "tile_0000");
  fs::rename(dir / "other" / "tile_0000", tiles / "tile_0000");
  const test::CommandResult mixed = run("merge " + q(tiles) + " -o " + q(dir / "mixed.glb"));
  EXPECT_EQ(mixed.code, 2) << mixed.output;
  EXPECT_NE(mixed.output.find("another split"), std::string::npos) << mixed.output;
  fs::remove_all(dir);
}

// A town whose untiled run needs more than the memory budget at its texel
// size: refused whole (one line, before any work), snowed as 3 x 3 tiles
// within the same budget each, and merged within it.
TEST(Tiles, ATownTooLargeForOneRunRunsAsTiles) {
  const fs::path dir = temp_dir("large");
  const fs::path scene = save_town(dir, 6);
  const std::string budget = " --texel 0.2 --directions 16 --memory-budget 0.06";
  const test::CommandResult whole =
      run("snow " + q(scene) + " --snow-output " + q(dir / "whole.glb") + budget);
  EXPECT_EQ(whole.code, 2) << whole.output;
  EXPECT_NE(whole.output.find("budget"), std::string::npos) << whole.output;
  const fs::path tiles = dir / "tiles";
  run_tiles(scene, "3x3", 9, tiles, budget);
  const test::CommandResult m =
      run("merge " + q(tiles) + " --snow-output " + q(dir / "snow.glb") + " --memory-budget 0.06");
  ASSERT_EQ(m.code, 0) << m.output;
  EXPECT_GT(number_after(m.output, "; snow "), 0.25 * 72.0 * 72.0 * 0.5) << m.output;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace snow
