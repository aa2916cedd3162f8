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
  std::vector<std::string> no_snow_on;  // name globs: shelter but receive no snow
  std::vector<std::string> ignore;      // name globs: neither receive nor shelter
};

/// One entry per setting: JSON key ("peel.texel"), CLI flag ("--texel") and
/// help text with the unit. Calls v(key, flag, help, field) for each.
template <class Visitor>
void visit_settings(Visitor&& v, PipelineSettings& s) {
  // Maps (peel).
  v("maps.texel", "--texel", "Map texel size in metres (0 = automatic from --max-side)",
    s.peel.texel);
  v("maps.max_side", "--max-side",
    "Longest map side in texels when --texel is 0 (snow: 0 = automatic, 1024, or where the snow "
    "would lie over 64 texels deep on those, the side that makes it 32)",
    s.peel.max_side);
  v("maps.layers", "--layers", "Surfaces kept per map column, top down (L)", s.peel.layers);
  v("maps.margin", "--margin", "Border around the scene in metres (negative = automatic)",
    s.peel.margin);
  v("maps.merge_distance", "--merge-distance",
    "Surfaces closer than this in metres count as one layer", s.peel.merge_distance);
  v("maps.device", "--peel-device",
    "Where the maps are peeled: gpu (depth passes), cpu (a vertical ray per texel) or auto (the "
    "planner's choice, as `snowmodel info` prints it)",
    s.peel.device);
  v("maps.memory_budget_gib", "--memory-budget",
    "Memory budget in GiB; larger runs stop before allocating", s.memory_budget_gib);
  // Coverage.
  v("coverage.directions", "--directions", "Fall directions sampled (K shadow maps)",
    s.coverage.directions);
  v("coverage.flutter_deg", "--flutter",
    "Flake flutter: half-angle of the cone of fall directions, degrees", s.coverage.flutter_deg);
  v("coverage.wind", "--wind",
    "Horizontal wind X,Z in m/s (tilts the fall by atan(wind/fall speed))", s.coverage.wind);
  v("coverage.fall_speed", "--fall-speed", "Flakes' still-air fall speed in m/s",
    s.coverage.fall_speed);
  v("coverage.seed", "--seed", "Seed of all jitter; same seed, same output", s.coverage.seed);
  v("coverage.batch", "--shadow-batch",
    "Shadow maps rendered per GPU batch (1..32; 0 = automatic: as many as fit in 64 MiB, 8 at "
    "least)",
    s.coverage.batch);
  v("coverage.bias", "--shadow-bias", "Shadow depth bias in metres (negative = automatic)",
    s.coverage.bias);
  v("coverage.method", "--coverage-method",
    "How lines of fall are tested: shadow-maps, cpu-shadow-maps (the same on the CPU cores), rays "
    "(each cast exactly on the GPU), cpu-rays (the same on the CPU cores) or auto (the planner's "
    "choice: the cheapest for the scene and the renderer); same results",
    s.coverage.method);
  // Accumulation and stabilizer.
  v("snow.depth", "--depth", "Fresh snow that falls, metres", s.accumulate.fall_depth);
  v("snow.steps", "--steps", "Time steps of snowfall, each followed by stabilizing",
    s.accumulate.steps);
  v("snow.snow_on_snow_every", "--snow-on-snow-every",
    "Re-render shadows with the lying snow every N steps (0 = off)",
    s.accumulate.snow_on_snow_every);
  v("snow.repose_deg", "--repose", "Angle of repose of the snow, degrees", s.stabilize.repose_deg);
  v("snow.repose_jitter_deg", "--repose-jitter", "Per-texel jitter of the repose angle, +- degrees",
    s.stabilize.repose_jitter_deg);
  v("snow.tolerance", "--tolerance", "Stabilizer stops when the largest move is below this, metres",
    s.stabilize.tolerance);
  v("snow.min_move", "--min-move",
    "Stabilizer moves smaller than this are not made, metres (0 = every move; negative = "
    "automatic: 0.1 x --tolerance)",
    s.stabilize.min_move);
  v("snow.max_iterations", "--max-iterations", "Stabilizer passes at most per step",
    s.stabilize.max_iterations);
  v("snow.max_stride", "--max-stride",
    "Longest stabilizer move in texels (a power of two, 1..64; 1 = single steps)",
    s.stabilize.max_stride);
  v("snow.adaptive_stride", "--adaptive-stride",
    "Start with single steps, longer moves only where the snow creeps (true/false)",
    s.stabilize.adaptive_stride);
  v("snow.device", "--stabilizer",
    "Where the stabilizer runs: gpu, cpu or auto (the planner's choice, as `snowmodel info` "
    "prints it); same results",
    s.stabilize.device);
  v("snow.route_steep", "--route-steep",
    "Route snow off supports steeper than repose in one go (true/false)", s.stabilize.route_steep);
  v("snow.deposit_piles", "--deposit-piles",
    "Lay routed snow as a pile at the angle of repose where it comes to rest, not on one texel "
    "(true/false)",
    s.stabilize.deposit_piles);
  v("snow.drain_edges", "--drain-edges",
    "Once snow creeps off an edge into the void, drain what will leave in one go (true/false)",
    s.stabilize.drain_edges);
  // Meshes.
  v("mesh.min_thickness", "--min-thickness", "Snow thinner than this is no snow, metres",
    s.polygonize.min_thickness);
  v("mesh.decimate_error", "--decimate-error",
    "Decimation error bound in metres (negative = half a texel)", s.polygonize.decimate_error);
  v("mesh.smooth_iterations", "--smooth", "Smoothing passes over the snow top",
    s.polygonize.smooth_iterations);
  v("mesh.min_patch_area", "--min-patch-area", "Drop snow patches smaller than this, square metres",
    s.polygonize.min_patch_area);
  v("mesh.closed", "--closed", "Closed snow solids (true) or open top surfaces only (false)",
    s.polygonize.closed);
  v("mesh.bottom_offset", "--bottom-offset", "Snow bottom lies this far under its support, metres",
    s.polygonize.bottom_offset);
  v("mesh.piece_triangles", "--piece-triangles",
    "A snow patch whose top has more triangles than this is decimated in pieces of about this "
    "many, side by side, on all cores (0 = whole); smaller pieces keep more cores busy, and each "
    "seam keeps its full-grid triangles",
    s.polygonize.piece_triangles);
  // Object filters.
  v("filters.no_snow_on", "--no-snow-on",
    "Name glob of objects that receive no snow but still shelter (repeatable)", s.no_snow_on);
  v("filters.ignore", "--ignore",
    "Name glob of objects that neither receive nor shelter (repeatable)", s.ignore);
}

/// What the planner needs of `settings` (plan::plan_run).
plan::Settings plan_settings(const PipelineSettings& settings);

/// The settings as JSON, grouped by the part before the dot of each key.
nlohmann::json settings_to_json(const PipelineSettings& settings);

/// Overwrites the fields named in `json` (same layout as settings_to_json;
/// a top-level "settings" member is also accepted, as written beside
/// outputs). Throws InputError naming the key for an unknown key or a value
/// of the wrong type.
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
