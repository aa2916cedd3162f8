#pragma once
// Every setting of the batch pipeline in one struct, with one field list
// (visit_settings) from which the CLI flags, the --config JSON reader and
// the effective-settings JSON writer are all derived.
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mesh/polygonize.h"
#include "plan/plan.h"
#include "scene/frame.h"
#include "scene/load_gltf.h"
#include "snow/accumulate.h"
#include "snow/coverage.h"
#include "snow/peel.h"
#include "snow/stabilize.h"

namespace snow::app {

struct PipelineSettings {
  LoadSettings load;
  PeelSettings peel;
  CoverageSettings coverage;
  StabilizeSettings stabilize;
  AccumulateSettings accumulate;
  PolygonizeSettings polygonize;
  float memory_budget_gib = 4.0f;       // GiB, stop before allocating more (peel.memory_budget)
  float unit_scale = 1.0f;              // metres per file unit (scene/frame.h)
  std::string up = "y";                 // the file's up axis: y or z
  std::vector<std::string> no_snow_on;  // name globs: shelter but receive no snow
  std::vector<std::string> ignore;      // name globs: neither receive nor shelter
  std::string snow_kind = "fresh";      // powder, fresh or wet (snow/cohesion.h)
  float stand_height = -1.0f;           // m, overrides the kind's (negative: the kind's)
  float hold_depth = -1.0f;             // m, overrides the kind's (negative: the kind's)
  std::vector<std::string> slippery;    // name globs: surfaces that shed snow sooner
  std::vector<std::string> rough;       // name globs: surfaces that hold more snow
  bool keep_enclosures = false;         // keep sky domes and boxes (scene/enclosure.h)
  bool wind_transport = true;           // the wind moves fallen snow (snow/drift.h)
  // Weather over time (snow/accumulate.h, WeatherRun).
  std::string weather;           // weather CSV (snow/weather.h); "": one snowfall of --depth
  float latitude = 0.0f;         // degrees, north positive (the sun's path)
  float longitude = 0.0f;        // degrees, east positive
  std::string start;             // UTC of the file's hour 0; "": the file's sun columns
  glm::vec2 north{0.0f, -1.0f};  // the scene's north, world (x, z)
  // Tracks in the snow (snow/tracks.h).
  std::vector<std::string> track;  // name globs: objects or lines that press tracks
  std::vector<std::string> clear;  // name globs: objects or lines that clear paths
  float track_width = 0.2f;        // m, the width a line presses or clears
  float track_load = 200.0f;       // kPa, the contact pressure of --track
  double track_hour = -1.0;        // hours into a --weather run (negative: at its end)
};

/// The values a numeric setting accepts: lo..hi, both included, every value
/// finite; where `negative_auto`, any negative value too (it asks for the
/// automatic choice). The bounds keep every accepted run finite (no count
/// that runs for hours, no distance that makes an absurd mesh); the help
/// text states them (range_text) and check_settings enforces them.
struct Range {
  double lo = 0.0;
  double hi = 0.0;
  bool negative_auto = false;
};

/// Range of a setting that is not a number (names, switches, globs): none.
inline constexpr Range kNoRange{};

/// --memory-budget, GiB, in every command that loads a scene.
inline constexpr Range kMemoryBudgetGib{0.01, 1048576};

/// Bytes of a --memory-budget of `gib` GiB.
inline uint64_t memory_budget_bytes(float gib) {
  return uint64_t(double(gib) * double(uint64_t(1) << 30));
}

/// One entry per setting: JSON key ("peel.texel"), CLI flag ("--texel"),
/// help text with the unit, the field and its Range. Calls
/// v(key, flag, help, field, range) for each.
template <class Visitor>
void visit_settings(Visitor&& v, PipelineSettings& s) {
  // The scene's frame.
  v("scene.unit_scale", "--unit-scale",
    "Metres per unit of the file: 0.01 for a scene in centimetres, 0.001 for millimetres (the "
    "snow goes back to the file's units)",
    s.unit_scale, Range{1e-6, 1e6});
  v("scene.up", "--up", "The file's up axis: y (glTF's) or z (the snow goes back to it)", s.up,
    kNoRange);
  // Maps (peel).
  v("maps.texel", "--texel", "Map texel size in metres (0 = automatic from --max-side)",
    s.peel.texel, Range{0, 1000});
  v("maps.max_side", "--max-side",
    "Longest map side in texels when --texel is 0 (0 = automatic: 1024 for snow, 512 for "
    "preview, or where the snow would lie over 64 texels deep on those, the side that makes "
    "it 32)",
    s.peel.max_side, Range{0, 65536});
  v("maps.layers", "--layers", "Surfaces kept per map column, top down (L)", s.peel.layers,
    Range{1, 64});
  v("maps.margin", "--margin", "Border around the scene in metres (negative = automatic)",
    s.peel.margin, Range{0, 10000, true});
  v("maps.merge_distance", "--merge-distance",
    "Surfaces closer than this in metres count as one layer", s.peel.merge_distance, Range{0, 100});
  v("maps.bridge_width", "--bridge-width",
    "Snow bridges gaps up to this wide, metres: bench slats, grates (0 = none)",
    s.peel.bridge_width, Range{0, 10});
  v("maps.device", "--peel-device",
    "Where the maps are peeled: gpu (depth passes), cpu (a vertical ray per texel) or auto (the "
    "planner's choice, as `snowmodel info` prints it)",
    s.peel.device, kNoRange);
  v("maps.memory_budget_gib", "--memory-budget",
    "Memory budget in GiB; larger runs stop before allocating", s.memory_budget_gib,
    kMemoryBudgetGib);
  // Coverage.
  v("coverage.directions", "--directions", "Fall directions sampled (K shadow maps)",
    s.coverage.directions, Range{1, 4096});
  v("coverage.flutter_deg", "--flutter",
    "Flake flutter: half-angle of the cone of fall directions, degrees", s.coverage.flutter_deg,
    Range{0, 60});
  v("coverage.wind", "--wind",
    "Horizontal wind X,Z in m/s, up to 25 m/s in all: tilts the fall (by atan(wind/fall "
    "speed), at most 75 degrees less the flutter) and, above the snow's drift threshold "
    "(powder 3.5, fresh 4, wet 9 m/s), blows the fallen snow into drifts",
    s.coverage.wind, Range{-100, 100});
  v("coverage.fall_speed", "--fall-speed", "Flakes' still-air fall speed in m/s",
    s.coverage.fall_speed, Range{0.01, 100});
  // Every uint64_t is a seed (the CLI refuses what does not fit, not wraps it).
  v("coverage.seed", "--seed",
    "Seed of all jitter; same seed, same output [0..18446744073709551615]", s.coverage.seed,
    kNoRange);
  v("coverage.batch", "--shadow-batch",
    "Shadow maps rendered per GPU batch (0 = automatic: as many as fit in 64 MiB, 8 at least)",
    s.coverage.batch, Range{0, 32});
  v("coverage.bias", "--shadow-bias", "Shadow depth bias in metres (negative = automatic)",
    s.coverage.bias, Range{0, 100, true});
  v("coverage.method", "--coverage-method",
    "How lines of fall are tested: shadow-maps, cpu-shadow-maps (the same on the CPU cores), rays "
    "(each cast exactly on the GPU), cpu-rays (the same on the CPU cores) or auto (the planner's "
    "choice: the cheapest for the scene and the renderer); same results",
    s.coverage.method, kNoRange);
  // Accumulation and stabilizer.
  v("snow.depth", "--depth", "Fresh snow that falls, metres", s.accumulate.fall_depth,
    Range{0, 1000});
  v("snow.steps", "--steps", "Time steps of snowfall, each followed by stabilizing",
    s.accumulate.steps, Range{1, kMaxSnowSteps});
  v("snow.snow_on_snow_every", "--snow-on-snow-every",
    "Re-render shadows with the lying snow every N steps (0 = off)",
    s.accumulate.snow_on_snow_every, Range{0, kMaxSnowSteps});
  v("snow.kind", "--snow",
    "Kind of snow: powder (dry, sheds sooner), fresh or wet (sticky, clings to steeper roofs and "
    "stands higher at edges)",
    s.snow_kind, kNoRange);
  v("snow.stand_height", "--stand-height",
    "Snow up to this deep stands at free edges by cohesion, metres (negative = the --snow kind's)",
    s.stand_height, Range{0, 100, true});
  v("snow.hold_depth", "--hold-depth",
    "Deepest snow that holds on a 40-degree slope, metres; steeper slopes hold less (negative = "
    "the --snow kind's)",
    s.hold_depth, Range{0.001, 100, true});
  v("snow.repose_deg", "--repose", "Angle of repose of snow that slid and piles up, degrees",
    s.stabilize.repose_deg, Range{5, 85});
  v("snow.repose_jitter_deg", "--repose-jitter",
    "Per-texel jitter of the repose angle, +- degrees (repose +- jitter within 1..89)",
    s.stabilize.repose_jitter_deg, Range{0, 40});
  v("snow.tolerance", "--tolerance", "Stabilizer stops when the largest move is below this, metres",
    s.stabilize.tolerance, Range{0, 10});
  v("snow.min_move", "--min-move",
    "Stabilizer moves smaller than this are not made, metres (0 = every move; negative = "
    "automatic: 0.1 x --tolerance)",
    s.stabilize.min_move, Range{0, 10, true});
  v("snow.max_iterations", "--max-iterations", "Stabilizer passes at most per step",
    s.stabilize.max_iterations, Range{0, 100000});
  v("snow.max_stride", "--max-stride",
    "Longest stabilizer move in texels (a power of two; 1 = single steps)", s.stabilize.max_stride,
    Range{1, 64});
  v("snow.adaptive_stride", "--adaptive-stride",
    "Start with single steps, longer moves only where the snow creeps (true/false)",
    s.stabilize.adaptive_stride, kNoRange);
  v("snow.device", "--stabilizer",
    "Where the stabilizer runs: gpu, cpu or auto (the planner's choice, as `snowmodel info` "
    "prints it); same results",
    s.stabilize.device, kNoRange);
  v("snow.route_steep", "--route-steep",
    "Route snow off supports steeper than repose in one go (true/false)", s.stabilize.route_steep,
    kNoRange);
  v("snow.deposit_piles", "--deposit-piles",
    "Lay routed snow as a pile at the angle of repose where it comes to rest, not on one texel "
    "(true/false)",
    s.stabilize.deposit_piles, kNoRange);
  v("snow.wind_transport", "--wind-transport",
    "Let a wind above the drift threshold move the fallen snow (true/false; false: the wind "
    "only tilts the fall)",
    s.wind_transport, kNoRange);
  // Weather over time.
  v("weather.file", "--weather",
    "Weather CSV, one row per time step: hour, precip_mm (water), temp_c, wind_ms, wind_from_deg, "
    "cloud (0-1), optionally sun_elev_deg, sun_azim_deg; replaces --depth, --steps and --wind",
    s.weather, kNoRange);
  v("weather.latitude", "--latitude", "Latitude of the scene for the sun, degrees north",
    s.latitude, Range{-90, 90});
  v("weather.longitude", "--longitude", "Longitude of the scene for the sun, degrees east",
    s.longitude, Range{-180, 180});
  v("weather.start", "--start",
    "UTC time of the weather file's hour 0, YYYY-MM-DDTHH:MM (the sun's position from it, "
    "--latitude and --longitude; without it, from the file's sun columns, else no sun)",
    s.start, kNoRange);
  v("weather.north", "--north", "The scene's north as X,Z in world coordinates", s.north,
    Range{-1e6, 1e6});
  // Tracks.
  v("tracks.press", "--track",
    "Name glob of objects that press tracks into the snow where they stand and, animated, "
    "wherever they go (wheels, feet, a box pushed along); glTF lines press a path --track-width "
    "wide (repeatable)",
    s.track, kNoRange);
  v("tracks.clear", "--clear",
    "Name glob of objects or lines that clear the snow away, into piles beside them (a shovelled "
    "path, a plough; repeatable)",
    s.clear, kNoRange);
  v("tracks.width", "--track-width", "Width of the path a glTF line presses or clears, metres",
    s.track_width, Range{0.01, 100});
  v("tracks.load_kpa", "--track-load",
    "Contact pressure of --track objects, kPa: about 200 for a car tyre, 20 for a boot (the "
    "snow compacts more under more)",
    s.track_load, Range{1, 10000});
  v("tracks.hour", "--track-hour",
    "Hour of a --weather run at which the tracks are made (negative = at its end); the snow "
    "falling after it fills them",
    s.track_hour, Range{0, 1e7, true});
  v("snow.drain_edges", "--drain-edges",
    "Once snow creeps off an edge into the void, drain what will leave in one go (true/false)",
    s.stabilize.drain_edges, kNoRange);
  v("snow.route_creep", "--route-creep",
    "Where snow creeps, route the loose snow down its whole path in one go (true/false)",
    s.stabilize.route_creep, kNoRange);
  // Meshes.
  v("mesh.min_thickness", "--min-thickness", "Snow thinner than this is no snow, metres",
    s.polygonize.min_thickness, Range{0, 100});
  v("mesh.decimate_error", "--decimate-error",
    "Decimation error bound in metres (negative = half a texel)", s.polygonize.decimate_error,
    Range{0, 100, true});
  v("mesh.shoulder_radius", "--shoulder",
    "Radius over which the snow rounds off at free edges (table tops, wall caps), metres (0 = "
    "square)",
    s.polygonize.shoulder_radius, Range{0, 10});
  v("mesh.overhang", "--overhang",
    "With shoulders, the snow bulges past free edges by up to this much, metres (0 = none)",
    s.polygonize.overhang, Range{0, 1});
  v("mesh.smooth_iterations", "--smooth", "Smoothing passes over the snow top",
    s.polygonize.smooth_iterations, Range{0, 100});
  v("mesh.min_patch_area", "--min-patch-area", "Drop snow patches smaller than this, square metres",
    s.polygonize.min_patch_area, Range{0, 1e6});
  v("mesh.closed", "--closed", "Closed snow solids (true) or open top surfaces only (false)",
    s.polygonize.closed, kNoRange);
  v("mesh.bottom_offset", "--bottom-offset", "Snow bottom lies this far under its support, metres",
    s.polygonize.bottom_offset, Range{0, 10});
  v("mesh.piece_triangles", "--piece-triangles",
    "A snow patch whose top has more triangles than this is decimated in pieces of about this "
    "many, side by side, on all cores (0 = whole); smaller pieces keep more cores busy, and each "
    "seam keeps its full-grid triangles",
    s.polygonize.piece_triangles, Range{0, 1e9});
  // Object filters.
  v("filters.no_snow_on", "--no-snow-on",
    "Name glob of objects that receive no snow but still shelter (repeatable)", s.no_snow_on,
    kNoRange);
  v("filters.ignore", "--ignore",
    "Name glob of objects that neither receive nor shelter (repeatable)", s.ignore, kNoRange);
  v("filters.keep_enclosures", "--keep-enclosures",
    "Keep objects that enclose the scene from above (sky domes, sky boxes), which are otherwise "
    "left out with a warning (true/false)",
    s.keep_enclosures, kNoRange);
  v("filters.slippery", "--slippery",
    "Name glob of objects whose surface sheds snow sooner: glass, metal, solar panels "
    "(repeatable)",
    s.slippery, kNoRange);
  v("filters.rough", "--rough",
    "Name glob of objects whose surface holds more snow: rock, shingles, gravel (repeatable)",
    s.rough, kNoRange);
}

/// The range as the help texts print it: "[0..100]", "[negative, or
/// 0..10000]"; empty for kNoRange.
std::string range_text(const Range& range);

/// InputError "FLAG (KEY) must be in LO..HI, got VALUE" unless `value` is
/// finite and in `range` (one line, naming the option and its bound);
/// `float_field`: the value came from a float, the bounds are rounded alike.
void check_range(const std::string& flag, const std::string& key, double value, const Range& range,
                 bool float_field = false);

/// Every numeric setting of `settings` in its Range (check_range), whether
/// it came from a flag or a --config file; run before the long work starts.
/// The stages check the combinations (repose +- jitter, strides that are
/// powers of two, wind against fall speed) themselves.
void check_settings(const PipelineSettings& settings);

/// The file frame that --unit-scale and --up give (InputError naming --up
/// for anything but y or z).
FileFrame file_frame(const PipelineSettings& settings);

/// Sets settings.stabilize.cohesion from the snow kind and its overrides
/// (stand_height, hold_depth where not negative). Throws InputError naming
/// --snow for an unknown kind.
void resolve_snow_settings(PipelineSettings& settings);

/// What the planner needs of `settings` (plan::plan_run).
plan::Settings plan_settings(const PipelineSettings& settings);

/// The settings as JSON, grouped by the part before the dot of each key.
nlohmann::json settings_to_json(const PipelineSettings& settings);

/// Overwrites the fields named in `json` (same layout as settings_to_json;
/// a top-level "settings" member is also accepted, as written beside
/// outputs). Throws InputError naming the key for an unknown key or a value
/// of the wrong type (a whole number its field cannot hold included); the
/// ranges are check_settings' job.
void settings_from_json(const nlohmann::json& json, PipelineSettings& settings);

/// Reads a JSON settings file into `settings`; InputError/IOError naming it.
void load_settings_file(const std::string& path, PipelineSettings& settings);

/// Whether the setting `key` is a developer knob: a backend or speed-up
/// that exists to compare or benchmark (the planner picks them), hidden
/// from --help and listed by --help-all.
bool is_developer_setting(const std::string& key);

/// Adds one CLI option per setting to `cmd`, bound to `settings`; their
/// values are assigned after --config is applied, so flags win over it.
/// Developer settings go to a hidden group unless `show_developer`.
void add_settings_options(CLI::App& cmd, PipelineSettings& settings, bool show_developer);

}  // namespace snow::app
