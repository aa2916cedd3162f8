// `snowmodel snow IN -o OUT [options]`: the offline batch job. Load, peel,
// coverage, snowfall with stabilizing, polygonize, export
// (docs/ARCHITECTURE.md, "Pipeline and data"). This file turns flags into
// stage settings, asks the planner (src/plan) for the run's choices and
// calls the stages in order with them.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <optional>

#include <glm/glm.hpp>

#include "app/commands.h"
#include "app/filters.h"
#include "app/outputs.h"
#include "app/run_gl.h"
#include "app/settings.h"
#include "app/snow_warnings.h"
#include "app/snow_weather.h"
#include "app/tiles.h"
#include "app/tracks.h"
#include "core/error.h"
#include "core/fs.h"
#include "core/heap.h"
#include "core/log.h"
#include "mesh/export.h"
#include "mesh/far_ground.h"
#include "mesh/output_policy.h"
#include "mesh/write_maps.h"
#include "plan/plan.h"
#include "plan/rules.h"
#include "render/preview.h"
#include "scene/builder.h"
#include "scene/flat_ground.h"
#include "scene/load_gltf.h"
#include "snow/stabilize.h"

namespace snow::app {
namespace {
namespace fs = std::filesystem;

struct SnowOptions {
  MeshOutputs out;             // the input and what the run writes
  std::string tiles;           // "CxR": snow one tile of this split (app/tiles.h)
  int tile = -1;               // which one
  std::string tile_dir;        // where the tiles go
  std::string resume;          // maps folder of an earlier --weather run to continue from
  std::string sequence;        // folder for snow_0001.glb, ... every `every` hours
  double every = 0.0;          // hours between sequence frames
  bool sequence_maps = false;  // the sequence's maps too (maps_0001, ...)
  bool depth_given = false, steps_given = false, wind_given = false;
  PipelineSettings settings;
};

/// Places `tile` at (x, y) of `canvas`.
void blit(render::ImageRGBA8& canvas, const render::ImageRGBA8& tile, int x0, int y0) {
  for (int y = 0; y < tile.height; ++y) {
    std::copy_n(tile.at(0, y), size_t(tile.width) * 4,
                canvas.pixels.begin() + ((size_t(y0 + y) * size_t(canvas.width)) + size_t(x0)) * 4);
  }
}

/// Before (top row) and after (bottom row), 3/4 view (left) and top view
/// (right), in one PNG.
void write_preview(const Scene& scene, const std::vector<SnowPatch>& patches,
                   const fs::path& path) {
  std::vector<TriMesh> snow;
  snow.reserve(patches.size());
  for (const SnowPatch& p : patches) snow.push_back(p.mesh);
  render::PreviewSettings settings;
  settings.width = 960;
  settings.height = 640;
  render::ImageRGBA8 canvas;
  canvas.width = settings.width * 2;
  canvas.height = settings.height * 2;
  canvas.pixels.assign(size_t(canvas.width) * size_t(canvas.height) * 4, 255);
  const glm::vec4 snow_color(0.92f, 0.94f, 0.97f, 1.0f);
  Progress progress("preview", 4);
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 2; ++col) {
      settings.view = col == 0 ? render::View::ThreeQuarter : render::View::Top;
      const render::ImageRGBA8 tile = render::render_preview(
          scene, row == 0 ? std::vector<TriMesh>{} : snow, snow_color, settings);
      blit(canvas, tile, col * settings.width, row * settings.height);
      progress.update(row * 2 + col + 1);
    }
  }
  render::write_png(canvas, path);
}

double peak_memory_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

// Resident memory now (MiB; 0 where /proc is missing).
double resident_memory_mib() {
  long pages = 0, resident = 0;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return double(resident) * double(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

/// Wall time of each stage, and the memory after it (debug lines).
class StageClock {
 public:
  template <class Work>
  void run(const char* name, Work&& work) {
    const auto start = std::chrono::steady_clock::now();
    work();
    times_.push_back(
        {name, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()});
    char line[128];
    std::snprintf(line, sizeof line, "%s: memory %.0f MiB resident, %.0f MiB peak so far", name,
                  resident_memory_mib(), peak_memory_mib());
    log_debug(line);
  }
  /// The stages and their times in one line of text, and the total in seconds.
  std::pair<std::string, double> report() const {
    std::string text;
    double total = 0;
    for (const auto& [name, seconds] : times_) {
      char part[64];
      std::snprintf(part, sizeof part, "%s%s %.2f s", text.empty() ? "" : ", ", name.c_str(),
                    seconds);
      text += part;
      total += seconds;
    }
    return {text, total};
  }

 private:
  std::vector<std::pair<std::string, double>> times_;
};

/// A tile run's options: all three given, no other output, no weather.
/// Throws InputError naming the option.
void check_tile_options(const SnowOptions& o, const PipelineSettings& s) {
  if (o.tiles.empty() || o.tile < 0 || o.tile_dir.empty())
    throw InputError("a tile needs --tiles CxR, --tile I and --tile-dir DIR");
  parse_tiles(o.tiles, o.tile);
  const MeshOutputs& out = o.out;
  if (!out.output.empty() || !out.snow_output.empty() || !out.maps_dir.empty() ||
      !out.preview.empty()) {
    throw InputError("a tile writes into --tile-dir only: snowmodel merge writes the outputs");
  }
  if (!s.weather.empty()) throw InputError("--tiles and --weather: tiles snow one snowfall");
  std::error_code ec;
  if (fs::exists(o.tile_dir, ec) && !fs::is_directory(o.tile_dir, ec))
    throw IOError("cannot write the tiles to " + o.tile_dir + ": a file is there");
}

/// The pipeline settings of a run, checked before the long work starts
/// (bad settings and output paths fail in milliseconds, not after minutes
/// of peeling and shadows). Returns the settings with the derived fields
/// set, and the format of --output in `format`.
PipelineSettings checked_settings(const SnowOptions& o, MeshFormat& format) {
  const bool tiled = !o.tiles.empty() || o.tile >= 0 || !o.tile_dir.empty();
  if (!tiled && o.out.output.empty() && o.out.snow_output.empty() && o.out.maps_dir.empty() &&
      o.out.preview.empty()) {
    throw InputError("nothing to write: give -o OUT, --snow-output, --maps or --preview");
  }
  PipelineSettings s = o.settings;
  check_settings(s);  // flags and --config alike
  resolve_snow_settings(s);
  s.peel.memory_budget = memory_budget_bytes(s.memory_budget_gib);
  s.load.limits.memory_budget = s.peel.memory_budget;  // the scene's data, images included
  s.stabilize.seed = uint32_t(s.coverage.seed);
  if (tiled && wants_tracks(s)) {
    throw InputError("--tiles and --track/--clear: tracks are made on the whole scene");
  }
  if (tiled) check_tile_options(o, s);
  format = check_outputs(o.out);
  check_stabilize_settings(s.stabilize);
  fall_directions(s.coverage);  // checks the coverage settings
  if (s.weather.empty()) {
    for (const auto& [given, flag] : {std::pair{!o.resume.empty(), "--resume"},
                                      {!o.sequence.empty(), "--sequence"},
                                      {s.track_hour >= 0.0, "--track-hour"}}) {
      if (given) throw InputError(std::string(flag) + " needs --weather");
    }
  } else {
    for (const auto& [given, flag] : {std::pair{o.depth_given, "--depth"},
                                      {o.steps_given, "--steps"},
                                      {o.wind_given, "--wind"}}) {
      if (given) throw InputError(std::string(flag) + " and --weather both give the snowfall");
    }
  }
  if (!o.sequence.empty() && !(o.every > 0.0)) {
    throw InputError("--sequence needs --every HOURS (> 0)");
  }
  if (!o.sequence.empty() && fs::exists(o.sequence) && !fs::is_directory(o.sequence)) {
    throw IOError("cannot write the sequence to " + o.sequence + ": a file is there");
  }
  return s;
}

/// The closing summary line.
void log_summary(const StageClock& clock, size_t triangles_in,
                 const std::vector<SnowPatch>& patches, const SnowResult& snow, bool gl_used,
                 bool weather) {
  size_t triangles_out = 0;
  for (const SnowPatch& p : patches) triangles_out += p.mesh.indices.size() / 3;
  const auto [timing, total] = clock.report();
  std::string drift;
  if (snow.drifted > 0.0) {
    char part[160];
    std::snprintf(part, sizeof part, "; the wind moved %.3f, carried in %.3f and out %.3f",
                  snow.drifted, snow.drifted_in, snow.drifted_out);
    drift = part;
  }
  char balance[320];
  if (weather) {
    std::snprintf(balance, sizeof balance,
                  "%.3f m^3 (%.3f fell fresh; settling and melt shrink it: the water balance is "
                  "on the weather line)",
                  snow.volume, snow.fallen_volume);
  } else {
    std::snprintf(balance, sizeof balance, "%.3f m^3 (fell %.3f, lost off the domain %.3f%s)",
                  snow.volume, snow.fallen_volume, snow.lost_volume, drift.c_str());
  }
  char summary[800];
  std::snprintf(summary, sizeof summary,
                "summary: %.2f s (%s); peak memory %.0f MiB; triangles in %zu, snow out %zu in %zu "
                "patches; snow %s; coverage by %s; stabilizer %d passes on the %s%s",
                total, timing.c_str(), peak_memory_mib(), triangles_in, triangles_out,
                patches.size(), balance,
                snow.coverage_method == CoverageMethod::CpuRays         ? "rays on the CPU"
                : snow.coverage_method == CoverageMethod::GpuRays       ? "rays on the GPU"
                : snow.coverage_method == CoverageMethod::CpuShadowMaps ? "shadow maps on the CPU"
                                                                        : "shadow maps",
                snow.iterations, snow.stabilized_on_cpu ? "CPU" : "GPU",
                gl_used ? "" : "; OpenGL not started");
  log_info(summary);
}

/// Turns the heap's huge pages off where the plan says so (core/heap.h),
/// saying so when it does.
void fit_heap(bool off) {
  if (off && turn_off_huge_pages()) {
    log_debug(
        "heap: transparent huge pages off from here on: a large job on a machine that hands "
        "free memory back to its host (core/heap.h)");
  }
}

/// The maps' part of a scene on a big flat ground: where the planner says
/// so (plan::detail_margin), the detail and a margin around it; the ground
/// beyond gets an even cover (mesh/far_ground.h).
struct DetailMaps {
  FlatGround ground;
  Bounds region;  // x, z of the maps; y unused
};

std::optional<DetailMaps> detail_maps(const Scene& scene, const CoverageSettings& coverage) {
  const std::optional<FlatGround> ground = find_flat_ground(scene);
  if (!ground) return std::nullopt;
  const glm::vec3 g = ground->bounds.size(), d = ground->detail.size();
  const double tilt =
      std::acos(std::clamp(-double(mean_fall_direction(coverage).y), -1.0, 1.0)) * 180.0 / M_PI +
      double(coverage.flutter_deg);
  const double margin = plan::detail_margin(std::max(g.x, g.z), std::max(d.x, d.z),
                                            double(ground->detail.max.y - ground->y), tilt);
  if (margin < 0.0) return std::nullopt;
  DetailMaps out{*ground, {}};
  const float m = float(margin);
  out.region.min = glm::max(ground->detail.min - glm::vec3(m), ground->bounds.min);
  out.region.max = glm::min(ground->detail.max + glm::vec3(m), ground->bounds.max);
  // The far cover needs room on every side.
  if (out.region.min.x <= ground->bounds.min.x || out.region.max.x >= ground->bounds.max.x ||
      out.region.min.z <= ground->bounds.min.z || out.region.max.z >= ground->bounds.max.z) {
    return std::nullopt;
  }
  return out;
}

/// What the wind does in this run, in one line (none without wind).
void log_wind(const PipelineSettings& s) {
  const double speed = glm::length(glm::dvec2(s.coverage.wind));
  if (!(speed > 0.0)) return;
  char line[256];
  if (s.accumulate.drift.transport > 0.0f) {
    std::snprintf(line, sizeof line,
                  "wind: %.3g m/s blows %s snow into drifts (it carries %.3g m of the fallen snow "
                  "per metre of width)",
                  speed, s.snow_kind.c_str(), double(s.accumulate.drift.transport));
  } else if (!s.wind_transport) {
    std::snprintf(line, sizeof line, "wind: %.3g m/s tilts the fall; transport is off", speed);
  } else {
    std::snprintf(line, sizeof line,
                  "wind: %.3g m/s tilts the fall; it is too light to move %s snow", speed,
                  s.snow_kind.c_str());
  }
  log_info(line);
}

/// The depth (m) of the snow on open ground, for the even cover beyond
/// the detail maps of a weather run: the median over layer 0's texels of
/// the ground object `object`.
float open_ground_depth(const SnowMaps& maps, const std::vector<float>& depth, int object) {
  std::vector<float> values;
  for (size_t t = 0; t < maps.grid.texels(); ++t) {
    if (maps.object[t] == object) values.push_back(depth[t]);
  }
  if (values.empty()) return 0.0f;
  auto middle = values.begin() + ptrdiff_t(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

/// Writes a weather run's sequence frame `number` into o.sequence: the snow
/// (snow_0001.glb, ...) in the file's frame, and with --sequence-maps its
/// maps (maps_0001, ...).
void write_sequence_frame(const SnowOptions& o, int number, double hour, const SnowPack& pack,
                          const SnowMaps& maps, const Scene& scene, const PolygonizeSettings& poly,
                          const FileFrame& frame) {
  char stem[32];
  std::snprintf(stem, sizeof stem, "%04d", number);
  std::vector<SnowPatch> patches = polygonize(maps, pack.depth, scene, poly);
  for (SnowPatch& p : patches) to_file_frame(p.mesh, frame);
  const fs::path dir(o.sequence);
  write_snow_meshes(patches, dir / (std::string("snow_") + stem + ".glb"), MeshFormat::Glb);
  if (o.sequence_maps) {
    std::vector<std::vector<float>> storage;
    const MapsSnowpack snowpack = maps_snowpack(pack, hour, storage);
    write_maps(dir / (std::string("maps_") + stem), maps, nullptr, &pack.depth, &snowpack);
  }
  char line[160];
  std::snprintf(line, sizeof line, "sequence: frame %d at hour %.6g, %zu snow patches", number,
                hour, patches.size());
  log_info(line);
}

void log_plan(const plan::RunPlan& run) {
  for (const std::string& line : plan::describe(run)) log_debug(line);
}

/// Tile `spec` of the untiled run's grid of `scene` with the halo its
/// settings need (plan::tile_halo).
TilePlan tile_of(const Scene& scene, const PipelineSettings& s, const TileSpec& spec) {
  const Bounds& b = scene.bounds;
  const bool wind = s.wind_transport && glm::length(s.coverage.wind) > 0.0f;
  return plan_tile(make_grid(b, s.peel), spec,
                   plan::tile_halo(double(b.max.y) - double(b.min.y), wind));
}

/// Writes a tile run's tile (app/tiles.h) and says where it went.
void write_tile_of_run(const SnowOptions& o, const TilePlan& plan, const SnowMaps& maps,
                       const SnowResult& snow, const Scene& scene, const PipelineSettings& s,
                       const FileFrame& frame) {
  write_tile(o.tile_dir, plan, maps, snow.coverage, snow.depth,
             {fs::absolute(o.out.input).string(), settings_to_json(o.settings).dump(), &scene,
              s.polygonize, frame});
  char line[300];
  std::snprintf(line, sizeof line,
                "wrote tile %d of %d x %d (texels %d..%d x %d..%d, halo %.3g m) to %s",
                plan.spec.index, plan.spec.columns, plan.spec.rows, plan.i0, plan.i1 - 1, plan.j0,
                plan.j1 - 1, double(plan.halo), tile_folder(o.tile_dir, plan.spec.index).c_str());
  log_info(line);
}

void run_snow(const SnowOptions& o, const GlobalOptions& global) {
  MeshFormat format = MeshFormat::Glb;
  PipelineSettings s = checked_settings(o, format);
  std::optional<WeatherRun> weather = weather_run_of(s);
  if (weather) {
    s.accumulate.fall_depth = weather_fall_depth(*weather);
    if (!o.sequence.empty()) fs::create_directories(o.sequence);
  }
  const FileFrame frame = file_frame(s);
  if (!weather) log_wind(s);
  StageClock clock;

  // The machine's facts; the renderer is probed beside the load.
  gl::ContextOptions context_options;
  context_options.backend = gl::parse_backend(global.gl_backend);
  const uint64_t input_bytes = gltf_input_bytes(o.out.input);
  const plan::MachineInfo machine = plan::probe_machine(context_options);
  RunGl gl(global, machine, input_bytes);
  // Textures, normals and UVs only show in the preview.
  s.load.load_images = s.load.shading = !o.out.preview.empty();
  fit_heap(plan::huge_pages_off(machine, input_bytes, 0));
  // The scene plus snow is written from the input's JSON as the loader
  // parsed it, planned right after the load (a refused buffer fails now,
  // not after the snow); the loader's copy is then freed.
  const bool combined = !o.out.output.empty() && !o.out.snow_only &&
                        (format == MeshFormat::Glb || format == MeshFormat::Gltf);
  s.load.keep_source = combined;
  s.load.lines = s.load.motions = wants_tracks(s);
  Scene scene;
  CombinedInputPtr combined_input;
  clock.run("load", [&] {
    scene = load_scene(o.out.input, s.load);
    if (combined) combined_input = plan_combined_gltf(*scene.source);
    scene.source.reset();
    to_metres_y_up(scene, frame);
  });
  warn_unmatched(scene, s.ignore, "--ignore");
  warn_unmatched(scene, s.no_snow_on, "--no-snow-on");
  const size_t triangles_in = scene.triangle_count();
  const Scene snow_scene =
      without_sky_enclosures(without_ignored(std::move(scene), s.ignore), s.keep_enclosures);
  const std::vector<uint8_t> receives = receiving_objects(snow_scene, s.no_snow_on);
  warn_unmatched(snow_scene, s.slippery, "--slippery");
  warn_unmatched(snow_scene, s.rough, "--rough");
  s.stabilize.grip = object_grip(snow_scene, s.slippery, s.rough);
  warn_if_not_metres_y_up(snow_scene);
  warn_if_out_of_scale(snow_scene, s.accumulate.fall_depth);
  warn_if_imprecise(snow_scene, s.accumulate.fall_depth);

  // Small objects on a big flat ground: maps over the detail alone (a
  // tile's maps are a part of the untiled run's).
  const std::optional<TileSpec> tile =
      o.tiles.empty() ? std::nullopt : std::optional<TileSpec>(parse_tiles(o.tiles, o.tile));
  const std::optional<DetailMaps> detail =
      tile ? std::nullopt : detail_maps(snow_scene, s.coverage);
  Scene clipped;
  if (detail) {
    clipped = with_ground_clipped(snow_scene, detail->ground, detail->region);
    s.peel.margin = 0.0f;
    s.polygonize.open_beyond = detail->region;
  }
  const Scene& map_scene = detail ? clipped : snow_scene;

  // The plan: the maps' size and where each stage runs.
  const plan::Settings wanted = plan_settings(s);
  const plan::SceneStats stats = scene_stats(map_scene, s.peel, wanted, input_bytes);
  plan::RunPlan run = plan::plan_run(stats, gl.machine(), wanted, gl.warming());
  if (!run.maps.note.empty()) log_info(run.maps.note);
  log_plan(run);
  s.peel.max_side = run.maps.max_side;
  fit_heap(run.huge_pages_off);
  // The coverage's BVH needs the scene alone: where the plan says so, it is
  // built on another thread while the peel runs.
  std::future<CoverageBvh> bvh_ahead;
  const auto build_bvh_ahead = [&] {
    bvh_ahead = std::async(std::launch::async, [&] {
      return build_coverage_bvh(map_scene, run.bvh_morton ? Bvh::Build::Morton : Bvh::Build::Sah);
    });
  };
  if (run.bvh_ahead) build_bvh_ahead();

  SnowMaps maps;
  TilePlan tile_plan;
  plan::GlFacts gl_after_peel;
  clock.run("peel", [&] {
    const auto context = gl.stage_context(run.gl.software);
    if (gl.learn_renderer()) {  // the peel's context told the renderer: plan again
      run = plan::plan_run(stats, gl.machine(), wanted, true);
      log_plan(run);
      if (run.bvh_ahead) build_bvh_ahead();
    }
    if (tile) {
      tile_plan = tile_of(map_scene, s, *tile);
      maps = peel_layers(map_scene, tile_plan.grid, s.peel, run.gl);
    } else {
      maps = peel_layers(map_scene, s.peel, run.gl);
    }
    if (detail) {
      const glm::vec3 r = detail->region.size(), g = detail->ground.bounds.size();
      char line[400];
      std::snprintf(line, sizeof line,
                    "maps: two levels: the detail and its surroundings, %.4g x %.4g m at %.3g m "
                    "texels; the open ground '%s' beyond (%.4g x %.4g m) under an even cover",
                    double(r.x), double(r.z), double(maps.grid.texel),
                    snow_scene.objects[size_t(detail->ground.object)].name.c_str(), double(g.x),
                    double(g.z));
      log_info(line);
    }
    gl_after_peel = {run.gl.software, run.gl.started || context->made()};
  });
  log_info("maps: " + std::to_string(maps.grid.width) + " x " + std::to_string(maps.grid.height) +
           " texels of " + std::to_string(maps.grid.texel) + " m, " + std::to_string(maps.layers) +
           " layers");
  warn_if_deep_in_texels(maps, s.accumulate.fall_depth);

  const std::vector<TrackSource> tracks =
      wants_tracks(s) ? track_sources(map_scene, s, maps.grid.texel) : std::vector<TrackSource>{};
  std::vector<float> compaction;  // per layer texel, where tracks were made

  SnowResult snow;
  std::optional<SnowPack> pack;  // a weather run's
  double pack_hour = 0.0;        // hours of weather behind it
  clock.run("snowfall", [&] {
    const auto context = gl.stage_context(run.gl.software);
    std::optional<CoverageBvh> bvh;
    if (bvh_ahead.valid()) {
      try {
        bvh = bvh_ahead.get();
      } catch (const std::bad_alloc&) {
        throw InputError("coverage: out of memory building the BVH of " +
                         std::to_string(snow_scene.triangle_count()) + " triangles");
      }
    }
    if (!weather) {
      snow = accumulate(map_scene, maps, s.coverage, s.stabilize, s.accumulate, gl_after_peel,
                        receives, bvh ? &*bvh : nullptr);
      return;
    }
    pack = starting_pack(o.resume, maps, weather->steps.front().hour, pack_hour);
    if (!o.sequence.empty()) {
      weather->every_hours = o.every;
      weather->on_frame = [&](int number, double hour, const SnowPack& now) {
        write_sequence_frame(o, number, hour, now, maps, map_scene, s.polygonize, frame);
      };
    }
    if (!tracks.empty()) tracks_in_weather(*weather, maps, tracks, s, compaction);
    snow = accumulate_weather(map_scene, maps, s.coverage, s.stabilize, *weather, *pack,
                              gl_after_peel, receives, bvh ? &*bvh : nullptr);
    pack_hour = weather->steps.back().hour + weather->steps.back().hours;
  });
  if (!weather && !tracks.empty()) {
    clock.run("tracks", [&] { compaction = tracks_in_snow(snow, maps, tracks, s); });
  }
  warn_if_unsettled(snow, s.stabilize);
  warn_if_sheltered(map_scene, maps, snow.coverage);
  if (tile) {
    clock.run("export", [&] { write_tile_of_run(o, tile_plan, maps, snow, map_scene, s, frame); });
    return;
  }

  std::vector<SnowPatch> patches;
  clock.run("polygonize", [&] { patches = polygonize(maps, snow.depth, map_scene, s.polygonize); });
  const float far_depth =
      pack ? open_ground_depth(maps, pack->depth, detail ? detail->ground.object : -1)
           : s.accumulate.fall_depth;
  if (detail && far_depth > 0.0f) {
    const SceneObject& g = snow_scene.objects[size_t(detail->ground.object)];
    patches.push_back(far_ground_snow(detail->ground, detail->region, far_depth,
                                      2.0f * maps.grid.texel, kFarGroundSeam,
                                      s.polygonize.bottom_offset, "snow/" + g.name + "/beyond"));
    snow.fallen_volume += patches.back().depth_volume;
    snow.volume += patches.back().depth_volume;
  }
  if (patches.empty()) warn_no_patches(snow, s.polygonize);
  clock.run("export", [&] {
    std::vector<std::vector<float>> storage;
    std::optional<MapsSnowpack> snowpack;
    if (pack) snowpack = maps_snowpack(*pack, pack_hour, storage);
    MapsExtra extra;
    if (!compaction.empty()) extra.values.push_back({"compaction", &compaction, "share"});
    write_outputs(o.out, format, std::move(combined_input), patches, frame, maps, &snow.coverage,
                  &snow.depth, snowpack ? &*snowpack : nullptr, settings_to_json(o.settings),
                  &extra);
  });
  if (!o.out.preview.empty()) {
    clock.run("preview", [&] {
      const auto context = gl.context();
      write_preview(snow_scene, patches, o.out.preview);
    });
    log_info("wrote " + o.out.preview);
  }
  log_summary(clock, triangles_in, patches, snow, gl.used(), pack.has_value());
}

}  // namespace

void register_snow(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<SnowOptions>();
  o->settings.peel.max_side = 0;  // automatic (choose_automatic_side); --max-side overrides
  CLI::App* cmd = app.add_subcommand(
      "snow", "Snow a glTF scene: compute where snow lands and rests, write it as meshes");
  // --config first: CLI11 applies options in the order they were added, so
  // flags given on the command line override the file.
  cmd->add_option_function<std::string>(
         "--config", [o](const std::string& path) { load_settings_file(path, o->settings); },
         "JSON settings file (as written beside outputs: OUT.settings.json); flags override it")
      ->check(CLI::ExistingFile);
  cmd->add_option("input", o->out.input, "glTF 2.0 scene (.gltf or .glb)")->required();
  add_output_options(*cmd, o->out, true);
  add_settings_options(*cmd, o->settings, global.help_all);
  cmd->add_option("--resume", o->resume,
                  "Continue a --weather run from the --maps folder an earlier one wrote (same "
                  "scene and maps settings)")
      ->group("Weather over time");
  cmd->add_option("--sequence", o->sequence,
                  "Write the snow every --every hours of a --weather run into this folder "
                  "(snow_0001.glb, ...)")
      ->group("Weather over time");
  cmd->add_option("--every", o->every, "Hours between --sequence frames")
      ->check(CLI::Range(0.01, 1e6))
      ->group("Weather over time");
  cmd->add_flag("--sequence-maps", o->sequence_maps,
                "Write each --sequence frame's maps too (maps_0001, ...)")
      ->group("Weather over time");
  cmd->add_option("--tiles", o->tiles,
                  "Snow one tile of this COLUMNSxROWS split of the maps (with --tile and "
                  "--tile-dir); snowmodel merge joins the tiles")
      ->group("City scale");
  cmd->add_option("--tile", o->tile, "The tile to snow: 0 .. COLUMNS*ROWS-1, row by row")
      ->group("City scale");
  cmd->add_option("--tile-dir", o->tile_dir, "Folder of the tiles (tile_0000, ...)")
      ->group("City scale");
  cmd->add_flag("--help-all", "Print this help with the developer options (backends, speed-ups)");
  cmd->callback([o, &global, cmd] {
    o->depth_given = cmd->count("--depth") > 0;
    o->steps_given = cmd->count("--steps") > 0;
    o->wind_given = cmd->count("--wind") > 0;
    run_snow(*o, global);
  });
}

}  // namespace snow::app
