// `snowmodel snow IN -o OUT [options]`: the offline batch job. Load, peel,
// coverage, snowfall with stabilizing, polygonize, export (DESIGN.md,
// "Pipeline and data"). This file only turns flags into stage settings and
// calls the stages in order.
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
#include "app/settings.h"
#include "core/error.h"
#include "core/fs.h"
#include "core/heap.h"
#include "core/log.h"
#include "mesh/export.h"
#include "mesh/write_maps.h"
#include "render/preview.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "plan/plan.h"
#include "snow/stabilize.h"

namespace snow::app {
namespace {
namespace fs = std::filesystem;

struct SnowOptions {
  std::string input;
  std::string output;       // input scene + snow (glb/gltf), or snow only for obj/ply
  std::string snow_output;  // snow only
  std::string format;       // overrides the extension of --output
  std::string maps_dir;
  std::string preview;
  std::string config;
  bool snow_only = false;
  PipelineSettings settings;
};

/// Warns when the fresh snow is deep against the scene's size. glTF units
/// are metres; a model made in other units (a building tile 1 unit wide)
/// gets snow out of scale, and stabilizing takes passes growing with the
/// square of the snow's depth in texels.
void warn_if_out_of_scale(const Scene& scene, float fall_depth) {
  const glm::vec3 size = scene.bounds.max - scene.bounds.min;
  const float width = std::max(size.x, size.z);
  if (!(width > 0) || fall_depth <= 0.1f * width) return;
  char line[300];
  std::snprintf(line, sizeof line,
                "snow depth %.3g m is %.0f %% of the scene's width (%.3g m); glTF units are "
                "metres: if the scene is not to scale, lower --depth",
                double(fall_depth), 100.0 * double(fall_depth / width), double(width));
  log_warn(line);
}

/// Warns when the scene lies so far from the origin that 32-bit floats (as
/// glTF stores them, and as the maps hold heights) step by more than a tenth
/// of the fresh snow's depth there: the snow's surface rounds that coarsely
/// (a georeferenced model, e.g. UTM northings of 5e6 m: floats 0.5 m apart).
void warn_if_imprecise(const Scene& scene, float fall_depth) {
  const glm::vec3 far = glm::max(glm::abs(scene.bounds.min), glm::abs(scene.bounds.max));
  const float reach = std::max({far.x, far.y, far.z});
  if (!(std::isfinite(reach) && fall_depth > 0.0f)) return;
  const float step = std::nextafter(reach, INFINITY) - reach;
  if (!(step > 0.1f * fall_depth)) return;
  char line[300];
  std::snprintf(line, sizeof line,
                "the scene reaches %.3g m from the origin, where 32-bit floats are %.3g m apart: "
                "too coarse for %.3g m of snow; move the scene near the origin (or check its "
                "units)",
                double(reach), double(step), double(fall_depth));
  log_warn(line);
}

/// Warns when the fresh snow is more than plan::kDeepTexels texels deep
/// (such runs take very long); suggests the map side that makes it
/// plan::kAimTexels deep.
void warn_if_deep_in_texels(const SnowMaps& maps, float fall_depth) {
  const float texels = fall_depth / maps.grid.texel;
  if (!(texels > plan::kDeepTexels)) return;
  const int side = std::max(maps.grid.width, maps.grid.height);
  const int suggested = plan::side_for_depth(side, maps.grid.texel, fall_depth);
  char line[300];
  std::snprintf(line, sizeof line,
                "the snow is %.0f texels deep (%.3g m on %.3g m texels): stabilizing may take very "
                "long; --max-side %d (or --texel %.3g) makes it %.0f texels deep",
                double(texels), double(fall_depth), double(maps.grid.texel), suggested,
                double(fall_depth / plan::kAimTexels), double(plan::kAimTexels));
  log_warn(line);
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

/// A throwaway context made on another thread while the scene loads
/// (plan::warm_up_gl): EGL displays stay initialized for the process, so
/// the first stage's own context then comes cheaply. Any GL trouble is
/// reported when a stage makes its context. Wait for the future before any
/// GL call (its destructor also waits).
std::future<void> warm_up_gl(const GlobalOptions& global) {
  return std::async(std::launch::async, [&global] {
    const QuietThread quiet;
    try {
      make_headless_context(global);
    } catch (const std::exception&) {
    }
  });
}

/// Warns when the last step's stabilizing stopped at --max-iterations with the
/// snow still moving more than --tolerance: the snow shown is not at rest.
void warn_if_unsettled(const SnowResult& snow, const StabilizeSettings& settings) {
  if (snow.last.converged || settings.tolerance <= 0.0f || snow.last.iterations == 0) return;
  char line[300];
  std::snprintf(line, sizeof line,
                "the snow did not settle within --max-iterations %d passes: it still moved more "
                "than --tolerance %.3g m (raise --max-iterations, or use less snow or coarser "
                "texels)",
                settings.max_iterations, double(settings.tolerance));
  log_warn(line);
}

/// Objects that enclose the scene like a sky dome or a sky box: their bounds
/// hold every other object and in most columns they top there is another
/// surface below them (unlike a hilly terrain, which is also wide and tall).
/// Snow that lands on them lands on nothing the user wants snowed.
std::vector<int32_t> enclosing_objects(const Scene& scene, const SnowMaps& maps) {
  std::vector<int32_t> result;
  if (scene.objects.size() < 2) return result;
  std::vector<Bounds> bounds;
  for (size_t o = 0; o < scene.objects.size(); ++o) bounds.push_back(object_bounds(scene, int(o)));
  const size_t texels = maps.grid.texels();
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const Bounds& b = bounds[o];
    const float slack = 1e-4f * glm::length(b.max - b.min);
    bool encloses = true;
    for (size_t k = 0; k < scene.objects.size() && encloses; ++k) {
      if (k == o || scene.objects[k].triangle_count == 0) continue;
      encloses = glm::all(glm::lessThanEqual(b.min, bounds[k].min + slack)) &&
                 glm::all(glm::greaterThanEqual(b.max, bounds[k].max - slack));
    }
    if (!encloses) continue;
    size_t tops = 0, over_something = 0;
    for (size_t t = 0; t < texels; ++t) {
      if (maps.object[t] != int32_t(o)) continue;
      ++tops;
      if (maps.layers > 1 && !std::isnan(maps.ground[texels + t])) ++over_something;
    }
    if (tops > 0 && 2 * over_something >= tops) result.push_back(int32_t(o));
  }
  return result;
}

/// Warns when almost no map column receives snow on anything but an object
/// that encloses the whole scene, naming the objects that shelter most of the
/// map (a sky dome, a sky box or a lid-like helper is the usual cause: --ignore
/// them).
void warn_if_sheltered(const Scene& scene, const SnowMaps& maps,
                       const std::vector<float>& coverage) {
  const std::vector<int32_t> enclosing = enclosing_objects(scene, maps);
  const auto is_enclosing = [&](int32_t o) {
    return std::find(enclosing.begin(), enclosing.end(), o) != enclosing.end();
  };
  const size_t texels = maps.grid.texels();
  size_t with_surface = 0, receiving = 0;
  // Columns each object tops: [o + 1] for object o (-1: none).
  std::vector<size_t> top_objects(scene.objects.size() + 1, 0);
  for (size_t t = 0; t < texels; ++t) {
    if (std::isnan(maps.ground[t])) continue;
    ++with_surface;
    const int32_t top = maps.object[t];
    ++top_objects[top >= 0 && size_t(top) < scene.objects.size() ? size_t(top) + 1 : 0];
    for (int l = 0; l < maps.layers; ++l) {
      const size_t k = size_t(l) * texels + t;
      if (coverage[k] > 0.5f && !is_enclosing(maps.object[k])) {
        ++receiving;
        break;
      }
    }
  }
  if (with_surface == 0 || double(receiving) > 0.05 * double(with_surface)) return;
  std::vector<std::pair<size_t, int32_t>> ranked;
  for (size_t k = 0; k < top_objects.size(); ++k) {
    if (top_objects[k] == 0) continue;
    // Enclosing objects first: they are the likely cause.
    const int32_t object = int32_t(k) - 1;
    ranked.push_back({top_objects[k] + (is_enclosing(object) ? texels : 0), object});
  }
  std::sort(ranked.rbegin(), ranked.rend());
  std::string names;
  for (size_t i = 0; i < ranked.size() && i < 3; ++i) {
    const int32_t o = ranked[i].second;
    const std::string name =
        o >= 0 && size_t(o) < scene.objects.size() ? scene.objects[size_t(o)].name : "?";
    names +=
        (i ? ", '" : "'") + name + "' (" + (is_enclosing(o) ? "encloses the scene, " : "") +
        "tops " +
        std::to_string(int(100.0 * double(top_objects[size_t(o + 1)]) / double(with_surface))) +
        "% of the map)";
  }
  log_warn("almost nothing receives snow (" + std::to_string(receiving) + " of " +
           std::to_string(with_surface) + " columns); sheltered by " + names +
           "; use --ignore for a sky dome or helper geometry");
}

/// Why no snow patch came out: nothing holds snow, the snow is thinner than
/// --min-thickness everywhere, or every patch is under --min-patch-area.
void warn_no_patches(const SnowResult& snow, const PolygonizeSettings& settings) {
  float deepest = 0.0f;
  for (float d : snow.depth) {
    if (std::isfinite(d)) deepest = std::max(deepest, d);
  }
  char line[300];
  if (!(snow.volume > 0.0) || deepest <= 0.0f) {
    std::snprintf(line, sizeof line, "no snow patch came out: nothing in the scene holds snow");
  } else if (deepest < settings.min_thickness) {
    std::snprintf(line, sizeof line,
                  "no snow patch came out: the deepest snow is %.3g m, thinner than "
                  "--min-thickness %.3g m (lower it, or raise --depth)",
                  double(deepest), double(settings.min_thickness));
  } else {
    std::snprintf(line, sizeof line,
                  "no snow patch came out: every patch is smaller than --min-patch-area %.3g m^2 "
                  "(lower it for small models)",
                  double(settings.min_patch_area));
  }
  log_warn(line);
}

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

void run_snow(const SnowOptions& o, const GlobalOptions& global) {
  using clock = std::chrono::steady_clock;
  std::vector<std::pair<std::string, double>> times;
  auto stage = [&](const char* name, auto&& work) {
    const auto start = clock::now();
    work();
    times.push_back({name, std::chrono::duration<double>(clock::now() - start).count()});
    char buf[128];
    std::snprintf(buf, sizeof buf, "%s: memory %.0f MiB resident, %.0f MiB peak so far", name,
                  resident_memory_mib(), peak_memory_mib());
    log_debug(buf);
  };

  if (o.output.empty() && o.snow_output.empty() && o.maps_dir.empty() && o.preview.empty()) {
    throw InputError("nothing to write: give -o OUT, --snow-output, --maps or --preview");
  }
  PipelineSettings s = o.settings;
  if (!std::isfinite(s.memory_budget_gib) || s.memory_budget_gib <= 0) {
    throw InputError("--memory-budget must be a positive number of GiB");
  }
  s.peel.memory_budget = uint64_t(double(s.memory_budget_gib) * double(1ull << 30));
  s.stabilize.seed = uint32_t(s.coverage.seed);
  // Fail on bad output paths before the long work starts.
  MeshFormat format = MeshFormat::Glb;
  if (!o.output.empty()) {
    format = o.format.empty() ? format_from_path(o.output) : format_from_path("x." + o.format);
    // glTF is written as binary or JSON by the file's extension (a .gltf
    // with its .bin beside it), so --format glb or gltf must agree with it.
    const std::string wanted = std::string(".") + format_name(format);
    if ((format == MeshFormat::Glb || format == MeshFormat::Gltf) &&
        lower_extension(o.output) != wanted) {
      throw InputError(o.output + ": a " + format_name(format) + " file needs the extension " +
                       wanted);
    }
  }
  for (const std::string& path : {o.output, o.snow_output, o.preview}) {
    if (path.empty()) continue;
    const fs::path folder =
        fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
    if (!fs::is_directory(folder))
      throw IOError("cannot write " + path + ": folder " + folder.string() + " does not exist");
  }
  if (!o.snow_output.empty()) format_from_path(o.snow_output);

  check_stabilize_settings(s.stabilize);  // before minutes of peeling and shadows
  fall_directions(s.coverage);            // checks the coverage settings

  // The machine's facts: the GL probe (which may load libEGL and Mesa's
  // vendor library) runs beside the load, and starts the warm-up the plan
  // allows. (warm_gl is declared first: the probe's future waits for its
  // task, which sets warm_gl, before warm_gl goes.)
  gl::ContextOptions context_options;
  context_options.backend = gl::parse_backend(global.gl_backend);
  plan::MachineInfo machine = plan::probe_machine(context_options);
  const uint64_t input_bytes = gltf_input_bytes(o.input);
  std::future<void> warm_gl;
  bool warming = false;
  std::future<std::optional<bool>> probed = std::async(std::launch::async, [&] {
    plan::MachineInfo probe = machine;
    probe.software = plan::probe_renderer(context_options);
    warming = plan::warm_up_gl(probe, input_bytes);
    if (warming) warm_gl = warm_up_gl(global);
    return probe.software;
  });
  // Textures, normals and UVs only show in the preview.
  s.load.load_images = s.load.shading = !o.preview.empty();
  fit_heap(plan::huge_pages_off(machine, input_bytes, 0));
  Scene scene;
  stage("load", [&] { scene = load_scene(o.input, s.load); });
  machine.software = probed.get();
  // Where only a context can tell the renderer, every stage makes its
  // context up front (the peel's tells it); where GL is known to render in
  // software, a stage makes its context only when a pass needs it
  // (gl::OnDemandContext): small scenes then never load the driver.
  const bool renderer_probed = machine.software.has_value();
  // The scene plus snow is written from the input as tinygltf reads it: read
  // on another thread while the snow is computed.
  const bool combined = !o.output.empty() && !o.snow_only &&
                        (format == MeshFormat::Glb || format == MeshFormat::Gltf);
  std::future<CombinedInputPtr> combined_input;
  if (combined) {
    combined_input =
        std::async(std::launch::async, [&o] { return read_combined_input(o.input, o.output); });
  }
  warn_unmatched(scene, s.ignore, "--ignore");
  warn_unmatched(scene, s.no_snow_on, "--no-snow-on");
  const size_t triangles_in = scene.triangle_count();
  const Scene snow_scene = without_ignored(std::move(scene), s.ignore);
  const std::vector<uint8_t> receives = receiving_objects(snow_scene, s.no_snow_on);
  warn_if_out_of_scale(snow_scene, s.accumulate.fall_depth);
  warn_if_imprecise(snow_scene, s.accumulate.fall_depth);

  const plan::Settings wanted = plan_settings(s);
  const plan::SceneStats stats = scene_stats(snow_scene, s.peel, wanted, input_bytes);
  plan::RunPlan run = plan::plan_run(stats, machine, wanted, warming);
  if (!run.maps.note.empty()) log_info(run.maps.note);
  for (const std::string& line : plan::describe(run)) log_debug(line);
  s.peel.max_side = run.maps.max_side;
  fit_heap(run.huge_pages_off);

  // Each GL stage runs in a context of its own, dropped when it is done:
  // Mesa keeps much of what a stage deleted allocated in the context, and
  // the stages after it would run on top of that.
  bool described = false;
  bool gl_used = warming;  // a context was made in this process
  auto gl_context = [&] {
    if (warm_gl.valid()) warm_gl.wait();
    auto context = make_headless_context(global);
    if (!described) log_info("OpenGL: " + context->description());
    described = gl_used = true;
    return context;
  };
  auto stage_context = [&] {
    auto context = std::make_unique<gl::OnDemandContext>(gl_context, run.gl.software);
    if (!renderer_probed) context->make();
    return context;
  };
  // The coverage's BVH needs the scene alone: where the plan says so, it is
  // built on another thread while the peel runs.
  std::future<CoverageBvh> bvh_ahead;
  const auto build_bvh_ahead = [&] {
    bvh_ahead = std::async(std::launch::async, [&] {
      return build_coverage_bvh(snow_scene,
                                run.bvh_morton ? Bvh::Build::Morton : Bvh::Build::Sah);
    });
  };
  if (run.bvh_ahead) build_bvh_ahead();
  SnowMaps maps;
  plan::GlFacts gl_after_peel;
  stage("peel", [&] {
    const auto context = stage_context();
    if (!renderer_probed) {  // the peel's context tells the renderer: plan again
      machine.software = plan::current_renderer_is_software();
      run = plan::plan_run(stats, machine, wanted, true);
      for (const std::string& line : plan::describe(run)) log_debug(line);
      if (run.bvh_ahead) build_bvh_ahead();
    }
    maps = peel_layers(snow_scene, s.peel, run.gl);
    gl_after_peel = {run.gl.software, run.gl.started || context->made()};
  });
  log_info("maps: " + std::to_string(maps.grid.width) + " x " + std::to_string(maps.grid.height) +
           " texels of " + std::to_string(maps.grid.texel) + " m, " + std::to_string(maps.layers) +
           " layers");
  warn_if_deep_in_texels(maps, s.accumulate.fall_depth);
  SnowResult snow;
  stage("snowfall", [&] {
    const auto context = stage_context();
    std::optional<CoverageBvh> bvh;
    if (bvh_ahead.valid()) {
      try {
        bvh = bvh_ahead.get();
      } catch (const std::bad_alloc&) {
        throw InputError("coverage: out of memory building the BVH of " +
                         std::to_string(snow_scene.triangle_count()) + " triangles");
      }
    }
    snow = accumulate(snow_scene, maps, s.coverage, s.stabilize, s.accumulate, receives,
                      bvh ? &*bvh : nullptr, gl_after_peel);
  });
  warn_if_unsettled(snow, s.stabilize);
  warn_if_sheltered(snow_scene, maps, snow.coverage);
  std::vector<SnowPatch> patches;
  stage("polygonize", [&] { patches = polygonize(maps, snow.depth, snow_scene, s.polygonize); });
  if (patches.empty()) warn_no_patches(snow, s.polygonize);

  stage("export", [&] {
    if (!o.output.empty()) {
      if (!o.snow_only && !combined)
        log_info(std::string(format_name(format)) + " holds the snow only");
      if (combined) {
        write_combined_gltf(combined_input.get(), patches, o.output);
      } else {
        write_snow_meshes(patches, o.output, format);
      }
      log_info("wrote " + o.output);
    }
    if (!o.snow_output.empty()) {
      write_snow_meshes(patches, o.snow_output, format_from_path(o.snow_output));
      log_info("wrote " + o.snow_output);
    }
    if (!o.maps_dir.empty()) {
      write_maps(o.maps_dir, maps, &snow.coverage, &snow.depth);
      log_info("wrote maps to " + o.maps_dir);
    }
    // The effective settings, beside the first output, so the run can be repeated.
    const fs::path first = !o.output.empty()        ? fs::path(o.output)
                           : !o.snow_output.empty() ? fs::path(o.snow_output)
                           : !o.maps_dir.empty()    ? fs::path(o.maps_dir) / "snow"
                                                    : fs::path(o.preview);
    nlohmann::json record;
    record["snowmodel"] = "0.1.0";
    record["input"] = o.input;
    record["settings"] = settings_to_json(o.settings);
    write_text_atomically(first.string() + ".settings.json", record.dump(2) + "\n");
  });
  if (!o.preview.empty()) {
    stage("preview", [&] {
      const auto context = gl_context();
      write_preview(snow_scene, patches, o.preview);
    });
    log_info("wrote " + o.preview);
  }

  // Closing summary.
  size_t triangles_out = 0;
  for (const SnowPatch& p : patches) triangles_out += p.mesh.indices.size() / 3;
  std::string timing;
  double total = 0;
  for (const auto& [name, seconds] : times) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%s %.2f s", timing.empty() ? "" : ", ", name.c_str(),
                  seconds);
    timing += buf;
    total += seconds;
  }
  char summary[512];
  std::snprintf(
      summary, sizeof summary,
      "summary: %.2f s (%s); peak memory %.0f MiB; triangles in %zu, snow out %zu in %zu "
      "patches; snow %.3f m^3 (fell %.3f, lost off the domain %.3f); coverage by %s; stabilizer "
      "%d passes on the %s%s",
      total, timing.c_str(), peak_memory_mib(), triangles_in, triangles_out, patches.size(),
      snow.volume, snow.fallen_volume, snow.lost_volume,
      snow.coverage_method == CoverageMethod::CpuRays         ? "rays on the CPU"
      : snow.coverage_method == CoverageMethod::GpuRays       ? "rays on the GPU"
      : snow.coverage_method == CoverageMethod::CpuShadowMaps ? "shadow maps on the CPU"
                                                              : "shadow maps",
      snow.iterations, snow.stabilized_on_cpu ? "CPU" : "GPU",
      gl_used ? "" : "; OpenGL not started");
  log_info(summary);
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
  cmd->add_option("input", o->input, "glTF 2.0 scene (.gltf or .glb)")->required();
  cmd->add_option("-o,--output", o->output,
                  "Output: the input scene plus snow (.glb, .gltf), or snow only (.obj, .ply)");
  cmd->add_option("--snow-output", o->snow_output,
                  "Also write the snow only (.glb, .gltf, .obj, .ply)");
  cmd->add_option(
         "--format", o->format,
         "Format of --output: obj or ply override its extension; glb and gltf must match it")
      ->check(CLI::IsMember({"glb", "gltf", "obj", "ply"}));
  cmd->add_flag("--snow-only", o->snow_only, "Write only the snow to --output");
  cmd->add_option("--maps", o->maps_dir,
                  "Write height, coverage and depth maps (EXR, PNG, manifest.json) here");
  cmd->add_option("--preview", o->preview, "Write a before/after preview PNG (3/4 and top views)");
  add_settings_options(*cmd, o->settings, global.help_all);
  cmd->add_flag("--help-all", "Print this help with the developer options (backends, speed-ups)");
  cmd->callback([o, &global] { run_snow(*o, global); });
}

}  // namespace snow::app
