// Benchmark of stage 3, the stabilizer (src/snow/stabilize.h): iterations to
// converge and time per iteration on the GL renderer at hand, for a canned
// scene or a glTF file with 0.3 m (--depth) of snow on every top surface,
// or with --coverage on that depth times the default coverage, as a one-step
// snowfall lays it.
// Results: tools/RESULTS.md.
//
//   snowmodel_bench_stabilize [--scene courtyard|house60|house30|FILE] [--side N]
//                             [--layers L] [--depth METRES] [--max-stride S] [--passes P]
//                             [--tiles on|off] [--count-tiles on|off]
//                             [--max-iterations N] [--route on|off]
//                             [--trace P] [--backend gpu|cpu] [--coverage on|off]
//                             [--probe I,J,R]
// With --passes P, runs exactly P passes (tolerance 0) to time them;
// otherwise runs to convergence (default settings). --tiles off computes
// every texel in every pass (StabilizeSettings::active_tiles = false).
// Routing (before the first pass) and relaxation are timed apart.
// --route off skips the routing
// (StabilizeSettings::route_steep = false), to time passes on maps too large
// to route with full passes. --trace P prints the residual, routed volume,
// routing passes, drains and pours,
// elapsed time and share of tiles computed (with --count-tiles on) every P
// passes (stderr), to see where the passes go. --backend cpu runs the
// CpuStabilizer (src/snow/stabilize_cpu.h) instead of the GPU passes.
// With --trace, --probe I,J,R also prints after each chunk the layer texels
// of the columns within R of column (I, J): ground, ceiling, normal's y and
// depth, top down.
// It also prints a pass against the memory-bandwidth bound (issue 52): the
// least a pass must move is every layer texel's depth read and written and
// its ground and ceiling read (kBoundBytesPerTexel), at the rate the device
// copies memory (a GL buffer copy for the GPU backend, memcpy for the CPU
// one); time full passes with --passes P --tiles off.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/heap.h"
#include "core/log.h"
#include "gl/context.h"
#include "gl/objects.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "snow/coverage.h"
#include "snow/peel.h"
#include "snow/stabilize.h"
#include "snow/stabilize_cpu.h"

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Bytes a stabilizer pass moves at least per layer texel: depth read and
/// written (2 x 4 B), ground and ceiling read (2 x 4 B).
constexpr double kBoundBytesPerTexel = 16.0;
/// Bytes copied to measure the copy rate, and the copies (the best is kept).
constexpr size_t kCopyBytes = size_t(256) << 20;
constexpr int kCopies = 5;

/// Bytes per second the device moves copying kCopyBytes (read + write
/// counted), the best of kCopies: a GL buffer copy (gpu) or memcpy (cpu).
double copy_rate(bool gl) {
  double best = 0.0;
  if (gl) {
    snow::gl::Buffer from = snow::gl::create_buffer(), to = snow::gl::create_buffer();
    glNamedBufferData(from.id(), GLsizeiptr(kCopyBytes), nullptr, GL_STATIC_DRAW);
    glNamedBufferData(to.id(), GLsizeiptr(kCopyBytes), nullptr, GL_STATIC_DRAW);
    const GLuint zero = 0;
    glClearNamedBufferData(from.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    glClearNamedBufferData(to.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    glFinish();
    for (int c = 0; c < kCopies; ++c) {
      const auto t0 = std::chrono::steady_clock::now();
      glCopyNamedBufferSubData(from.id(), to.id(), 0, 0, GLsizeiptr(kCopyBytes));
      glFinish();
      best = std::max(best, 2.0 * double(kCopyBytes) / seconds_since(t0));
    }
  } else {
    std::vector<char> from(kCopyBytes, 1), to(kCopyBytes, 0);
    for (int c = 0; c < kCopies; ++c) {
      const auto t0 = std::chrono::steady_clock::now();
      std::memcpy(to.data(), from.data(), kCopyBytes);
      best = std::max(best, 2.0 * double(kCopyBytes) / seconds_since(t0));
    }
    if (to[kCopyBytes / 2] != 1) std::abort();  // the copies are kept
  }
  return best;
}

}  // namespace

struct Options {
  std::string scene_name = "courtyard";
  int side = 1024, layers = 4, passes = -1, trace = 0;
  float snow_depth = 0.3f;
  std::string backend = "gpu";
  bool with_coverage = false;
  int probe_i = 0, probe_j = 0, probe_r = -1;
  snow::StabilizeSettings settings;
};

// Parses the command line into `o`; returns -1 to go on, else the exit code.
int parse_options(int argc, char** argv, Options& o) {
  for (int a = 1; a < argc; a += 2) {
    const std::string key = argv[a];
    if (key == "-h" || key == "--help" || a + 1 == argc) {
      std::fprintf(key == "-h" || key == "--help" ? stdout : stderr,
                   "usage: snowmodel_bench_stabilize [--scene courtyard|house60|house30|FILE.glb] "
                   "[--side N] [--layers L]\n  [--depth METRES] [--max-stride S] [--passes P] "
                   "[--tiles on|off] "
                   "[--count-tiles on|off] [--max-iterations N]\n  [--route on|off] [--trace P] "
                   "[--backend gpu|cpu] [--coverage on|off] [--probe I,J,R]\n");
      return key == "-h" || key == "--help" ? 0 : 2;
    }
    const char* value = argv[a + 1];
    const bool on = std::strcmp(value, "off") != 0;
    if (key == "--scene")
      o.scene_name = value;
    else if (key == "--side")
      o.side = std::atoi(value);
    else if (key == "--layers")
      o.layers = std::atoi(value);
    else if (key == "--depth")
      o.snow_depth = float(std::atof(value));
    else if (key == "--max-stride")
      o.settings.max_stride = std::atoi(value);
    else if (key == "--passes")
      o.passes = std::atoi(value);
    else if (key == "--max-iterations")
      o.settings.max_iterations = std::atoi(value);
    else if (key == "--tiles")
      o.settings.active_tiles = on;
    else if (key == "--route")
      o.settings.route_steep = on;
    else if (key == "--trace")
      o.trace = std::atoi(value);
    else if (key == "--backend")
      o.backend = value;
    else if (key == "--probe")
      std::sscanf(value, "%d,%d,%d", &o.probe_i, &o.probe_j, &o.probe_r);
    else if (key == "--coverage")
      o.with_coverage = on;
    else if (key == "--count-tiles")
      o.settings.count_tiles = on;
    else {
      std::fprintf(stderr, "unknown option %s\n", key.c_str());
      return 2;
    }
  }
  return -1;
}

snow::Scene bench_scene(const std::string& name) {
  using namespace snow;
  if (name == "courtyard") return make_courtyard().build();
  if (name == "house60") return make_house_scene(60.0f);
  if (name == "house30") return make_house_scene(30.0f);
  if (std::filesystem::exists(name)) return load_scene(name);
  throw InputError("unknown scene " + name + " (not a built-in scene nor a file)");
}

// The surfaces and depths of the texels within `o.probe_r` of (probe_i, probe_j).
void print_probe(const Options& o, const snow::SnowMaps& maps, const std::vector<float>& depth) {
  for (int jj = std::max(0, o.probe_j - o.probe_r);
       jj <= std::min(maps.grid.height - 1, o.probe_j + o.probe_r); ++jj) {
    for (int ii = std::max(0, o.probe_i - o.probe_r);
         ii <= std::min(maps.grid.width - 1, o.probe_i + o.probe_r); ++ii) {
      std::fprintf(stderr, "  (%d,%d)", ii, jj);
      for (int l = 0; l < maps.layers; ++l) {
        const size_t k = maps.index(l, ii, jj);
        if (std::isnan(maps.ground[k])) break;
        std::fprintf(stderr, " [%d g%.6g c%.6g n%.2f d%.6g]", l, maps.ground[k], maps.ceiling[k],
                     maps.normal[k].y, depth[k]);
      }
      std::fprintf(stderr, "\n");
    }
  }
}

int main(int argc, char** argv) {
  snow::tune_heap(argv);  // as snowmodel does, so the timings compare
  using namespace snow;
  Options o;
  if (const int code = parse_options(argc, argv, o); code >= 0) return code;
  StabilizeSettings& settings = o.settings;
  const std::string& scene_name = o.scene_name;
  const int side = o.side, layers = o.layers, passes = o.passes, trace = o.trace;
  const float snow_depth = o.snow_depth;
  try {
    set_log_level(LogLevel::Warn);
    auto context = gl::create_context();
    const Scene scene = bench_scene(scene_name);

    PeelSettings peel;
    peel.max_side = side;
    peel.layers = layers;
    // As snowmodel does.
    if (plan::huge_pages_off(plan::probe_machine({}), 0, make_grid(scene.bounds, peel).texels()))
      turn_off_huge_pages();
    auto t0 = std::chrono::steady_clock::now();
    const SnowMaps maps = peel_layers(scene, peel, plan::current_gl());
    const double peel_s = seconds_since(t0);
    std::vector<float> depth(size_t(maps.layers) * maps.grid.texels(), 0.0f);
    if (o.with_coverage) {
      // The snow of a one-step snowfall with the default coverage, none
      // under the bridges (as snowmodel's snowfall: mask_coverage).
      depth = compute_coverage(scene, maps, CoverageSettings{}, plan::current_gl());
      mask_coverage(maps, {}, depth);
      for (float& d : depth) d *= snow_depth;
    } else {
      for (int j = 0; j < maps.grid.height; ++j) {
        for (int i = 0; i < maps.grid.width; ++i) {
          if (maps.has_surface(0, i, j)) depth[maps.index(0, i, j)] = snow_depth;
        }
      }
    }
    if (passes >= 0) {
      settings.tolerance = 0.0f;
      settings.max_iterations = passes;
    }
    double setup_s = 0, route_s = 0, total_s = 0;
    StabilizeResult route, r;
    auto run = [&](auto tag) {
      using StabilizerType = typename decltype(tag)::type;
      t0 = std::chrono::steady_clock::now();
      StabilizerType stabilizer(maps, settings);
      stabilizer.set_depth(depth);
      setup_s = seconds_since(t0);
      t0 = std::chrono::steady_clock::now();
      route = stabilizer.iterate(0);  // routing only
      route_s = seconds_since(t0);
      t0 = std::chrono::steady_clock::now();
      if (trace > 0) {
        // The passes in chunks of `trace` (each chunk ends with a convergence
        // check, as iterate() does), summed as one call would report them.
        // Also where the depth changed most over the chunk: layer, texel,
        // object, ground height, depth.
        StabilizeResult sum;
        std::vector<float> before = stabilizer.depth();
        while (sum.iterations < settings.max_iterations && !sum.converged) {
          r = stabilizer.iterate(std::min(trace, settings.max_iterations - sum.iterations));
          sum.add(r);
          const std::vector<float> after = stabilizer.depth();
          size_t most = 0;
          for (size_t k = 0; k < after.size(); ++k) {
            if (std::abs(after[k] - before[k]) > std::abs(after[most] - before[most])) most = k;
          }
          const int l = int(most / maps.grid.texels());
          const int i = int(most % maps.grid.texels()) % maps.grid.width;
          const int j = int(most % maps.grid.texels()) / maps.grid.width;
          const int32_t object = maps.object[most];
          std::fprintf(stderr,
                       "pass %d residual %.3e m routed %.4f m^3 (%d passes, %d of creep, %d "
                       "drains, %d pours) "
                       "%.1f s, "
                       "tiles %.1f %%; largest "
                       "change %.2e m at layer %d (%d, %d) on %s, ground %.3f m, depth %.4f m\n",
                       sum.iterations, r.residual, r.routed_volume, r.route_passes, r.creep_routes,
                       r.drains, r.pours, seconds_since(t0), 100.0 * r.tile_share,
                       after[most] - before[most], l, i, j,
                       object >= 0 ? scene.objects[size_t(object)].name.c_str() : "-",
                       maps.ground[most], after[most]);
          before = after;
          if (o.probe_r >= 0) print_probe(o, maps, after);
        }
        r = sum;
      } else {
        r = stabilizer.iterate(settings.max_iterations);
      }
      total_s = seconds_since(t0);
    };
    if (o.backend == "gpu")
      run(std::common_type<Stabilizer>{});
    else if (o.backend == "cpu")
      run(std::common_type<CpuStabilizer>{});
    else
      throw InputError("unknown backend " + o.backend + " (gpu or cpu)");
    std::printf(
        "renderer: %s\nscene %s, %d x %d texels (%.4f m), %d layers, max_stride %d, tiles %s\n"
        "peel %.2f s, upload %.2f s, routing %d passes %.2f s (%.3f m^3 routed)\n"
        "relaxation: %d passes, converged %s, residual %.2e m, %.2f s, %.1f ms per pass; "
        "total %.2f s; tiles computed %.1f %%\n"
        "volume %.3f m^3, lost %.3f m^3\n",
        context->description().c_str(), scene_name.c_str(), maps.grid.width, maps.grid.height,
        maps.grid.texel, maps.layers, settings.max_stride, settings.active_tiles ? "on" : "off",
        peel_s, setup_s, route.route_passes, route_s, route.routed_volume, r.iterations,
        r.converged ? "yes" : "no", r.residual, total_s,
        1000.0 * total_s / std::max(1, r.iterations), route_s + total_s, 100.0 * r.tile_share,
        r.volume, route.lost_volume + r.lost_volume);
    const double bytes = kBoundBytesPerTexel * double(maps.layers) * double(maps.grid.texels());
    const double rate = copy_rate(o.backend == "gpu");
    const double pass_s = total_s / std::max(1, r.iterations), bound_s = bytes / rate;
    std::printf(
        "memory bound: %.0f MB a pass at %.1f GB/s (%s) = %.2f ms; a pass %.2f ms = %.1fx the "
        "bound\n",
        bytes / 1e6, rate / 1e9, o.backend == "gpu" ? "GL buffer copy" : "memcpy", 1000.0 * bound_s,
        1000.0 * pass_s, pass_s / bound_s);
  } catch (const Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return e.exit_code();
  }
  return 0;
}
