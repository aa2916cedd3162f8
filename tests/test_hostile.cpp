// Hostile input and failure tests of the snowmodel executable (issue #9):
// scenes that must be refused or handled with a warning, GL failures
// (injected with SNOWMODEL_FAULT) that must exit 3, and runs killed at
// arbitrary moments that must never leave a partial file under the target
// name. The loader's own hostile-file table is in test_scene_load.cpp
// (counts, cycles, deep hierarchies, non-finite values, URIs outside the
// folder); here the same kinds of files go through the whole CLI, which must
// answer each with exit code 2, one error line and no file written.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "mesh/gltf_writer.h"
#include "scene/load_gltf.h"
#include "support/command.h"
#include "support/files.h"

extern char** environ;

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

const fs::path kCourtyard = fs::path(SNOW_SOURCE_DIR) / "assets/scenes/courtyard.glb";
// Tiny maps: every run is a second or two on llvmpipe (also under ASan).
const std::string kTiny = " --max-side 24 --directions 4 --layers 2";

using RunResult = snow::test::CommandResult;
using snow::test::temporaries;

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

/// Runs snowmodel with `args`; `env` is prepended to the shell command ("A=b").
RunResult run(const std::string& args, const std::string& env = "") {
  return snow::test::run_command(env + " " + std::string(SNOWMODEL_EXE) + " " + args);
}

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("snow_hostile_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

size_t file_count(const fs::path& dir) {
  return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

size_t count_lines_with(const std::string& text, const std::string& needle) {
  size_t count = 0;
  for (size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1))
    ++count;
  return count;
}

/// An axis-aligned quad (two triangles) with corners a, b, c, d in order.
snow::TriMesh quad(const std::string& name, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
  snow::TriMesh m;
  m.name = name;
  m.positions = {a, b, c, d};
  m.indices = {0, 1, 2, 0, 2, 3};
  return m;
}

/// Horizontal quad at height y over [x0,x1] x [z0,z1], facing up (or down).
snow::TriMesh flat(const std::string& name, float y, float x0, float x1, float z0, float z1,
                   bool up = true) {
  if (up) return quad(name, {x0, y, z0}, {x0, y, z1}, {x1, y, z1}, {x1, y, z0});
  return quad(name, {x0, y, z0}, {x1, y, z0}, {x1, y, z1}, {x0, y, z1});
}

fs::path write_glb(const fs::path& path, const std::vector<snow::TriMesh>& meshes) {
  tinygltf::Model model;
  snow::append_meshes(model, meshes, {snow::MeshMaterial{}}, "Scene");
  snow::save_gltf(model, path);
  return path;
}

/// A one-triangle .gltf with a data-URI buffer; `edit` changes the document.
template <typename Edit>
fs::path write_triangle_gltf(const fs::path& path, Edit&& edit) {
  json doc = json::parse(R"({
    "asset": {"version": "2.0"},
    "buffers": [{"byteLength": 36, "uri":
      "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAAAAAAAAAAAAAIA/AACAPwAAAAAAAAAA"}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
    "meshes": [{"name": "Tri", "primitives": [{"attributes": {"POSITION": 0}}]}],
    "nodes": [{"name": "N", "mesh": 0}],
    "scenes": [{"nodes": [0]}], "scene": 0})");
  edit(doc);
  std::ofstream(path, std::ios::binary) << doc.dump();
  return path;
}

/// Expects a failed run: `code`, exactly one "error:" line naming `needle`,
/// and nothing written into `out`.
void expect_refused(const RunResult& r, int code, const std::string& needle, const fs::path& out,
                    const std::string& what) {
  EXPECT_EQ(r.code, code) << what << ": " << r.output;
  EXPECT_EQ(count_lines_with(r.output, "error:"), 1u) << what << ": " << r.output;
  EXPECT_NE(r.output.find(needle), std::string::npos) << what << ": " << r.output;
  // A sanitizer's report ("ERROR: AddressSanitizer: ..."; `info` names the
  // allocator in its heap line, which is no report).
  EXPECT_EQ(r.output.find("ERROR: AddressSanitizer"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("runtime error:"), std::string::npos) << r.output;
  EXPECT_EQ(file_count(out), 0u) << what << " left files behind";
}

class Hostile : public ::testing::Test {
 protected:
  void SetUp() override {
    snow::set_log_level(snow::LogLevel::Quiet);
    dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    out_ = dir_ / "out";
    fs::create_directories(out_);
  }
  void TearDown() override {
    snow::set_log_level(snow::LogLevel::Info);
    fs::remove_all(dir_);
  }
  fs::path dir_, out_;
};

// --- hostile scenes through the CLI ---------------------------------------------------------

TEST_F(Hostile, HundredKilometreSceneWithMillimetreTexelStopsAtTheMemoryGuard) {
  // 100 km x 100 km ground with a house-sized box on it, 1 mm texels: 1e16
  // texels. The guard must refuse before allocating, naming the budget.
  const fs::path scene = write_glb(dir_ / "huge.glb", {flat("Ground", 0, -5e4f, 5e4f, -5e4f, 5e4f),
                                                       flat("Roof", 3, 0, 10, 0, 10)});
  const RunResult r = run("snow " + q(scene) + " --texel 0.001 -o " + q(out_ / "x.glb"));
  expect_refused(r, 2, "budget", out_, "100 km at 1 mm");
  EXPECT_NE(r.output.find("--texel"), std::string::npos) << "suggests a coarser texel";
  // The same scene at an automatic texel is fine.
  const RunResult ok = run("snow " + q(scene) + kTiny + " -o " + q(out_ / "ok.glb"));
  EXPECT_EQ(ok.code, 0) << ok.output;
}

TEST_F(Hostile, AllVerticalTrianglesGiveAValidEmptyResultAndAWarning) {
  // Walls only: nothing faces up, nothing can hold snow.
  const fs::path scene =
      write_glb(dir_ / "walls.glb", {quad("WallX", {0, 0, 0}, {4, 0, 0}, {4, 3, 0}, {0, 3, 0}),
                                     quad("WallZ", {0, 0, 1}, {0, 3, 1}, {0, 3, 5}, {0, 0, 5}),
                                     quad("WallD", {1, 0, 1}, {3, 0, 3}, {3, 3, 3}, {1, 3, 1})});
  const RunResult r = run("snow " + q(scene) + kTiny + " -o " + q(out_ / "walls_snow.glb") +
                          " --snow-output " + q(out_ / "snow.obj"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("warning:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("nothing in the scene holds snow"), std::string::npos) << r.output;
  // The combined output is the input scene again, readable and with the same triangles.
  const snow::Scene back = snow::load_scene(out_ / "walls_snow.glb");
  EXPECT_EQ(back.triangle_count(), 6u);
  ASSERT_TRUE(fs::exists(out_ / "snow.obj"));
}

// "Everything under one roof" (a sky box or dome enclosing the scene takes
// all the snow: warning naming it) is Cli.WarnsWhenASkyBoxTakesTheSnow in
// test_cli.cpp.

TEST_F(Hostile, BrokenAndHostileFilesExitTwoWithOneLine) {
  struct Case {
    std::string name;
    fs::path input;
    std::string needle;
  };
  std::vector<Case> cases;
  cases.push_back({"billion count",
                   write_triangle_gltf(dir_ / "count.gltf",
                                       [](json& d) { d["accessors"][0]["count"] = 1000000000; }),
                   "accessor 0"});
  cases.push_back({"billion nodes declared",
                   write_triangle_gltf(dir_ / "nodes.gltf",
                                       [](json& d) {
                                         d["scenes"][0]["nodes"] = {0, 999999999};
                                       }),
                   "node"});
  cases.push_back({"cycle",
                   write_triangle_gltf(dir_ / "cycle.gltf",
                                       [](json& d) {
                                         d["nodes"][0]["children"] = {1};
                                         d["nodes"][1] = {{"children", {0}}};
                                       }),
                   "cycle"});
  cases.push_back({"non-finite transform",
                   write_triangle_gltf(dir_ / "scale.gltf",
                                       [](json& d) {
                                         d["nodes"][0]["scale"] = {1e39, 1, 1};
                                       }),
                   "not finite"});
  cases.push_back({"overflowing matrix",
                   write_triangle_gltf(dir_ / "matrix.gltf",
                                       [](json& d) {
                                         d["nodes"][0]["matrix"] = {1e300, 0, 0, 0, 0, 1, 0, 0,
                                                                    0,     0, 1, 0, 0, 0, 0, 1};
                                       }),
                   "not finite"});
  cases.push_back({"zero area",
                   write_triangle_gltf(dir_ / "zero.gltf",
                                       [](json& d) {
                                         d["nodes"][0]["scale"] = {0, 0, 0};
                                       }),
                   "degenerate"});
  cases.push_back({"URI outside the folder",
                   write_triangle_gltf(dir_ / "escape.gltf",
                                       [](json& d) { d["buffers"][0]["uri"] = "../escape.bin"; }),
                   "refused"});
  cases.push_back({"absolute URI",
                   write_triangle_gltf(dir_ / "absolute.gltf",
                                       [](json& d) { d["buffers"][0]["uri"] = "/etc/passwd"; }),
                   "refused"});
  for (const Case& c : cases) {
    const RunResult r = run("snow " + q(c.input) + kTiny + " -o " + q(out_ / "x.glb") +
                            " --preview " + q(out_ / "x.png"));
    expect_refused(r, 2, c.needle, out_, c.name);
    fs::remove_all(out_);
    fs::create_directories(out_);
  }
}

TEST_F(Hostile, HundredThousandDeepHierarchyRuns) {
  // 100,000 nested nodes (each translating by 1 mm) over one triangle: the
  // loader walks them iteratively; the whole run must succeed.
  const fs::path scene = write_triangle_gltf(dir_ / "deep.gltf", [](json& d) {
    json nodes = json::array();
    const int depth = 100000;
    for (int i = 0; i < depth; ++i) {
      json n = {{"translation", {0, 0.00001, 0}}};
      if (i + 1 < depth) n["children"] = {i + 1};
      if (i + 1 == depth) n["mesh"] = 0;
      nodes.push_back(n);
    }
    d["nodes"] = nodes;
  });
  const RunResult r = run("snow " + q(scene) + kTiny + " --snow-only -o " + q(out_ / "deep.obj"));
  EXPECT_EQ(r.code, 0) << r.output.substr(0, 2000);
  EXPECT_TRUE(fs::exists(out_ / "deep.obj"));
}

// --- the input policy (scene/input_policy.h) through every command ------------------------

TEST_F(Hostile, DeeplyNestedJsonExitsTwoThroughTheCombinedWriter) {
  // 30,000 levels in `extras`: tinygltf's recursive parser, which the
  // combined writer used to read the input again, ran out of stack.
  const fs::path scene = write_triangle_gltf(dir_ / "deep.gltf", [](json&) {});
  std::string text;
  {
    std::ifstream in(scene);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  text.insert(text.rfind('}'), ",\"extras\":" + std::string(30000, '[') + std::string(30000, ']'));
  std::ofstream(scene) << text;
  for (const std::string& command :
       {"snow " + q(scene) + kTiny + " -o " + q(out_ / "x.glb"),
        "snow " + q(scene) + kTiny + " -o " + q(out_ / "x.gltf"), "info " + q(scene)}) {
    expect_refused(run(command), 2, "JSON nested deeper than 512 levels", out_, command);
  }
}

// The input's JSON is parsed once, by the loader, for every output: JSON
// nested 100,000 levels deep or broken gives one error line and exit 2
// whether the scene plus snow goes to a .glb or a .gltf.
TEST_F(Hostile, DeepOrBrokenJsonIsOneErrorForEveryCombinedOutput) {
  const fs::path deep = write_triangle_gltf(dir_ / "deep.gltf", [](json&) {});
  std::string text;
  {
    std::ifstream in(deep);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const std::string broken_text = text.substr(0, text.size() / 2);
  text.insert(text.rfind('}'),
              ",\"extras\":" + std::string(100000, '[') + std::string(100000, ']'));
  std::ofstream(deep) << text;
  std::ofstream(dir_ / "broken.gltf") << broken_text;
  for (const char* out : {"x.glb", "x.gltf"}) {
    const std::string to = kTiny + " -o " + q(out_ / out);
    expect_refused(run("snow " + q(deep) + to), 2, "JSON nested deeper than 512 levels", out_,
                   std::string("deep to ") + out);
    expect_refused(run("snow " + q(dir_ / "broken.gltf") + to), 2, "broken JSON", out_,
                   std::string("broken to ") + out);
  }
}

TEST_F(Hostile, FilesOutsideTheSceneFolderAreNeverRead) {
  // The secret lies beside the scene's folder; the scene names it in every
  // way that leads out of the folder.
  const fs::path folder = dir_ / "scene";
  fs::create_directories(folder);
  std::ofstream(dir_ / "secret.png", std::ios::binary) << "\x89PNG\r\n\x1a\nSECRET";
  fs::create_symlink(dir_ / "secret.png", folder / "link.png");
  fs::create_symlink(dir_ / "secret.png", folder / "link.bin");
  const std::vector<std::string> image_uris = {"../secret.png", "%2e%2e/secret.png",
                                               (dir_ / "secret.png").string(), "link.png"};
  std::vector<fs::path> scenes;
  for (size_t i = 0; i < image_uris.size(); ++i) {
    scenes.push_back(
        write_triangle_gltf(folder / ("image" + std::to_string(i) + ".gltf"), [&](json& d) {
          d["images"] = {{{"uri", image_uris[i]}}};
          d["textures"] = {{{"source", 0}}};
          d["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
          d["meshes"][0]["primitives"][0]["material"] = 0;
        }));
  }
  scenes.push_back(write_triangle_gltf(folder / "buffer_link.gltf",
                                       [](json& d) { d["buffers"][0]["uri"] = "link.bin"; }));
  for (const fs::path& scene : scenes) {
    for (const char* target : {"x.glb", "x.gltf"}) {
      const RunResult r = run("snow " + q(scene) + kTiny + " -o " + q(out_ / target));
      expect_refused(r, 2, "refused", out_, scene.filename().string() + " to " + target);
      fs::remove_all(out_);
      fs::create_directories(out_);
    }
  }
}

TEST_F(Hostile, FifosAreRefusedNotWaitedOn) {
  ASSERT_EQ(mkfifo((dir_ / "pipe.gltf").c_str(), 0600), 0);
  ASSERT_EQ(mkfifo((dir_ / "pipe.bin").c_str(), 0600), 0);
  const fs::path buffer_pipe = write_triangle_gltf(
      dir_ / "buffer_pipe.gltf", [](json& d) { d["buffers"][0]["uri"] = "pipe.bin"; });
  // `timeout` ends a run that waits (exit 124) instead of the test.
  const std::string exe = "timeout 60 " + std::string(SNOWMODEL_EXE) + " ";
  for (const fs::path& scene : {dir_ / "pipe.gltf", buffer_pipe}) {
    for (const std::string& args :
         {"snow " + q(scene) + kTiny + " -o " + q(out_ / "x.glb"), "info " + q(scene),
          "render " + q(scene) + " -o " + q(out_ / "x.png")}) {
      const RunResult r = snow::test::run_command(exe + args);
      expect_refused(r, 2, "regular file", out_, args);
    }
  }
}

TEST_F(Hostile, DecodedImagesOverTheMemoryBudgetExitTwo) {
  // Three images of 1024 x 1024 pixels (PPM: stb decodes it without a
  // compressor here), 4 MiB each decoded; the preview decodes them.
  const fs::path scene = write_triangle_gltf(dir_ / "images.gltf", [&](json& d) {
    d["meshes"][0]["primitives"] = json::array();
    for (int i = 0; i < 3; ++i) {
      const std::string name = "image" + std::to_string(i) + ".ppm";
      std::ofstream(dir_ / name, std::ios::binary) << "P6\n1024 1024\n255\n"
                                                   << std::string(1024 * 1024 * 3, '\x80');
      d["images"].push_back({{"uri", name}});
      d["textures"].push_back({{"source", i}});
      d["materials"].push_back({{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", i}}}}}});
      d["meshes"][0]["primitives"].push_back({{"attributes", {{"POSITION", 0}}}, {"material", i}});
    }
  });
  // 0.01 GiB (10.2 MiB, the smallest budget allowed): the first image
  // fits while it is decoded (its 3 MiB file and 4 MiB of pixels), the
  // second does not.
  const RunResult r = run("snow " + q(scene) + kTiny + " --memory-budget 0.01 --preview " +
                          q(out_ / "x.png") + " -o " + q(out_ / "x.glb"));
  expect_refused(r, 2, "--memory-budget", out_, "three images");
  EXPECT_NE(r.output.find("image 1"), std::string::npos) << r.output;
  // render and info decode the images too, under their own --memory-budget.
  for (const std::string& command :
       {"render " + q(scene) + " -o " + q(out_ / "x.png"), "info --no-gl " + q(scene)}) {
    const RunResult small = run(command + " --memory-budget 0.01");
    expect_refused(small, 2, "--memory-budget", out_, command);
    EXPECT_NE(small.output.find("image"), std::string::npos) << small.output;
    EXPECT_EQ(run(command + " --memory-budget 0.005").code, 2) << command;  // out of range
  }
  const RunResult fits = run("render " + q(scene) + " -o " + q(out_ / "x.png"));
  EXPECT_EQ(fits.code, 0) << fits.output;  // the default budget holds them
}

// --- GL failures ------------------------------------------------------------------------------

// A texCoord of 2^31 (issue 48): the scene plus snow never writes it
// wrapped to -2^31. The input's JSON is copied as written, whether its
// buffer is a data URI or a .bin beside it: the value is kept.
TEST_F(Hostile, TexCoordBeyondIntIsKeptNeverWrapped) {
  auto wide = [](json& doc) {
    doc["textures"] = json::array({json::object()});
    doc["materials"] = {{{"pbrMetallicRoughness",
                          {{"baseColorTexture", {{"index", 0}, {"texCoord", 2147483648u}}}}}}};
    doc["meshes"][0]["primitives"][0]["material"] = 0;
  };
  const fs::path data = write_triangle_gltf(dir_ / "data.gltf", wide);
  const RunResult from_data = run("snow " + q(data) + kTiny + " -o " + q(out_ / "x.gltf"));
  ASSERT_EQ(from_data.code, 0) << from_data.output;
  EXPECT_EQ(
      json::parse(std::ifstream(
          out_ / "x.gltf"))["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"],
      2147483648u);
  // The same document with its buffer in a .bin file.
  json doc = json::parse(std::ifstream(data));
  const std::string uri = doc["buffers"][0]["uri"];
  const std::string base64 = uri.substr(uri.find(',') + 1);
  ASSERT_EQ(base64, "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAIA/AACAPwAAAAAAAAAA");
  const float xyz[9] = {0, 0, 0, 0, 0, 1, 1, 0, 0};  // what the base64 holds
  std::ofstream(dir_ / "tri.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(xyz), sizeof xyz);
  doc["buffers"][0]["uri"] = "tri.bin";
  std::ofstream(dir_ / "bin.gltf") << doc.dump();
  const RunResult kept = run("snow " + q(dir_ / "bin.gltf") + kTiny + " -o " + q(out_ / "y.glb"));
  ASSERT_EQ(kept.code, 0) << kept.output;
  std::ifstream glb(out_ / "y.glb", std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(glb)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 20u);
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  const json out = json::parse(std::string(bytes.data() + 20, length));
  EXPECT_EQ(out["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"],
            2147483648u);
}

TEST_F(Hostile, GlAllocationFailureAndContextLossExitThree) {
  struct Case {
    std::string fault;
    std::string needle;
  };
  // The first GL check (the peel's first allocation), the first in
  // coverage and the first in the stabilizer (on the GPU: on llvmpipe both
  // would run on the CPU).
  for (const Case& c :
       {Case{"gl-alloc", "out of GPU memory"}, Case{"gl-alloc:coverage", "out of GPU memory"},
        Case{"gl-alloc:stabilize", "out of GPU memory"}, Case{"context-loss", "context lost"},
        Case{"context-loss:coverage", "context lost"},
        Case{"context-loss:stabilize", "context lost"}}) {
    const RunResult r = run("snow " + q(kCourtyard) + kTiny +
                                " --stabilizer gpu --coverage-method shadow-maps -o " +
                                q(out_ / "x.glb") + " --preview " + q(out_ / "x.png"),
                            "SNOWMODEL_FAULT=" + c.fault);
    expect_refused(r, 3, c.needle, out_, c.fault);
  }
  // The preview renderer's allocations too.
  const RunResult render =
      run("render " + q(kCourtyard) + " -o " + q(out_ / "r.png"), "SNOWMODEL_FAULT=gl-alloc");
  expect_refused(render, 3, "out of GPU memory", out_, "render");
}

// --- killed runs ------------------------------------------------------------------------------

/// Starts snowmodel with `args` (no shell), returns its pid.
pid_t spawn(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  std::string exe = SNOWMODEL_EXE;
  argv.push_back(exe.data());
  std::vector<std::string> copy = args;
  for (std::string& a : copy) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  if (posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

TEST_F(Hostile, KilledRunsNeverLeaveAPartialOutput) {
  const std::vector<std::string> args = {"snow",
                                         kCourtyard.string(),
                                         "--max-side",
                                         "48",
                                         "--directions",
                                         "8",
                                         "--layers",
                                         "4",
                                         "-o",
                                         (out_ / "x.glb").string(),
                                         "--maps",
                                         (out_ / "maps").string(),
                                         "--snow-output",
                                         (out_ / "s.obj").string()};
  // One full run to learn how long it takes here.
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  const pid_t full = spawn(args);
  ASSERT_GT(full, 0);
  int status = 0;
  waitpid(full, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  const double seconds = std::chrono::duration<double>(clock::now() - start).count();
  const snow::Scene complete = snow::load_scene(out_ / "x.glb");
  fs::remove_all(out_);
  fs::create_directories(out_);

  // Kill at moments spread over the run, more of them near the end (export).
  int complete_outputs = 0, absent_outputs = 0;
  const std::vector<double> fractions = {0.05, 0.2,  0.4,  0.6,  0.75, 0.85, 0.9,
                                         0.93, 0.96, 0.98, 0.99, 1.0,  1.02};
  const std::array<int, 3> signals = {SIGKILL, SIGTERM, SIGINT};
  for (size_t k = 0; k < fractions.size(); ++k) {
    const int sig = signals[k % signals.size()];
    const pid_t pid = spawn(args);
    ASSERT_GT(pid, 0);
    std::this_thread::sleep_for(std::chrono::duration<double>(fractions[k] * seconds));
    kill(pid, sig);
    waitpid(pid, &status, 0);
    const std::string moment = "signal " + std::to_string(sig) + " at " +
                               std::to_string(fractions[k]) + " of " + std::to_string(seconds) +
                               " s";
    // Each target is absent or complete.
    if (fs::exists(out_ / "x.glb")) {
      ++complete_outputs;
      snow::Scene back;
      ASSERT_NO_THROW(back = snow::load_scene(out_ / "x.glb")) << moment;
      EXPECT_EQ(back.triangle_count(), complete.triangle_count()) << moment;
    } else {
      ++absent_outputs;
    }
    if (fs::exists(out_ / "x.glb.settings.json")) {
      std::ifstream in(out_ / "x.glb.settings.json");
      EXPECT_FALSE(json::parse(in, nullptr, false).is_discarded()) << moment;
    }
    if (fs::exists(out_ / "maps" / "manifest.json")) {
      std::ifstream in(out_ / "maps" / "manifest.json");
      EXPECT_FALSE(json::parse(in, nullptr, false).is_discarded()) << moment;
    }
    if (fs::exists(out_ / "s.obj")) {
      std::ifstream in(out_ / "s.obj");
      const std::string text{std::istreambuf_iterator<char>(in), {}};
      EXPECT_FALSE(text.empty()) << moment;
      EXPECT_EQ(text.back(), '\n') << moment << ": OBJ cut short";
    }
    // A caught signal removes the temporary files; SIGKILL may leave them,
    // never under a target name.
    if (sig != SIGKILL) {
      EXPECT_TRUE(temporaries(out_).empty()) << moment;
    }
    fs::remove_all(out_);
    fs::create_directories(out_);
  }
  EXPECT_GT(absent_outputs, 0) << "no kill landed before the export";
  std::printf("killed %zu runs of %.2f s: %d left a complete x.glb, %d none\n", fractions.size(),
              seconds, complete_outputs, absent_outputs);
}

}  // namespace
