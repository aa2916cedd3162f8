// `snowmodel preview IN [options]`: the live accumulation preview window
// (or, with --headless, its frame loop off-screen).
// This file only turns flags into settings; the window, the per-frame
// physics (the batch stages, stepped) and the drawing live in src/live.
#include <cmath>
#include <cstdio>

#include "app/commands.h"
#include "app/filters.h"
#include "app/settings.h"
#include "app/snow_warnings.h"
#include "app/snow_weather.h"
#include "app/tracks.h"
#include "core/error.h"
#include "core/log.h"
#include "live/viewer.h"
#include "mesh/export.h"
#include "mesh/output_policy.h"
#include "plan/plan.h"
#include "snow/peel.h"

namespace snow::app {
namespace {

struct PreviewOptions {
  std::string input;
  std::string size = "1280x800";
  std::string view = "orbit";
  std::string overlay = "snow";
  PipelineSettings settings;
  live::ViewerOptions viewer;
  std::vector<std::string> snowfall_given;  // the flags given that --weather replaces
};

// The ranges of the preview's own numeric options (app/settings.h, Range):
// stated in their help texts and checked by check_viewer_options, like the
// pipeline settings' by check_settings. The simulation's match
// live::LiveSimulation's own checks.
constexpr Range kFrames{0, 1e9};
constexpr Range kAzimuth{-360, 360};
constexpr Range kElevation{-89, 89};
constexpr Range kZoom{0.01, 100};
constexpr Range kFov{1, 170};
constexpr Range kFallRate{0, 1000};
constexpr Range kFrameTime{1e-4, 3600};
constexpr Range kAddEvery{0, 100000};
constexpr Range kPassesPerFrame{0, 100000};
constexpr Range kSnowStride{0, 4096};
constexpr Range kFlakes{0, 1e6};
constexpr Range kWeatherSpeed{0, 1e4};

/// `help` with the range appended, as visit_settings' options print it.
std::string ranged(const char* help, const Range& range) {
  return std::string(help) + " " + range_text(range);
}

/// InputError naming the option unless every numeric option of `v` is in
/// its range.
void check_viewer_options(const live::ViewerOptions& v) {
  check_range("--frames", "", v.frames, kFrames);
  check_range("--azimuth", "", v.azimuth, kAzimuth);
  check_range("--elevation", "", v.elevation, kElevation);
  check_range("--zoom", "", v.zoom, kZoom);
  check_range("--fov", "", v.fov, kFov);
  check_range("--fall-rate", "", v.sim.fall_rate, kFallRate);
  check_range("--frame-time", "", v.sim.frame_time, kFrameTime);
  check_range("--add-every", "", v.sim.add_every, kAddEvery);
  check_range("--passes-per-frame", "", v.sim.passes_per_frame, kPassesPerFrame);
  check_range("--snow-stride", "", v.snow_stride, kSnowStride);
  check_range("--flakes", "", v.view.flakes, kFlakes);
  check_range("--weather-speed", "", v.sim.weather_speed, kWeatherSpeed);
}

void run_preview(PreviewOptions o) {
  live::ViewerOptions& v = o.viewer;
  PipelineSettings& s = o.settings;
  int w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(o.size.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 1 || h < 1 || w > 16384 ||
      h > 16384)
    throw InputError("--size must be WIDTHxHEIGHT in pixels, e.g. 1280x800, got '" + o.size + "'");
  v.width = w;
  v.height = h;
  v.top_view = o.view == "top";
  v.view.overlay = o.overlay == "coverage" ? live::Overlay::Coverage
                   : o.overlay == "depth"  ? live::Overlay::Depth
                                           : live::Overlay::None;
  check_settings(s);  // flags and --config alike
  std::optional<WeatherRun> weather = weather_run_of(s);
  if (weather) {
    if (!o.snowfall_given.empty())
      throw InputError(o.snowfall_given.front() + " and --weather both give the snowfall");
    s.accumulate.fall_depth = weather_fall_depth(*weather);
  }
  resolve_snow_settings(s);
  check_viewer_options(v);
  v.frame = file_frame(s);
  s.peel.memory_budget = memory_budget_bytes(s.memory_budget_gib);
  s.load.limits.memory_budget = s.peel.memory_budget;  // the scene's data, images included
  s.stabilize.seed = uint32_t(s.coverage.seed);
  v.input = o.input;
  v.sim.peel = s.peel;
  v.sim.coverage = s.coverage;
  v.sim.stabilize = s.stabilize;
  v.sim.total_depth = s.accumulate.fall_depth;
  v.sim.snow_on_snow_every = s.accumulate.snow_on_snow_every;
  v.sim.snow_kind = snow_kind_from_name(s.snow_kind);
  v.sim.wind_transport = s.wind_transport;
  if (weather) v.sim.weather = std::make_shared<const WeatherRun>(std::move(*weather));
  v.mesh = s.polygonize;
  // Fail before the window opens.
  std::vector<OutputPath> outputs;
  if (!v.screenshot.empty())
    outputs.push_back({"--screenshot", v.screenshot, OutputKind::File, {}, {}});
  if (!v.export_path.empty()) {
    outputs.push_back(
        {"--export", v.export_path, OutputKind::Mesh, format_from_path(v.export_path), {}});
  }
  if (!v.maps_path.empty()) outputs.push_back({"--maps", v.maps_path, OutputKind::Maps, {}, {}});
  check_output_paths(o.input, outputs);

  // Ignored objects are neither simulated nor drawn (a sky dome would hide
  // the scene from the orbit camera).
  // The export (the scene plus snow) writes from the JSON the loader parsed.
  s.load.keep_source = true;
  s.load.lines = s.load.motions = wants_tracks(s);
  if (s.track_hour >= 0.0) {
    throw InputError("--track-hour: the preview presses the tracks once the snow rests");
  }
  Scene loaded = load_scene(o.input, s.load);
  to_metres_y_up(loaded, v.frame);
  warn_unmatched(loaded, s.ignore, "--ignore");
  warn_unmatched(loaded, s.no_snow_on, "--no-snow-on");
  const Scene scene =
      without_sky_enclosures(without_ignored(std::move(loaded), s.ignore), s.keep_enclosures);
  if (!s.no_snow_on.empty()) v.receives = receiving_objects(scene, s.no_snow_on);
  warn_unmatched(scene, s.slippery, "--slippery");
  warn_unmatched(scene, s.rough, "--rough");
  v.sim.stabilize.grip = object_grip(scene, s.slippery, s.rough);
  // The maps' side: the planner's, as for the batch job, from the preview's
  // coarser automatic side (--max-side or --texel override it).
  plan::Settings wanted = plan_settings(s);
  wanted.auto_side = plan::kPreviewMaxSide;
  const plan::SceneStats stats = scene_stats(scene, s.peel, wanted, 0);
  const plan::MapPlan maps = plan::plan_maps(wanted, stats.asked_grid_side, stats.asked_grid_texel);
  if (!maps.note.empty()) log_info(maps.note);
  if (s.peel.texel <= 0.0f) v.sim.peel.max_side = maps.max_side;
  warn_if_not_metres_y_up(scene);
  if (wants_tracks(s)) {
    // Poses at most half a texel apart on maps at least this fine.
    const glm::vec3 size = scene.bounds.size();
    const float texel = s.peel.texel > 0.0f
                            ? s.peel.texel
                            : std::max(size.x, size.z) / float(std::max(maps.max_side, 1));
    v.tracks = track_sources(scene, s, texel);
    v.track_settings = track_settings(s);
  }
  const live::ViewerReport r = live::run_viewer(scene, v);
  char summary[400];
  std::snprintf(
      summary, sizeof summary,
      "preview: %lld frames in %.2f s, %.2f fps (after 5 frames); per frame: snowfall "
      "and stabilizer %.1f ms, scene %.1f ms, snow %.1f ms; snow grid %zu triangles drawn; "
      "snow %.3f m^3 lying of %.3f fallen",
      static_cast<long long>(r.frames), r.seconds, r.fps, r.stabilize_ms, r.scene_ms, r.snow_ms,
      r.snow_triangles, r.volume, r.fallen);
  log_info(summary);
  if (v.sim.weather) {
    std::snprintf(summary, sizeof summary,
                  "preview: weather hour %.6g; water %.4g m^3 fell as snow, %.4g melted, %.4g left "
                  "the maps, %.4g lies",
                  r.hour, r.water_fallen, r.water_melted, r.water_lost, r.water_lying);
    log_info(summary);
  }
}

}  // namespace

void register_preview(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<PreviewOptions>();
  o->settings.peel.max_side = 0;  // automatic (the planner's); --max-side overrides
  o->settings.coverage.directions = plan::kPreviewDirections;
  CLI::App* cmd = app.add_subcommand(
      "preview",
      "Open a window in which snow falls, piles up and slides while you orbit and tweak");
  cmd->add_option_function<std::string>(
         "--config", [o](const std::string& path) { load_settings_file(path, o->settings); },
         "JSON settings file (as written beside outputs of the snow command); flags override it")
      ->check(CLI::ExistingFile);
  cmd->add_option("input", o->input, "glTF 2.0 scene (.gltf or .glb)")->required();
  live::ViewerOptions& v = o->viewer;
  cmd->add_option("--frames", v.frames,
                  ranged("Quit after this many frames (0 = when closed)", kFrames));
  cmd->add_option("--screenshot", v.screenshot,
                  "PNG of the last frame (scene and snow, no panel), written at exit");
  cmd->add_flag("--screenshot-panel", v.screenshot_panel,
                "The --screenshot shows the settings panel too");
  cmd->add_option("--export", v.export_path,
                  "Snow meshes at exit: .glb/.gltf (scene plus snow), .obj/.ply (snow only)");
  cmd->add_flag("--export-snow-only", v.snow_only, "Export only the snow, also to .glb/.gltf");
  cmd->add_option("--maps", v.maps_path,
                  "Folder for the snow maps at exit (height, coverage, depth per layer; as the "
                  "snow command's --maps)");
  cmd->add_option("--size", o->size, "Window size WIDTHxHEIGHT in pixels [1..16384 each]")
      ->capture_default_str();
  cmd->add_option("--view", o->view, "Start camera: orbit (perspective) or top (orthographic)")
      ->check(CLI::IsMember({"orbit", "top"}))
      ->capture_default_str();
  cmd->add_option("--azimuth", v.azimuth,
                  ranged("Start camera: degrees from south (+Z) towards east (+X)", kAzimuth))
      ->capture_default_str();
  cmd->add_option("--elevation", v.elevation,
                  ranged("Start camera: degrees above the horizon", kElevation))
      ->capture_default_str();
  cmd->add_option("--zoom", v.zoom,
                  ranged("Start camera: the framed distance divided by this", kZoom))
      ->capture_default_str();
  cmd->add_option("--fov", v.fov, ranged("Vertical field of view in degrees", kFov))
      ->capture_default_str();
  cmd->add_option(
         "--fall-rate", v.sim.fall_rate,
         ranged("Fresh snow per simulated second on open flat ground, metres (--depth in all)",
                kFallRate))
      ->capture_default_str();
  cmd->add_option("--frame-time", v.sim.frame_time,
                  ranged("Simulated seconds per frame", kFrameTime))
      ->capture_default_str();
  cmd->add_option("--add-every", v.sim.add_every,
                  ranged("Add snow every N frames, N frames' worth at once (0 = automatic: 1, or 4 "
                         "where GL renders in software)",
                         kAddEvery))
      ->capture_default_str();
  cmd->add_option("--passes-per-frame", v.sim.passes_per_frame,
                  ranged("Stabilizer relaxation passes per frame", kPassesPerFrame))
      ->capture_default_str();
  cmd->add_option("--snow-stride", v.snow_stride,
                  ranged("Texels between the snow grid's vertices at its finest level of detail "
                         "(0 = automatic: at most 768 per side, 256 on a software renderer)",
                         kSnowStride))
      ->capture_default_str();
  cmd->add_option("--flakes", v.view.flakes, ranged("Falling flakes drawn (0 = none)", kFlakes))
      ->capture_default_str();
  cmd->add_option("--overlay", o->overlay, "Snow drawn as: snow, coverage or depth")
      ->check(CLI::IsMember({"snow", "coverage", "depth"}))
      ->capture_default_str();
  cmd->add_option("--weather-speed", v.sim.weather_speed,
                  ranged("Hours of a --weather file played per simulated second (--frame-time "
                         "per frame)",
                         kWeatherSpeed))
      ->capture_default_str()
      ->group("Weather over time");
  cmd->add_flag("--headless", v.headless,
                "No window: draw off-screen on a headless GL context (needs --frames; for "
                "benchmarks, screenshots and exports on machines without a display)");
  cmd->add_flag("--paused", v.paused, "Start paused (space resumes)");
  cmd->add_flag("!--no-panel", v.panel, "Hide the settings panel (H shows it)");
  add_settings_options(*cmd, o->settings, global.help_all);
  cmd->add_flag("--help-all", "Print this help with the developer options (backends, speed-ups)");
  cmd->callback([o, &global, cmd] {
    o->viewer.gl_backend = global.gl_backend;
    for (const char* flag : {"--depth", "--wind", "--fall-rate"}) {
      if (cmd->count(flag) > 0) o->snowfall_given.push_back(flag);
    }
    run_preview(*o);
  });
}

}  // namespace snow::app
