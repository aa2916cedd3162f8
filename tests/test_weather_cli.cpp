// `snowmodel snow --weather` end to end (issue 53): a run split into two
// resumed halves ends where the straight run ends, a resume on another grid
// and malformed weather files are refused with one line and no output, and
// sequences write a frame every --every hours.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "mesh/gltf_writer.h"
#include "scene/builder.h"
#include "support/command.h"
#include "support/exr.h"

namespace snow {
namespace {
namespace fs = std::filesystem;

const std::string kFast = " --max-side 96 --directions 8";

test::CommandResult run(const std::string& args) { return test::run_snowmodel(args); }

std::string q(const fs::path& p) { return test::quoted(p); }

fs::path temp_dir(const std::string& name) { return test::fresh_dir("snow_weather", name); }

/// A 16 m yard with a gable-roofed house, as a .glb.
fs::path save_yard(const fs::path& dir) {
  SceneBuilder b;
  b.add_plane("Yard", 0.0f, {-8.0f, -8.0f}, {8.0f, 8.0f});
  b.add_box("Walls", {-3.0f, 0.0f, -2.0f}, {3.0f, 2.5f, 2.0f});
  b.add_gable_roof("Roof", {-3.0f, 2.5f, -2.0f}, {3.0f, 2.5f, 2.0f}, 35.0f, 0.3f, 0.15f);
  tinygltf::Model model;
  append_meshes(model, b.meshes(), b.materials(), "Yard");
  const fs::path path = dir / "yard.glb";
  save_gltf(model, path);
  return path;
}

/// Hours [from, to) of a storm (snow with wind from the west) then a sunny
/// thaw.
fs::path save_weather(const fs::path& path, int from, int to) {
  std::ofstream out(path);
  out << "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud\n";
  for (int h = from; h < to; ++h) {
    if (h < 12) {
      out << h << ",2," << -4 - h % 3 << ",5,270,1\n";
    } else {
      out << h << ",0," << (h < 20 ? 3 : -1) << ",1,270,0.2\n";
    }
  }
  return path;
}

/// Sum over every layer of the maps folder's layer<l>_<kind>.exr.
double map_sum(const fs::path& dir, const std::string& kind) {
  double sum = 0.0;
  for (int l = 0; fs::exists(dir / ("layer" + std::to_string(l) + "_height.exr")); ++l) {
    int w = 0, h = 0;
    for (float v :
         test::read_exr(dir / ("layer" + std::to_string(l) + "_" + kind + ".exr"), &w, &h)) {
      sum += double(v);
    }
  }
  return sum;
}

nlohmann::json manifest(const fs::path& dir) {
  std::ifstream in(dir / "manifest.json");
  return nlohmann::json::parse(in);
}

// March at 47 N: 12 h of snow, then a thaw in the sun; straight, and in two
// halves (the second resumed from the first's maps): the lying water and
// depth end within 2 %, and the water balance holds.
TEST(WeatherCli, TwoResumedHalvesEndWhereTheStraightRunEnds) {
  const fs::path dir = temp_dir("resume");
  const fs::path scene = save_yard(dir);
  const std::string sun = " --start 2026-03-10T00:00 --latitude 47 --longitude 8" + kFast;
  const test::CommandResult full =
      run("snow " + q(scene) + " --maps " + q(dir / "full") + " --weather " +
          q(save_weather(dir / "all.csv", 0, 24)) + sun);
  ASSERT_EQ(full.code, 0) << full.output;
  const test::CommandResult first =
      run("snow " + q(scene) + " --maps " + q(dir / "first") + " --weather " +
          q(save_weather(dir / "first.csv", 0, 16)) + sun);
  ASSERT_EQ(first.code, 0) << first.output;
  const test::CommandResult second =
      run("snow " + q(scene) + " --maps " + q(dir / "second") + " --resume " + q(dir / "first") +
          " --weather " + q(save_weather(dir / "second.csv", 16, 24)) + sun);
  ASSERT_EQ(second.code, 0) << second.output;
  const double straight = map_sum(dir / "full", "swe"), resumed = map_sum(dir / "second", "swe");
  std::printf("lying water: straight %.6f, resumed %.6f (sums of texels)\n", straight, resumed);
  ASSERT_GT(straight, 0.0);
  EXPECT_NEAR(resumed, straight, 0.02 * straight);
  EXPECT_NEAR(map_sum(dir / "second", "depth"), map_sum(dir / "full", "depth"),
              0.02 * map_sum(dir / "full", "depth"));
  const nlohmann::json a = manifest(dir / "full")["snowpack"],
                       b = manifest(dir / "second")["snowpack"];
  EXPECT_NEAR(b["fallen"].get<double>(), a["fallen"].get<double>(),
              1e-6 * a["fallen"].get<double>());
  EXPECT_GT(b["melted"].get<double>(), 0.0);
  EXPECT_NEAR(b["melted"].get<double>(), a["melted"].get<double>(),
              0.02 * a["melted"].get<double>());
  EXPECT_DOUBLE_EQ(b["hour"].get<double>(), 24.0);
  // Mass balance from the files: lying + melted + lost = fallen.
  const double texel = manifest(dir / "second")["texel_size"].get<double>();
  EXPECT_NEAR(resumed * texel * texel + b["melted"].get<double>() + b["lost"].get<double>(),
              b["fallen"].get<double>(), 1e-4 * b["fallen"].get<double>());
  // Loads are water x g: 1 m of water is 9.81 kN/m^2.
  EXPECT_NEAR(map_sum(dir / "second", "load"), resumed * 9.80665, 1e-3 * resumed * 9.80665);
  fs::remove_all(dir);
}

TEST(WeatherCli, ResumingOnAnotherGridIsRefused) {
  const fs::path dir = temp_dir("grid");
  const fs::path scene = save_yard(dir);
  ASSERT_EQ(run("snow " + q(scene) + " --maps " + q(dir / "first") + " --weather " +
                q(save_weather(dir / "first.csv", 0, 4)) + kFast)
                .code,
            0);
  const test::CommandResult r =
      run("snow " + q(scene) + " -o " + q(dir / "out.glb") + " --resume " + q(dir / "first") +
          " --weather " + q(save_weather(dir / "second.csv", 4, 8)) + " --max-side 64");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("error: resume: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("written for 96 x"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.glb"));
  // A folder of a run without weather holds no snowpack.
  ASSERT_EQ(run("snow " + q(scene) + " --maps " + q(dir / "plain") + kFast).code, 0);
  const test::CommandResult plain =
      run("snow " + q(scene) + " -o " + q(dir / "out.glb") + " --resume " + q(dir / "plain") +
          " --weather " + q(dir / "second.csv") + kFast);
  EXPECT_EQ(plain.code, 2) << plain.output;
  EXPECT_NE(plain.output.find("hold no snowpack"), std::string::npos) << plain.output;
  fs::remove_all(dir);
}

// Each malformed file: exit 2, one error line naming the line and the
// column, before any work, and no output.
TEST(WeatherCli, MalformedWeatherFilesAreOneLineErrors) {
  const fs::path dir = temp_dir("malformed");
  const fs::path scene = save_yard(dir);
  const std::string header = "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud\n";
  const struct {
    std::string text, expected;
  } cases[] = {
      {"hour,precip_mm,wind_ms,wind_from_deg,cloud\n0,1,2,270,0\n", "missing column 'temp_c'"},
      {header + "0,1,-3,2,270,0\n1,1,cold,2,270,0\n", ":3: column 'temp_c'"},
      {header + "0,1,-3,2,270,0\n5,1,-3,2,270,0\n3,1,-3,2,270,0\n", ":4: hours must increase"},
      {header + "0,1,-3,2,270,0\n1,1,-3,2,270,7\n", ":3: column 'cloud'"},
      {header + "0,1,900,2,270,0\n", ":2: column 'temp_c'"},
  };
  for (const auto& c : cases) {
    { std::ofstream(dir / "bad.csv") << c.text; }
    const test::CommandResult r = run("snow " + q(scene) + " -o " + q(dir / "out.glb") +
                                      " --weather " + q(dir / "bad.csv") + kFast);
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("error: "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(c.expected), std::string::npos) << c.expected << "\n" << r.output;
    EXPECT_EQ(r.output.find("peel"), std::string::npos) << "refused after the work started";
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(dir / "out.glb"));
  }
  const test::CommandResult both = run("snow " + q(scene) + " -o " + q(dir / "out.glb") +
                                       " --depth 0.2 --weather " + q(dir / "bad.csv"));
  EXPECT_EQ(both.code, 2);
  EXPECT_NE(both.output.find("--depth and --weather"), std::string::npos) << both.output;
  // The live preview reads the file the same way.
  const test::CommandResult preview =
      run("preview " + q(scene) + " --headless --frames 1 --weather " + q(dir / "bad.csv"));
  EXPECT_EQ(preview.code, 2);
  EXPECT_NE(preview.output.find(cases[4].expected), std::string::npos) << preview.output;
  EXPECT_EQ(std::count(preview.output.begin(), preview.output.end(), '\n'), 1) << preview.output;
  const test::CommandResult rate =
      run("preview " + q(scene) + " --headless --frames 1 --fall-rate 0.1 --weather " +
          q(save_weather(dir / "good.csv", 0, 4)));
  EXPECT_EQ(rate.code, 2);
  EXPECT_NE(rate.output.find("--fall-rate and --weather"), std::string::npos) << rate.output;
  fs::remove_all(dir);
}

// The live preview plays the first 16 hours headless (an hour a frame) and
// writes its maps: the same water fell as in the batch job's run of those
// hours, the manifest holds the hours played, and the batch job resumes
// from the preview's maps.
TEST(WeatherCli, ThePreviewPlaysAWeatherFileAndTheBatchJobResumesFromIt) {
  const fs::path dir = temp_dir("preview");
  const fs::path scene = save_yard(dir);
  const std::string sun = " --start 2026-03-10T00:00 --latitude 47 --longitude 8" + kFast;
  const fs::path first = save_weather(dir / "first.csv", 0, 16);
  const test::CommandResult preview =
      run("preview " + q(scene) + " --headless --frames 20 --frame-time 0.5 --weather-speed 2 " +
          "--size 64x48 --maps " + q(dir / "live") + " --weather " + q(first) + sun);
  ASSERT_EQ(preview.code, 0) << preview.output;
  EXPECT_NE(preview.output.find("preview: weather hour 16;"), std::string::npos) << preview.output;
  ASSERT_EQ(
      run("snow " + q(scene) + " --maps " + q(dir / "batch") + " --weather " + q(first) + sun).code,
      0);
  const nlohmann::json live = manifest(dir / "live")["snowpack"],
                       batch = manifest(dir / "batch")["snowpack"];
  EXPECT_DOUBLE_EQ(live["hour"].get<double>(), 16.0);
  EXPECT_NEAR(live["fallen"].get<double>(), batch["fallen"].get<double>(),
              1e-6 * batch["fallen"].get<double>());
  EXPECT_NEAR(map_sum(dir / "live", "swe"), map_sum(dir / "batch", "swe"),
              0.03 * map_sum(dir / "batch", "swe"));
  const test::CommandResult resumed =
      run("snow " + q(scene) + " -o " + q(dir / "out.glb") + " --resume " + q(dir / "live") +
          " --weather " + q(save_weather(dir / "second.csv", 16, 24)) + sun);
  EXPECT_EQ(resumed.code, 0) << resumed.output;
  fs::remove_all(dir);
}

TEST(WeatherCli, SequencesWriteAFrameEveryHours) {
  const fs::path dir = temp_dir("sequence");
  const fs::path scene = save_yard(dir);
  const test::CommandResult r =
      run("snow " + q(scene) + " -o " + q(dir / "out.glb") + " --weather " +
          q(save_weather(dir / "w.csv", 0, 16)) + " --sequence " + q(dir / "seq") +
          " --every 6 --sequence-maps" + kFast);
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* frame : {"0001", "0002", "0003"}) {
    EXPECT_GT(fs::file_size(dir / "seq" / (std::string("snow_") + frame + ".glb")), 1000u) << frame;
    EXPECT_TRUE(manifest(dir / "seq" / (std::string("maps_") + frame))["snowpack"].is_object());
  }
  EXPECT_FALSE(fs::exists(dir / "seq" / "snow_0004.glb"));
  // Frame 2 (hour 12, the storm over) holds more water than frame 3 (hour
  // 16, after four hours of thaw).
  EXPECT_GT(map_sum(dir / "seq" / "maps_0002", "swe"), map_sum(dir / "seq" / "maps_0003", "swe"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace snow
