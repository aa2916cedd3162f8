// End-to-end tests of the snowmodel executable: exit codes, outputs,
// determinism, filters, settings files, and the bad-input table.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <string>

#include <tiny_gltf.h>

#include "core/heap.h"
#include "gl/context.h"
#include "mesh/gltf_writer.h"
#include "scene/builder.h"
#include "scene/frame.h"
#include "support/command.h"
#include "support/enclosures.h"
#include "support/files.h"

namespace fs = std::filesystem;

namespace {

const fs::path kCourtyard = fs::path(SNOW_SOURCE_DIR) / "assets/scenes/courtyard.glb";
// Small maps and few directions keep each run to seconds on llvmpipe.
const std::string kFast = " --max-side 96 --directions 16 --layers 6";

using RunResult = snow::test::CommandResult;
using snow::test::read_all;
using snow::test::write_all;

RunResult run(const std::string& args) {
  return snow::test::run_command(std::string(SNOWMODEL_EXE) + " " + args);
}

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("snow_cli_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

size_t file_count(const fs::path& dir) {
  return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

/// Runs the Khronos glTF validator (tools/validator) on `file`; fails the
/// test on any error. tools/test installs the validator.
void expect_valid_gltf(const fs::path& file) {
  const fs::path dir = fs::path(SNOW_SOURCE_DIR) / "tools" / "validator";
  ASSERT_TRUE(fs::exists(dir / "node_modules" / "gltf-validator"))
      << "run `npm ci` in tools/validator (tools/test does)";
  const std::string command = "node " + q(dir / "validate.mjs") + " " + q(file) + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  std::array<char, 1024> buffer{};
  size_t n = 0;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) output.append(buffer.data(), n);
  EXPECT_EQ(pclose(pipe), 0) << output;
}

// A one-triangle glTF whose buffer is a data URI, with `positions` as the
// three vertices' floats (as JSON-free raw bytes in base64 is overkill: use
// an external .bin written next to it).
fs::path write_triangle_gltf(const fs::path& dir, const std::string& name, const float (&xyz)[9],
                             bool write_bin = true) {
  if (write_bin) {
    write_all(dir / (name + ".bin"), std::string(reinterpret_cast<const char*>(xyz), sizeof xyz));
  }
  const std::string json = R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
    "nodes":[{"mesh":0,"name":"Tri"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
    "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
    "bufferViews":[{"buffer":0,"byteLength":36}],
    "buffers":[{"uri":")" + name +
                           R"(.bin","byteLength":36}]})";
  const fs::path path = dir / (name + ".gltf");
  write_all(path, json);
  return path;
}

}  // namespace

TEST(Cli, InfoPrintsSceneSummary) {
  const RunResult r = run("info " + q(kCourtyard));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("OpenGL:"), std::string::npos);
  EXPECT_NE(r.output.find("triangles: 956"), std::string::npos) << r.output;
  // Where the stabilizer runs by default: the batch job's on the CPU, the
  // preview's on llvmpipe too.
  const bool software = r.output.find("llvmpipe") != std::string::npos;
  EXPECT_NE(r.output.find(software ? "plan: stabilizer: CPU passes (the preview: CPU passes)"
                                   : "plan: stabilizer: CPU passes (the preview: GPU passes)"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(software ? "plan: peel: a vertical ray per texel on the CPU, unless"
                                   : "plan: peel: a vertical ray per texel on the CPU for a small"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("plan: maps of 1024 texels on the longer side"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(software ? "shadow maps or rays on the CPU cores, or GL's shadow maps"
                                   : "rays on the GPU where they cost less"),
            std::string::npos)
      << r.output;
}

// The developer knobs (backends, speed-ups) stay out of --help; --help-all
// lists them, and they work either way.
TEST(Cli, HelpHidesDeveloperOptionsAndHelpAllListsThem) {
  for (const char* command : {"snow", "preview"}) {
    const RunResult help = run(std::string(command) + " --help");
    ASSERT_EQ(help.code, 0) << help.output;
    EXPECT_NE(help.output.find("--depth"), std::string::npos) << help.output;
    EXPECT_NE(help.output.find("--help-all"), std::string::npos) << help.output;
    const RunResult all = run(std::string(command) + " --help-all");
    ASSERT_EQ(all.code, 0) << all.output;
    for (const char* flag : {"--peel-device", "--coverage-method", "--stabilizer", "--route-steep",
                             "--drain-edges", "--deposit-piles", "--adaptive-stride"}) {
      EXPECT_EQ(help.output.find(flag), std::string::npos) << command << " --help: " << flag;
      EXPECT_NE(all.output.find(flag), std::string::npos) << command << " --help-all: " << flag;
    }
  }
  const fs::path dir = temp_dir("developer");
  const RunResult hidden = run("snow " + q(kCourtyard) +
                               " --max-side 32 --directions 4 --stabilizer cpu --route-steep false"
                               " --snow-output " +
                               q((dir / "snow.obj").string()));
  EXPECT_EQ(hidden.code, 0) << hidden.output;
  EXPECT_TRUE(fs::exists(dir / "snow.obj"));
  fs::remove_all(dir);
}

TEST(Cli, InfoSaysWhetherTheHeapHasHugePages) {
  // snowmodel re-executes itself with glibc.malloc.hugetlb=1 added to
  // GLIBC_TUNABLES (core/heap.h), unless the user named that tunable.
  const auto info = [](const std::string& env) {
    return snow::test::run_command(env + " " + std::string(SNOWMODEL_EXE) + " info --no-gl");
  };
  const RunResult unset = info("env -u GLIBC_TUNABLES");
  ASSERT_EQ(unset.code, 0) << unset.output;
  if (unset.output.find("this glibc has no") != std::string::npos) GTEST_SKIP() << unset.output;
  EXPECT_NE(unset.output.find("Huge pages for the heap: "), std::string::npos) << unset.output;
  EXPECT_NE(unset.output.find("GLIBC_TUNABLES glibc.malloc.hugetlb=1)"), std::string::npos)
      << unset.output;
  // The mmap threshold is set (AddressSanitizer's allocator has none).
  const auto threshold_set = [](const std::string& output) {
    return output.find("mmap threshold: 32 MiB") != std::string::npos ||
           output.find("mmap threshold: the allocator's own (AddressSanitizer's)") !=
               std::string::npos;
  };
  EXPECT_TRUE(threshold_set(unset.output)) << unset.output;
  // Other tunables are kept, and the hugetlb one added.
  const RunResult other = info("GLIBC_TUNABLES=glibc.malloc.check=0");
  ASSERT_EQ(other.code, 0) << other.output;
  EXPECT_NE(other.output.find("GLIBC_TUNABLES glibc.malloc.hugetlb=1)"), std::string::npos)
      << other.output;
  // At most one re-execution: the marker it sets stops another.
  const RunResult once = info("env -u GLIBC_TUNABLES SNOWMODEL_HUGE_PAGES_REEXEC=1");
  ASSERT_EQ(once.code, 0) << once.output;
  EXPECT_NE(once.output.find("GLIBC_TUNABLES glibc.malloc.hugetlb=unset)"), std::string::npos)
      << once.output;
  // The user's own choice wins.
  const RunResult off = info("GLIBC_TUNABLES=glibc.malloc.hugetlb=0");
  ASSERT_EQ(off.code, 0) << off.output;
  EXPECT_NE(off.output.find("Huge pages for the heap: off (GLIBC_TUNABLES glibc.malloc.hugetlb=0)"),
            std::string::npos)
      << off.output;
  EXPECT_TRUE(threshold_set(off.output)) << off.output;
  const RunResult threshold = info("GLIBC_TUNABLES=glibc.malloc.mmap_threshold=65536");
  ASSERT_EQ(threshold.code, 0) << threshold.output;
  EXPECT_NE(threshold.output.find(
                "mmap threshold: as set (GLIBC_TUNABLES glibc.malloc.mmap_threshold=65536)"),
            std::string::npos)
      << threshold.output;
}

// snowmodel is a launcher (src/app/launcher.c) that starts snowmodel-core,
// beside it, with the huge-page tunable set (the test above runs through
// it); the core also runs on its own, and a launcher without its core says
// what is missing.
TEST(Cli, LauncherStartsTheCoreBesideIt) {
  const RunResult core = snow::test::run_command("env -u GLIBC_TUNABLES " +
                                                 std::string(SNOWMODEL_CORE_EXE) + " info --no-gl");
  ASSERT_EQ(core.code, 0) << core.output;
  if (core.output.find("this glibc has no") == std::string::npos) {
    EXPECT_NE(core.output.find("GLIBC_TUNABLES glibc.malloc.hugetlb=1)"), std::string::npos)
        << core.output;  // it re-executed itself
  }
  const fs::path dir = temp_dir("launcher");
  fs::copy_file(SNOWMODEL_EXE, dir / "snowmodel");
  const RunResult alone = snow::test::run_command(q(dir / "snowmodel") + " --version");
  EXPECT_EQ(alone.code, 1) << alone.output;
  EXPECT_NE(alone.output.find("cannot run " + (dir / "snowmodel-core").string()), std::string::npos)
      << alone.output;
  EXPECT_NE(alone.output.find("snowmodel is not installed whole"), std::string::npos)
      << alone.output;
  fs::remove_all(dir);
}

// A large job (maps of 512 x 512 texels or more, or 32 MiB of input or
// more) turns the heap's huge pages off where the machine hands free memory
// back to its host (core/heap.h fit_huge_pages); a small job, or huge
// pages the user asked for, keep them.
TEST(Cli, LargeJobsFitTheHeapsHugePagesToTheMachine) {
  const RunResult info = snow::test::run_command("env -u GLIBC_TUNABLES " +
                                                 std::string(SNOWMODEL_EXE) + " info --no-gl");
  ASSERT_EQ(info.code, 0) << info.output;
  if (info.output.find("Huge pages for the heap: on") == std::string::npos)
    GTEST_SKIP() << info.output;
  const bool reported = snow::free_pages_reported();
  EXPECT_EQ(info.output.find("jobs of 512 x 512 texels or 32 MiB of input or more turn them off") !=
                std::string::npos,
            reported)
      << info.output;
  const fs::path dir = temp_dir("huge_pages");
  const std::string line = "heap: transparent huge pages off from here on";
  const auto job = [&](const std::string& env, int side, const fs::path& scene = kCourtyard) {
    const RunResult r =
        snow::test::run_command(env + " " + std::string(SNOWMODEL_EXE) + " -v snow " + q(scene) +
                                " --depth 0.05 --directions 16 --layers 4 --max-side " +
                                std::to_string(side) + " -o " + q(dir / "out.glb"));
    EXPECT_EQ(r.code, 0) << r.output;
    return r.output.find(line) != std::string::npos;
  };
  EXPECT_EQ(job("env -u GLIBC_TUNABLES", 512), reported);
  EXPECT_FALSE(job("env -u GLIBC_TUNABLES", 256));
  EXPECT_FALSE(job("GLIBC_TUNABLES=glibc.malloc.hugetlb=1", 512));  // the user's choice
  // A triangle whose .bin holds 32 MiB (a hole but for its 36 bytes): a
  // large input, on small maps.
  const float xyz[9] = {0, 0, 0, 0, 0, 1, 1, 0, 0};
  const fs::path big = write_triangle_gltf(dir, "big", xyz);
  fs::resize_file(dir / "big.bin", uintmax_t(32) << 20);
  EXPECT_EQ(job("env -u GLIBC_TUNABLES", 64, big), reported);
  fs::resize_file(dir / "big.bin", (uintmax_t(32) << 20) - 4096);
  EXPECT_FALSE(job("env -u GLIBC_TUNABLES", 64, big));
  fs::remove_all(dir);
}

TEST(Cli, InfoJson) {
  const RunResult r = run("info --json " + q(kCourtyard));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("\"triangles\""), std::string::npos) << r.output;
}

TEST(Cli, SnowWritesAllOutputsAndIsDeterministic) {
  const fs::path dir = temp_dir("outputs");
  const std::string common = "snow " + q(kCourtyard) + kFast;
  const RunResult a =
      run(common + " -o " + q(dir / "a.glb") + " --snow-output " + q(dir / "a_snow.obj") +
          " --maps " + q(dir / "maps") + " --preview " + q(dir / "a.png"));
  ASSERT_EQ(a.code, 0) << a.output;
  for (const char* f : {"a.glb", "a_snow.obj", "a_snow.mtl", "a.png", "a.glb.settings.json",
                        "maps/manifest.json"}) {
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  }
  EXPECT_NE(a.output.find("summary:"), std::string::npos) << a.output;
  EXPECT_EQ(a.output.find("almost nothing receives snow"), std::string::npos) << a.output;
  expect_valid_gltf(dir / "a.glb");
  // Same input, settings and seed: byte-identical output.
  const RunResult b = run(common + " -o " + q(dir / "b.glb"));
  ASSERT_EQ(b.code, 0) << b.output;
  EXPECT_EQ(read_all(dir / "a.glb"), read_all(dir / "b.glb"));
  // A different seed changes the jitter, hence the snow.
  const RunResult c = run(common + " --seed 7 -o " + q(dir / "c.glb"));
  ASSERT_EQ(c.code, 0) << c.output;
  EXPECT_NE(read_all(dir / "a.glb"), read_all(dir / "c.glb"));
  // The effective settings repeat the run.
  const RunResult d = run("snow " + q(kCourtyard) + " --config " + q(dir / "a.glb.settings.json") +
                          " -o " + q(dir / "d.glb"));
  ASSERT_EQ(d.code, 0) << d.output;
  EXPECT_EQ(read_all(dir / "a.glb"), read_all(dir / "d.glb"));
  // The stabilizer on the GPU and on the CPU: the same snow, byte for byte.
  for (const char* device : {"gpu", "cpu"}) {
    const RunResult e =
        run(common + " --stabilizer " + device + " -o " + q(dir / (device + std::string(".glb"))));
    ASSERT_EQ(e.code, 0) << e.output;
    const std::string where =
        std::string(device) == "cpu" ? "passes on the CPU" : "passes on the GPU";
    EXPECT_NE(e.output.find(where), std::string::npos) << e.output;
    EXPECT_EQ(read_all(dir / "a.glb"), read_all(dir / (device + std::string(".glb")))) << device;
  }
  // The summary names the coverage method; rays cast on the CPU or the GPU
  // agree with each other exactly (the reference's result); shadow maps
  // drawn by GL or on the CPU differ only where a shadow texel's centre lies
  // on a triangle's edge (the snow lying: 62.995 m^3 both).
  std::map<std::string, double> lying;
  for (const auto& [method, said] :
       {std::make_pair("shadow-maps", "coverage by shadow maps;"),
        std::make_pair("cpu-shadow-maps", "coverage by shadow maps on the CPU;"),
        std::make_pair("cpu-rays", "coverage by rays on the CPU;"),
        std::make_pair("rays", "coverage by rays on the GPU;")}) {
    const RunResult f = run(common + " --coverage-method " + method + " -o " +
                            q(dir / (method + std::string(".glb"))));
    ASSERT_EQ(f.code, 0) << f.output;
    EXPECT_NE(f.output.find(said), std::string::npos) << f.output;
    const size_t at = f.output.find("; snow ");
    ASSERT_NE(at, std::string::npos) << f.output;
    lying[method] = std::stod(f.output.substr(at + 7));
  }
  EXPECT_EQ(read_all(dir / "cpu-rays.glb"), read_all(dir / "rays.glb"));
  EXPECT_NEAR(lying["cpu-shadow-maps"], lying["shadow-maps"], 1e-3 * lying["shadow-maps"]);
}

TEST(Cli, NoSnowOnAndIgnoreFilters) {
  const fs::path dir = temp_dir("filters");
  const RunResult plain =
      run("snow " + q(kCourtyard) + kFast + " --snow-only -o " + q(dir / "plain.obj"));
  ASSERT_EQ(plain.code, 0) << plain.output;
  const std::string plain_obj = read_all(dir / "plain.obj");
  EXPECT_NE(plain_obj.find("o snow/TableTop"), std::string::npos);
  EXPECT_EQ(plain_obj.find("o snow/HouseSlab"), std::string::npos) << "no snow inside the house";

  const RunResult no_table =
      run("snow " + q(kCourtyard) + kFast + " --no-snow-on 'Table*' -o " + q(dir / "nt.obj"));
  ASSERT_EQ(no_table.code, 0) << no_table.output;
  EXPECT_EQ(read_all(dir / "nt.obj").find("o snow/TableTop"), std::string::npos);

  const RunResult no_roof =
      run("snow " + q(kCourtyard) + kFast + " --ignore HouseRoof -o " + q(dir / "nr.obj"));
  ASSERT_EQ(no_roof.code, 0) << no_roof.output;
  EXPECT_NE(plain_obj.find("o snow/HouseRoof"), std::string::npos);
  EXPECT_EQ(read_all(dir / "nr.obj").find("o snow/HouseRoof"), std::string::npos)
      << "an ignored object receives no snow";

  const RunResult unmatched =
      run("snow " + q(kCourtyard) + kFast + " --ignore 'NoSuchThing*' -o " + q(dir / "u.obj"));
  EXPECT_EQ(unmatched.code, 0);
  EXPECT_NE(unmatched.output.find("matches no object"), std::string::npos);
}

TEST(Cli, ExitCodesAndNoPartialOutputs) {
  const fs::path dir = temp_dir("bad");
  const fs::path out = dir / "out";
  fs::create_directories(out);
  const float good[9] = {0, 0, 0, 1, 0, 0, 0, 0, 1};
  const float nan_xyz[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 1};

  struct Case {
    std::string name;
    fs::path input;
    int code;
  };
  std::vector<Case> cases;
  write_all(dir / "truncated.glb", read_all(kCourtyard).substr(0, 100));
  cases.push_back({"truncated GLB", dir / "truncated.glb", 2});
  std::string bad_magic = read_all(kCourtyard);
  bad_magic[0] = 'X';
  write_all(dir / "magic.glb", bad_magic);
  cases.push_back({"wrong magic", dir / "magic.glb", 2});
  write_all(dir / "broken.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [");
  cases.push_back({"broken JSON", dir / "broken.gltf", 2});
  cases.push_back({"missing .bin", write_triangle_gltf(dir, "nobin", good, false), 2});
  cases.push_back({"NaN position", write_triangle_gltf(dir, "nan", nan_xyz), 2});
  write_all(dir / "empty.gltf", R"({"asset":{"version":"2.0"},"scenes":[{"nodes":[]}]})");
  cases.push_back({"empty scene", dir / "empty.gltf", 2});
  for (const Case& c : cases) {
    const RunResult r = run("snow " + q(c.input) + kFast + " -o " + q(out / "x.glb") +
                            " --preview " + q(out / "x.png"));
    EXPECT_EQ(r.code, c.code) << c.name << ": " << r.output;
    EXPECT_NE(r.output.find("error:"), std::string::npos) << c.name;
    EXPECT_EQ(file_count(out), 0u) << c.name << " left files behind";
  }
  // I/O: unwritable output folder; no input file.
  const RunResult unwritable = run("snow " + q(kCourtyard) + kFast + " -o /nonexistent_dir/x.glb");
  EXPECT_EQ(unwritable.code, 4) << unwritable.output;
  // Bad settings are bad input.
  EXPECT_EQ(run("snow " + q(kCourtyard) + " --layers 0 -o " + q(out / "x.glb")).code, 2);
  EXPECT_EQ(run("snow " + q(kCourtyard) + " --wind 3 -o " + q(out / "x.glb")).code, 2);
  EXPECT_EQ(run("snow " + q(kCourtyard) + " --frobnicate -o " + q(out / "x.glb")).code, 2);
  // Unsigned options take no negative number (not as their largest value).
  for (const char* option : {"--seed -1", "--piece-triangles -1"}) {
    const RunResult negative =
        run("snow " + q(kCourtyard) + " " + option + " -o " + q(out / "x.glb"));
    EXPECT_EQ(negative.code, 2) << option;
    EXPECT_NE(negative.output.find("expected a whole number >= 0, got '-1'"), std::string::npos)
        << negative.output;
  }
  // Stabilizer settings are checked before the scene is loaded and peeled.
  const RunResult bad_stride =
      run("snow " + q(kCourtyard) + " --max-stride 3 -o " + q(out / "x.glb"));
  EXPECT_EQ(bad_stride.code, 2);
  EXPECT_NE(bad_stride.output.find("max_stride"), std::string::npos) << bad_stride.output;
  EXPECT_EQ(bad_stride.output.find("peel"), std::string::npos) << bad_stride.output;
  const RunResult bad_kind = run("snow " + q(kCourtyard) + " --snow slush -o " + q(out / "x.glb"));
  EXPECT_EQ(bad_kind.code, 2);
  EXPECT_NE(bad_kind.output.find("--snow must be powder, fresh or wet, got 'slush'"),
            std::string::npos)
      << bad_kind.output;
  const RunResult bad_device =
      run("snow " + q(kCourtyard) + " --stabilizer tpu -o " + q(out / "x.glb"));
  EXPECT_EQ(bad_device.code, 2);
  EXPECT_NE(bad_device.output.find("device must be auto, gpu or cpu, got 'tpu'"), std::string::npos)
      << bad_device.output;
  const RunResult bad_method =
      run("snow " + q(kCourtyard) + " --coverage-method raytrace -o " + q(out / "x.glb"));
  EXPECT_EQ(bad_method.code, 2);
  EXPECT_NE(bad_method.output.find(
                "coverage method must be auto, shadow-maps, rays, cpu-rays or cpu-shadow-maps"),
            std::string::npos)
      << bad_method.output;
  EXPECT_EQ(bad_method.output.find("peel"), std::string::npos) << bad_method.output;
  // glTF goes by the output's extension: --format must agree with it, and
  // says so before the work.
  const RunResult bad_format =
      run("snow " + q(kCourtyard) + " --format glb -o " + q(out / "x.bin"));
  EXPECT_EQ(bad_format.code, 2);
  EXPECT_NE(bad_format.output.find("x.bin: a glb file needs the extension .glb"), std::string::npos)
      << bad_format.output;
  EXPECT_EQ(bad_format.output.find("peel"), std::string::npos) << bad_format.output;
  write_all(dir / "bad_settings.json", R"({"maps": {"texle": 0.1}})");
  const RunResult bad_config = run("snow " + q(kCourtyard) + " --config " +
                                   q(dir / "bad_settings.json") + " -o " + q(out / "x.glb"));
  EXPECT_EQ(bad_config.code, 2);
  EXPECT_NE(bad_config.output.find("maps.texle"), std::string::npos) << bad_config.output;
  // No usable GL.
  const RunResult no_gl =
      run("--gl-backend egl-device snow " + q(kCourtyard) + kFast + " -o " + q(out / "x.glb"));
  if (no_gl.code != 0) {
    EXPECT_EQ(no_gl.code, 3) << no_gl.output;
  }
  fs::remove_all(out);
  fs::create_directories(out);
  EXPECT_EQ(file_count(out), 0u);
}

// Every numeric option has a range (issue 48): out of it, from a flag or a
// --config file, is one error line naming the option and the bound, exit 2,
// before any work; no count runs for minutes, no seed wraps.
TEST(Cli, OptionsOutsideTheirRangesAreRefused) {
  const fs::path dir = temp_dir("ranges");
  const fs::path out = dir / "x.glb";
  struct Case {
    std::string args;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"--smooth 1000000", "--smooth (mesh.smooth_iterations) must be in 0..100, got 1000000"},
      {"--smooth -1", "--smooth (mesh.smooth_iterations) must be in 0..100, got -1"},
      {"--steps 100000", "--steps (snow.steps) must be in 1..1000, got 100000"},
      {"--min-thickness -1", "--min-thickness (mesh.min_thickness) must be in 0..100, got -1"},
      {"--bottom-offset 1e9",
       "--bottom-offset (mesh.bottom_offset) must be in 0..10, got 1000000000"},
      {"--depth inf", "--depth (snow.depth) must be in 0..1000, got inf"},
      {"--wind 300,0", "--wind (coverage.wind) must be in -100..100, got 300"},
      {"--margin nan", "--margin (maps.margin) must be negative (automatic) or in 0..10000"},
      {"--max-iterations 1000000", "--max-iterations (snow.max_iterations) must be in 0..100000"},
      {"--memory-budget 0", "--memory-budget (maps.memory_budget_gib) must be in 0.01..1048576"},
      {"--seed 18446744073709551616",
       "--seed: expected a whole number up to 18446744073709551615, got '18446744073709551616'"},
      {"--steps 99999999999", "--steps"},
  };
  for (const Case& c : cases) {
    const RunResult r = run("snow " + q(kCourtyard) + " " + c.args + " -o " + q(out));
    EXPECT_EQ(r.code, 2) << c.args << ": " << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << ": " << r.output;
    EXPECT_EQ(r.output.find("peel"), std::string::npos) << c.args << ": " << r.output;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
  // The largest seed is a seed; a negative margin is automatic.
  const RunResult largest = run("snow " + q(kCourtyard) + kFast +
                                " --seed 18446744073709551615 --margin -5 -o " + q(out));
  EXPECT_EQ(largest.code, 0) << largest.output;
  // The same bounds hold for a --config file, and a whole number its field
  // cannot hold is not wrapped into one.
  write_all(dir / "smooth.json", R"({"mesh": {"smooth_iterations": 1000000}})");
  write_all(dir / "wrap.json", R"({"mesh": {"smooth_iterations": 4294967298}})");
  write_all(dir / "seed.json", R"({"coverage": {"seed": 18446744073709551616}})");
  for (const auto& [file, message] : std::vector<std::pair<std::string, std::string>>{
           {"smooth.json", "--smooth (mesh.smooth_iterations) must be in 0..100, got 1000000"},
           {"wrap.json", "'mesh.smooth_iterations' has a value of the wrong type (4294967298"},
           {"seed.json", "'coverage.seed' has a value of the wrong type"}}) {
    const RunResult r =
        run("snow " + q(kCourtyard) + " --config " + q(dir / file) + " -o " + q(dir / "y.glb"));
    EXPECT_EQ(r.code, 2) << file << ": " << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << file << ": " << r.output;
  }
  // The preview's own options too, before a window opens.
  const RunResult zoom = run("preview " + q(kCourtyard) + " --zoom 0");
  EXPECT_EQ(zoom.code, 2) << zoom.output;
  EXPECT_NE(zoom.output.find("--zoom must be in 0.01..100, got 0"), std::string::npos)
      << zoom.output;
  // The help states the ranges.
  const RunResult help = run("snow --help");
  EXPECT_NE(help.output.find("Smoothing passes over the snow top [0..100]"), std::string::npos)
      << help.output;
  EXPECT_NE(help.output.find("[1..1000]"), std::string::npos) << help.output;
}

TEST(Cli, SharedScenesSnow) {
  const fs::path shared = SNOW_SHARED_SCENES;
  if (!fs::exists(shared)) GTEST_SKIP() << "../shared/scenes is absent";
  const fs::path dir = temp_dir("shared");
  // A Kenney tile is about 1 m wide: 48 texels keep the run short.
  for (const char* scene : {"kenney-city/building-small-a.glb"}) {
    const RunResult r = run("snow " + q(shared / scene) +
                            " --max-side 48 --directions 16 --layers 6 -o " + q(dir / "out.glb"));
    EXPECT_EQ(r.code, 0) << scene << ": " << r.output;
    EXPECT_TRUE(fs::exists(dir / "out.glb")) << scene;
    expect_valid_gltf(dir / "out.glb");
    fs::remove(dir / "out.glb");
  }
}

namespace {
// Writes the scene of `builder` as a .glb file.
void save_built_scene(const snow::SceneBuilder& builder, const fs::path& path) {
  tinygltf::Model model;
  snow::append_meshes(model, builder.meshes(), builder.materials(), "Scene");
  snow::save_gltf(model, path);
}
}  // namespace

// The highest point (m) of the OBJ object `name` in `obj`'s text, or -1.
double object_top(const std::string& obj, const std::string& name) {
  std::istringstream in(obj);
  bool inside = false;
  double top = -1.0;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("o ", 0) == 0) inside = line.substr(2) == name;
    if (!inside || line.rfind("v ", 0) != 0) continue;
    std::istringstream v(line.substr(2));
    double c[3];
    v >> c[0] >> c[1] >> c[2];
    top = std::max(top, c[1]);
  }
  return top;
}

// A 2 x 2 x 1 m block on square planes of 20 m, 200 m and 2 km, default
// settings: the block gets the same snow on each (to 1 cm; its top 0.3 m
// over it and up to 1.5 cm more, the snow its rounded shoulders give up),
// the big planes' far ground an even cover under two map levels that the
// run names, all within the default memory budget.
TEST(Cli, SmallObjectOnBigGroundsGetsTheSameSnow) {
  const fs::path dir = temp_dir("big_grounds");
  double first_top = -1.0;
  for (const float side : {20.0f, 200.0f, 2000.0f}) {
    snow::SceneBuilder b;
    b.add_plane("Ground", 0.0f, glm::vec2(-0.5f * side), glm::vec2(0.5f * side));
    b.add_box("Block", {-1.0f, 0.0f, -1.0f}, {1.0f, 1.0f, 1.0f});
    const std::string name = "ground" + std::to_string(int(side));
    save_built_scene(b, dir / (name + ".glb"));
    const RunResult r = run("-v snow " + q(dir / (name + ".glb")) + " --directions 16 " +
                            "--snow-output " + q(dir / (name + ".obj")));
    ASSERT_EQ(r.code, 0) << r.output;
    const bool levels = side > 20.0f;  // 20 m: one map at 2 cm texels holds it all
    EXPECT_EQ(r.output.find("maps: two levels") != std::string::npos, levels) << r.output;
    const std::string obj = read_all(dir / (name + ".obj"));
    const double top = object_top(obj, "snow/Block");
    EXPECT_GT(top, 1.3 - 0.005) << side;
    EXPECT_LT(top, 1.3 + 0.015) << side;
    if (first_top < 0.0) first_top = top;
    EXPECT_NEAR(top, first_top, 0.01) << side;
    if (levels) {
      EXPECT_NEAR(object_top(obj, "snow/Ground/beyond"), 0.3, 0.002) << side;
    }
    const size_t at = r.output.find("peak memory ");
    ASSERT_NE(at, std::string::npos);
    EXPECT_LT(std::atof(r.output.c_str() + at + 12), 4096.0) << r.output;  // MiB
  }
}

// Wind in the batch job, on the wind's yard (a cube, a fence, a roof step):
// a wind too light to move fresh snow says so and only tilts the fall; one
// of 8 m/s moves it (the summary says how much), the snow meshes (with
// cornices at lee edges) are validator-clean, and the same run twice
// writes the same bytes.
TEST(Cli, WindDriftsTheSnowDeterministically) {
  const fs::path dir = temp_dir("wind");
  save_built_scene(snow::make_wind_yard(), dir / "yard.glb");
  const std::string base = "snow " + q(dir / "yard.glb") + " --directions 16 --max-side 400 ";
  const RunResult light = run(base + "--wind 3,0 -o " + q(dir / "light.glb"));
  ASSERT_EQ(light.code, 0) << light.output;
  EXPECT_NE(light.output.find("wind: 3 m/s tilts the fall; it is too light to move fresh snow"),
            std::string::npos)
      << light.output;
  EXPECT_EQ(light.output.find("the wind moved"), std::string::npos) << light.output;
  for (const char* name : {"a.glb", "b.glb"}) {
    const RunResult r = run(base + "--wind 8,0 -o " + q(dir / name));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("wind: 8 m/s blows fresh snow into drifts"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("the wind moved"), std::string::npos) << r.output;
  }
  EXPECT_EQ(read_all(dir / "a.glb"), read_all(dir / "b.glb"));
  expect_valid_gltf(dir / "a.glb");
  const RunResult over = run(base + "--wind 20,20 -o " + q(dir / "over.glb"));
  EXPECT_EQ(over.code, 2) << over.output;
  EXPECT_FALSE(fs::exists(dir / "over.glb"));
}

// The m^3 of snow the run's summary line reports ("snow V m^3"), or -1.
double summary_volume(const std::string& output) {
  const size_t at = output.find("; snow ");
  return at == std::string::npos ? -1.0 : std::atof(output.c_str() + at + 7);
}

// The yard (three objects) in metres, in centimetres and +Z up, as
// exporters write them: the frame warnings say which option fixes each, the
// options give the metre run's snow, and the snow goes back to the file's
// frame.
TEST(Cli, CentimetresAndZUpAreNoticedAndFixedByOptions) {
  const fs::path dir = temp_dir("frames");
  snow::SceneBuilder yard = snow::test::yard_under(snow::test::Sky::None);
  yard.add_box("Shed", {2.0f, 0.0f, 2.0f}, {4.0f, 2.0f, 4.0f});
  const auto save_in = [&](const snow::FileFrame& frame, const fs::path& path) {
    std::vector<snow::TriMesh> meshes = yard.meshes();
    for (snow::TriMesh& m : meshes) snow::to_file_frame(m, frame);
    tinygltf::Model model;
    snow::append_meshes(model, meshes, yard.materials(), "Scene");
    snow::save_gltf(model, path);
  };
  save_in({}, dir / "m.glb");
  save_in({0.01f, false}, dir / "cm.glb");
  save_in({1.0f, true}, dir / "zup.glb");
  const std::string common = " --max-side 96 --directions 8 --snow-output ";
  const auto snow = [&](const std::string& scene, const std::string& options) {
    const RunResult r =
        run("snow " + q(dir / scene) + options + common + q(dir / (scene + ".obj")));
    EXPECT_EQ(r.code, 0) << r.output;
    return r;
  };
  const RunResult metres = snow("m.glb", "");
  EXPECT_EQ(metres.output.find("--unit-scale"), std::string::npos) << metres.output;
  EXPECT_EQ(metres.output.find("--up z"), std::string::npos) << metres.output;
  const double volume = summary_volume(metres.output);
  ASSERT_GT(volume, 0.0) << metres.output;
  const RunResult cm = snow("cm.glb", "");
  EXPECT_NE(cm.output.find("if the scene is in centimetres, give --unit-scale 0.01"),
            std::string::npos)
      << cm.output;
  const RunResult cm_fixed = snow("cm.glb", " --unit-scale 0.01");
  EXPECT_EQ(cm_fixed.output.find("--unit-scale 0.01"), std::string::npos) << cm_fixed.output;
  EXPECT_NEAR(summary_volume(cm_fixed.output), volume, 0.01 * volume);
  const RunResult zup = snow("zup.glb", "");
  EXPECT_NE(zup.output.find("if the scene is +Z up, give --up z"), std::string::npos) << zup.output;
  const RunResult zup_fixed = snow("zup.glb", " --up z");
  EXPECT_EQ(zup_fixed.output.find("--up z"), std::string::npos) << zup_fixed.output;
  EXPECT_NEAR(summary_volume(zup_fixed.output), volume, 0.01 * volume);
  // The snow lies in the file's frame: its top in centimetres; +Z up.
  const auto extent = [&](const std::string& obj, int axis) {
    std::istringstream in(read_all(dir / obj));
    double most = 0.0;
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("v ", 0) != 0) continue;
      std::istringstream v(line.substr(2));
      double c[3];
      v >> c[0] >> c[1] >> c[2];
      most = std::max(most, c[axis]);
    }
    return most;
  };
  EXPECT_NEAR(extent("cm.glb.obj", 1), 100.0 * extent("m.glb.obj", 1), 1.0);
  EXPECT_NEAR(extent("zup.glb.obj", 2), extent("m.glb.obj", 1), 0.01);
}

// A yard under a sky dome, in a sky box, in an inverted sphere
// (tests/support/enclosures.h): the sky is left out with a warning naming
// it, and the yard gets the snow it gets under the open sky; kept, the dome
// takes the snow and the block gets none.
TEST(Cli, SkyEnclosuresAreLeftOutWithAWarning) {
  using snow::test::Sky;
  const fs::path dir = temp_dir("sky_enclosures");
  const std::string options = " --max-side 128 --directions 8 --snow-output ";
  save_built_scene(snow::test::yard_under(Sky::None), dir / "open.glb");
  const RunResult open = run("snow " + q(dir / "open.glb") + options + q(dir / "open.obj"));
  ASSERT_EQ(open.code, 0) << open.output;
  const double top = object_top(read_all(dir / "open.obj"), "snow/Block");
  ASSERT_GT(top, 1.2);
  for (const auto& [sky, name] : {std::pair{Sky::Dome, "SkyDome"}, std::pair{Sky::Box, "SkyBox"},
                                  std::pair{Sky::InvertedSphere, "SkySphere"}}) {
    save_built_scene(snow::test::yard_under(sky), dir / (std::string(name) + ".glb"));
    const std::string common = "snow " + q(dir / (std::string(name) + ".glb")) + options;
    const RunResult r = run(common + q(dir / (std::string(name) + ".obj")));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_NE(r.output.find("object '" + std::string(name) + "' encloses the scene from above"),
              std::string::npos)
        << r.output;
    const std::string snow = read_all(dir / (std::string(name) + ".obj"));
    EXPECT_NEAR(object_top(snow, "snow/Block"), top, 0.01) << name;
    EXPECT_EQ(snow.find("o snow/" + std::string(name)), std::string::npos) << name;
  }
  const RunResult kept = run("snow " + q(dir / "SkyDome.glb") + " --keep-enclosures true" +
                             options + q(dir / "kept.obj"));
  ASSERT_EQ(kept.code, 0) << kept.output;
  EXPECT_EQ(read_all(dir / "kept.obj").find("o snow/Block"), std::string::npos);
}

// A 1 m floor with a 0.4 m table top 0.3 m above it.
void save_small_table(const fs::path& path) {
  snow::SceneBuilder builder;
  builder.add_plane("Floor", 0.0f, {-0.5f, -0.5f}, {0.5f, 0.5f});
  builder.add_box("Top", {-0.2f, 0.3f, -0.2f}, {0.2f, 0.33f, 0.2f});
  save_built_scene(builder, path);
}

// Where GL renders in software, a small scene runs on the CPU alone (the
// peel, coverage and stabilizer of small maps): no context is made, so the
// driver is not even loaded (road-straight-lightposts: 0.33 -> 0.14 s, 104
// -> 19 MiB). A pass that needs GL still makes its stage's context.
TEST(Cli, SmallScenesInSoftwareNeedNoGl) {
  if (snow::gl::probe_software() != std::optional<bool>(true)) {
    GTEST_SKIP() << "GL does not render in software here";
  }
  const fs::path dir = temp_dir("no_gl");
  save_small_table(dir / "table.glb");
  const std::string common = "-v snow " + q(dir / "table.glb") + " --depth 0.05 --max-side 64";
  const RunResult cpu = run(common + " -o " + q(dir / "cpu.glb"));
  ASSERT_EQ(cpu.code, 0) << cpu.output;
  EXPECT_EQ(cpu.output.find("OpenGL:"), std::string::npos) << cpu.output;
  EXPECT_EQ(cpu.output.find("GL context"), std::string::npos) << cpu.output;
  EXPECT_NE(cpu.output.find("on the CPU; stabilizer"), std::string::npos) << cpu.output;
  EXPECT_NE(cpu.output.find("passes on the CPU; OpenGL not started"), std::string::npos)
      << cpu.output;
  const RunResult gl = run(common + " --coverage-method shadow-maps -o " + q(dir / "gl.glb"));
  ASSERT_EQ(gl.code, 0) << gl.output;
  EXPECT_NE(gl.output.find("OpenGL:"), std::string::npos) << gl.output;
  EXPECT_EQ(gl.output.find("OpenGL not started"), std::string::npos) << gl.output;
  EXPECT_EQ(gl.output.find("OpenGL:"), gl.output.rfind("OpenGL:")) << gl.output;
  EXPECT_NE(gl.output.find("coverage by shadow maps;"), std::string::npos) << gl.output;
}

// 0.3 m of snow on a table 1 m wide (a model in other units than metres)
// is out of scale: the run warns; 2 cm is not. Snow many texels deep warns
// that stabilizing will be slow.
TEST(Cli, WarnsWhenTheSnowIsOutOfScale) {
  const fs::path dir = temp_dir("scale");
  save_small_table(dir / "small.glb");

  const std::string common = "snow " + q(dir / "small.glb") + " --max-side 32 --directions 8";
  const RunResult deep = run(common + " -o " + q(dir / "deep.obj"));
  ASSERT_EQ(deep.code, 0) << deep.output;
  EXPECT_NE(deep.output.find("snow depth 0.3 m is 30 % of the scene's width (1 m)"),
            std::string::npos)
      << deep.output;
  const RunResult shallow = run(common + " --depth 0.02 -o " + q(dir / "shallow.obj"));
  ASSERT_EQ(shallow.code, 0) << shallow.output;
  EXPECT_EQ(shallow.output.find("of the scene's width"), std::string::npos) << shallow.output;
  EXPECT_EQ(shallow.output.find("texels deep"), std::string::npos) << shallow.output;
  EXPECT_EQ(shallow.output.find("from the origin"), std::string::npos) << shallow.output;

  // A floor 5e6 m from the origin (as UTM northings put a model): floats are
  // 0.5 m apart there, too coarse for 0.3 m of snow.
  const float far[9] = {0, 0, 5e6f, 0, 0, 5e6f + 4, 4, 0, 5e6f};
  const RunResult distant = run("snow " + q(write_triangle_gltf(dir, "far", far)) +
                                " --max-side 16 --directions 4 -o " + q(dir / "far.obj"));
  ASSERT_EQ(distant.code, 0) << distant.output;
  EXPECT_NE(distant.output.find("reaches 5e+06 m from the origin, where 32-bit floats are 0.5 m "
                                "apart: too coarse for 0.3 m of snow"),
            std::string::npos)
      << distant.output;

  // 0.3 m on 1.04 m / 256 texels is 74 texels deep: the run warns and names
  // the map side that makes it 32 (16 passes keep the run short).
  const RunResult fine =
      run("snow " + q(dir / "small.glb") +
          " --max-side 256 --directions 8 --max-iterations 16 -o " + q(dir / "fine.obj"));
  ASSERT_EQ(fine.code, 0) << fine.output;
  EXPECT_NE(fine.output.find("texels deep"), std::string::npos) << fine.output;
  EXPECT_NE(fine.output.find("--max-side 110"), std::string::npos) << fine.output;

  // Without --max-side the map side is automatic: the 1024 texels would make
  // the snow 295 texels deep, so the run takes the 110 that make it 32 and
  // says so instead of warning.
  const RunResult automatic = run("snow " + q(dir / "small.glb") +
                                  " --directions 8 --max-iterations 16 -o " + q(dir / "auto.obj"));
  ASSERT_EQ(automatic.code, 0) << automatic.output;
  EXPECT_NE(automatic.output.find("automatic side 110 texels"), std::string::npos)
      << automatic.output;
  EXPECT_NE(automatic.output.find("maps: 110 x 110 texels"), std::string::npos) << automatic.output;
  EXPECT_EQ(automatic.output.find("far finer than its shapes need"), std::string::npos)
      << automatic.output;
}

// A run whose stabilizer stops at --max-iterations with the snow still
// moving says so; one that settles does not.
TEST(Cli, WarnsWhenTheSnowDoesNotSettle) {
  const fs::path dir = temp_dir("settle");
  save_small_table(dir / "small.glb");
  // Loose snow (no cohesion) creeps off the table's edges for many passes.
  const std::string common =
      "snow " + q(dir / "small.glb") + " --max-side 32 --directions 8 --stand-height 0";
  const RunResult cut = run(common + " --max-iterations 2 -o " + q(dir / "cut.obj"));
  ASSERT_EQ(cut.code, 0) << cut.output;
  EXPECT_NE(cut.output.find("did not settle within --max-iterations 2 passes"), std::string::npos)
      << cut.output;
  const RunResult settled = run(common + " -o " + q(dir / "settled.obj"));
  ASSERT_EQ(settled.code, 0) << settled.output;
  EXPECT_EQ(settled.output.find("did not settle"), std::string::npos) << settled.output;
}

// A run that meshes no snow says why: snow thinner than --min-thickness, or
// patches smaller than --min-patch-area (a 1 m floor with 2 cm of snow).
TEST(Cli, SaysWhyNoSnowPatchCameOut) {
  const fs::path dir = temp_dir("no_patch");
  snow::SceneBuilder builder;
  builder.add_plane("Floor", 0.0f, {-0.5f, -0.5f}, {0.5f, 0.5f});
  save_built_scene(builder, dir / "floor.glb");
  const std::string common =
      "snow " + q(dir / "floor.glb") + " --max-side 32 --directions 8 --depth 0.02";
  const RunResult thin = run(common + " --min-thickness 0.05 -o " + q(dir / "thin.obj"));
  ASSERT_EQ(thin.code, 0) << thin.output;
  EXPECT_NE(thin.output.find("thinner than --min-thickness 0.05"), std::string::npos)
      << thin.output;
  const RunResult small = run(common + " --min-patch-area 5 -o " + q(dir / "small.obj"));
  ASSERT_EQ(small.code, 0) << small.output;
  EXPECT_NE(small.output.find("smaller than --min-patch-area 5"), std::string::npos)
      << small.output;
  const RunResult fine = run(common + " -o " + q(dir / "fine.obj"));
  ASSERT_EQ(fine.code, 0) << fine.output;
  EXPECT_EQ(fine.output.find("no snow patch"), std::string::npos) << fine.output;
}

// A sky box around the scene takes all the snow: the run warns and names it,
// and --ignore of the sky box gives snow on the ground (and the bench, whose
// snow joins the ground's patch) and no warning.
TEST(Cli, WarnsWhenASkyBoxTakesTheSnow) {
  const fs::path dir = temp_dir("skybox");
  snow::SceneBuilder builder;
  builder.add_plane("Ground", 0.0f, {-5.0f, -5.0f}, {5.0f, 5.0f});
  builder.add_box("Bench", {-1.5f, 0.0f, -0.75f}, {1.5f, 0.5f, 0.75f});
  builder.add_box("SkyBox", {-8.0f, -2.0f, -8.0f}, {8.0f, 20.0f, 8.0f});
  save_built_scene(builder, dir / "sky.glb");

  const std::string common = "snow " + q(dir / "sky.glb") + " --max-side 96 --directions 16";
  // Kept (it would be left out, Cli.SkyEnclosuresAreLeftOutWithAWarning), the
  // sky box takes the snow, and the fallback warning names it.
  const RunResult boxed = run(common + " --keep-enclosures true -o " + q(dir / "boxed.glb"));
  ASSERT_EQ(boxed.code, 0) << boxed.output;
  EXPECT_NE(boxed.output.find("almost nothing receives snow"), std::string::npos) << boxed.output;
  EXPECT_NE(boxed.output.find("'SkyBox' (encloses the scene"), std::string::npos) << boxed.output;

  const RunResult open = run(common + " --ignore SkyBox -o " + q(dir / "open.obj"));
  ASSERT_EQ(open.code, 0) << open.output;
  EXPECT_EQ(open.output.find("almost nothing receives snow"), std::string::npos) << open.output;
  const std::string obj = read_all(dir / "open.obj");
  EXPECT_NE(obj.find("o snow/Ground"), std::string::npos);
}
