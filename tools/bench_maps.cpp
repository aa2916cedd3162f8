// Benchmark of pipeline stages 1 and 2 (not a test): depth peeling and
// coverage time per stage, against the raw rasterization work they contain
// (the peel's passes and the K shadow passes as bare depth passes of the
// same sizes), so the overhead ratio is visible. Results go to
// tools/RESULTS.md ("Peel and coverage").
//
// Usage: snowmodel_bench_maps [--side N] [--layers L] [--directions K]
//                             [--big-side N] [--big-triangles T] [--no-big | --big-only]
//                             [--method auto|shadow-maps|rays|cpu-rays|cpu-shadow-maps]
//                             [--accuracy] [--verbose] [scene.glb|scene.gltf ...]
// Without scene arguments it runs the bundled courtyard, a few scenes from
// ../shared/scenes (when present) and a generated scene of about
// --big-triangles triangles (default 1M) at --big-side (default 2048).
// --accuracy also casts the same K rays on the CPU for every layer texel
// (snow::reference::compute_coverage) and adds the mean and largest
// |GPU - CPU| coverage over the texels with a surface. --verbose prints the
// stages' debug lines (stderr): the receivers left after the culls, the
// triangles per map and the method the automatic choice took, what
// choose_coverage_method's costs are measured against.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/heap.h"
#include "core/log.h"
#include "gl/context.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "snow/coverage.h"
#include "snow/peel.h"
#include "snow/reference/coverage_ref.h"

namespace {

// CPU seconds of this process, all threads (llvmpipe's workers included):
// steadier than wall time on a shared machine.
double cpu_seconds() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Options {
  int side = 1024;
  int layers = 8;
  int directions = 64;
  int big_side = 2048;
  int big_triangles = 1000000;
  bool big = true;
  bool big_only = false;
  int repeat = 1;               // coverage runs per scene; each stage's best time is reported
  bool accuracy = false;        // compare with the CPU ray-cast reference
  bool verbose = false;         // the stages' debug lines
  std::string method = "auto";  // snow::CoverageSettings::method
  std::vector<std::string> scenes;
};

struct Row {
  std::string name;
  size_t triangles = 0;
  int width = 0, height = 0, layers_found = 0, peel_passes = 0;
  glm::ivec2 shadow{0};
  double peel = 0, setup = 0, shadow_s = 0, composite = 0, readback = 0;
  double raw_peel = 0, raw_shadow = 0;
  double raw_grid = 0;  // K depth passes at the snow map's own size (no culling, no shear growth)
  double coverage_cpu = 0;  // CPU seconds of one coverage run, all threads
  double queued_share = 0;  // receivers sent to the exact pass per batch / receivers
  snow::CoverageMethod method = snow::CoverageMethod::ShadowMaps;
  double culled_share = 0;  // receivers found open to the sky on the CPU / all receivers
  double mean_error = 0, max_error = 0;  // |GPU - CPU reference| coverage (--accuracy)
  double reference_s = 0;                // wall time of the CPU reference
};

Row run(const std::string& name, const snow::Scene& scene, int side, const Options& o) {
  Row r;
  r.name = name;
  r.triangles = scene.triangle_count();
  snow::PeelSettings ps;
  ps.max_side = side;
  ps.layers = o.layers;
  // As snowmodel does, so that the timings compare.
  if (snow::plan::huge_pages_off(snow::plan::probe_machine({}), 0,
                                 snow::make_grid(scene.bounds, ps).texels()))
    snow::turn_off_huge_pages();
  snow::SnowMaps maps;
  r.peel = 1e30;
  for (int k = 0; k < o.repeat; ++k) {
    const double t0 = seconds();
    maps = snow::peel_layers(scene, ps, snow::plan::current_gl());
    r.peel = std::min(r.peel, seconds() - t0);
  }
  r.width = maps.grid.width;
  r.height = maps.grid.height;
  for (int l = 0; l < maps.layers; ++l) {
    bool any = false;
    for (size_t t = 0; t < maps.grid.texels() && !any; ++t) {
      any = !std::isnan(maps.ground[size_t(l) * maps.grid.texels() + t]);
    }
    if (any) r.layers_found = l + 1;
  }
  // The peel ran one pass per layer found, plus the one that found nothing
  // (or counted the overflow).
  r.peel_passes = std::min(r.layers_found + 1, o.layers + 1);

  snow::CoverageSettings cs;
  cs.directions = o.directions;
  cs.method = o.method;
  snow::CoverageRenderer renderer(scene, snow::plan::current_gl());
  renderer.set_profiling(true);
  // Each stage's best time over the runs (the first run also JIT-compiles
  // the shaders; other processes on the machine only ever add time).
  r.setup = r.shadow_s = r.composite = r.readback = r.coverage_cpu = 1e30;
  std::vector<float> coverage;
  for (int k = 0; k < o.repeat; ++k) {
    const double c0 = cpu_seconds();
    coverage = renderer.compute(maps, cs);
    r.coverage_cpu = std::min(r.coverage_cpu, cpu_seconds() - c0);
    const auto& t = renderer.timings();
    r.setup = std::min(r.setup, t.setup);
    r.shadow_s = std::min(r.shadow_s, t.shadow);
    r.composite = std::min(r.composite, t.composite);
    r.readback = std::min(r.readback, t.readback);
    r.culled_share =
        double(t.culled - t.shaded) /
        double(std::max<uint64_t>(1, t.culled + t.pairs / uint64_t(std::max(1, cs.directions))));
    r.method = t.method;
    r.queued_share =
        t.method == snow::CoverageMethod::CpuShadowMaps
            ? double(t.queued) / double(std::max<uint64_t>(1, t.pairs))  // uncertain pairs
        : t.method != snow::CoverageMethod::ShadowMaps
            ? 1.0
            : double(t.queued) /
                  double(std::max<uint64_t>(
                      1, t.pairs / uint64_t(snow::shadow_batch(
                                       cs, double(renderer.shadow_map_size().x) *
                                               double(renderer.shadow_map_size().y)))));
  }
  // Cast as rays (snow::choose_coverage_method), no shadow maps were drawn:
  // the raw passes at the maps' size.
  const bool rays =
      r.method == snow::CoverageMethod::GpuRays || r.method == snow::CoverageMethod::CpuRays;
  r.shadow = rays ? glm::ivec2(r.width, r.height) : renderer.shadow_map_size();
  if (o.accuracy) {
    const double t0 = seconds();
    const std::vector<float> cpu =
        snow::reference::compute_coverage(scene, maps, snow::fall_directions(cs));
    r.reference_s = seconds() - t0;
    double sum = 0;
    size_t n = 0;
    for (size_t k = 0; k < cpu.size(); ++k) {
      if (std::isnan(maps.ground[k])) continue;
      const double e = std::abs(double(coverage[k]) - double(cpu[k]));
      sum += e;
      r.max_error = std::max(r.max_error, e);
      ++n;
    }
    r.mean_error = n > 0 ? sum / double(n) : 0.0;
  }

  r.raw_peel = r.raw_shadow = r.raw_grid = 1e30;
  for (int k = 0; k < o.repeat; ++k) {
    r.raw_peel =
        std::min(r.raw_peel, snow::time_depth_passes(scene, r.width, r.height, r.peel_passes));
    r.raw_shadow = std::min(
        r.raw_shadow, snow::time_depth_passes(scene, r.shadow.x, r.shadow.y, o.directions, true));
    r.raw_grid =
        std::min(r.raw_grid, snow::time_depth_passes(scene, r.width, r.height, o.directions, true));
  }
  return r;
}

void print(const Row& r, const Options& o) {
  const double total = r.peel + r.setup + r.shadow_s + r.composite + r.readback;
  const double raw = r.raw_peel + r.raw_grid;
  std::printf(
      "| %s | %zu | %dx%d | %d | %.2f | %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | "
      "%.2f | %.2f | %.2f | %.0f%% | %.1f%% |",
      r.name.c_str(), r.triangles, r.width, r.height, r.layers_found, r.peel,
      r.method == snow::CoverageMethod::GpuRays   ? "GPU rays"
      : r.method == snow::CoverageMethod::CpuRays ? "CPU rays"
      : r.method == snow::CoverageMethod::CpuShadowMaps
          ? (std::to_string(r.shadow.x) + "x" + std::to_string(r.shadow.y) + " CPU").c_str()
          : (std::to_string(r.shadow.x) + "x" + std::to_string(r.shadow.y)).c_str(),
      r.setup, r.shadow_s, r.composite, r.readback, total, r.raw_peel, r.raw_grid, r.raw_shadow,
      total / raw, r.coverage_cpu, 100.0 * r.culled_share, 100.0 * r.queued_share);
  if (o.accuracy) std::printf(" %.4f | %.3f | %.1f |", r.mean_error, r.max_error, r.reference_s);
  std::printf("\n");
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  snow::tune_heap(argv);  // as snowmodel does, so the timings compare
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() { return i + 1 < argc ? std::atoi(argv[++i]) : 0; };
    if (a == "--side")
      o.side = next();
    else if (a == "--layers")
      o.layers = next();
    else if (a == "--directions")
      o.directions = next();
    else if (a == "--big-side")
      o.big_side = next();
    else if (a == "--big-triangles")
      o.big_triangles = next();
    else if (a == "--no-big")
      o.big = false;
    else if (a == "--big-only")
      o.big_only = true;
    else if (a == "--accuracy")
      o.accuracy = true;
    else if (a == "--verbose")
      o.verbose = true;
    else if (a == "--method" && i + 1 < argc)
      o.method = argv[++i];
    else if (a == "--repeat")
      o.repeat = std::max(1, next());
    else if (a == "-h" || a == "--help") {
      std::printf(
          "usage: snowmodel_bench_maps [--side N] [--layers L] [--directions K]\n"
          "  [--big-side N] [--big-triangles T] [--no-big | --big-only] [--repeat R]\n"
          "  [--method auto|shadow-maps|rays|cpu-rays|cpu-shadow-maps] [--accuracy] [--verbose]\n"
          "  [scene.glb|scene.gltf ...]\n");
      return 0;
    } else if (a.rfind("--", 0) == 0) {
      std::fprintf(stderr, "unknown option %s (--help lists them)\n", a.c_str());
      return 2;
    } else
      o.scenes.push_back(a);
  }
  try {
    snow::set_log_level(o.verbose ? snow::LogLevel::Debug : snow::LogLevel::Warn);
    auto context = snow::gl::create_context();
    std::printf("GL: %s\n", context->description().c_str());
    std::printf("maps side %d (generated scene %d), L = %d, K = %d\n\n", o.side, o.big_side,
                o.layers, o.directions);
    std::printf(
        "| scene | triangles | map | layers | peel s | shadow map | setup s | shadow s | count s | "
        "readback s | total s | raw peel s | raw K passes s | raw K passes at shadow size s | "
        "total / raw | coverage CPU s | "
        "open sky | exact |%s\n",
        o.accuracy ? " mean abs error | max abs error | CPU reference s |" : "");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|%s\n",
                o.accuracy ? "---|---|---|" : "");
    std::vector<std::string> scenes = o.scenes;
    if (scenes.empty()) {
      const std::filesystem::path root(SNOW_SOURCE_DIR);
      scenes.push_back((root / "assets/scenes/courtyard.glb").string());
      const std::filesystem::path shared = root / "../shared/scenes";
      for (const char* s : {"kenney-city/building-small-a.glb", "kenney-city/pavement-fountain.glb",
                            "kenney-city/road-straight-lightposts.glb",
                            "khronos/SheenChair/SheenChair.gltf", "khronos/ToyCar/ToyCar.gltf"}) {
        if (std::filesystem::exists(shared / s)) scenes.push_back((shared / s).string());
      }
    }
    if (o.big_only) scenes.clear();
    for (const std::string& path : scenes) {
      snow::LoadSettings ls;
      ls.load_images = false;
      const snow::Scene scene = snow::load_scene(path, ls);
      print(run(std::filesystem::path(path).filename().string(), scene, o.side, o), o);
    }
    if (o.big && (o.scenes.empty() || o.big_only)) {
      const snow::Scene big = snow::make_terrain(o.big_triangles).build();
      print(run("generated terrain", big, o.big_side, o), o);
    }
  } catch (const snow::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return e.exit_code();
  }
  return 0;
}
