#pragma once
// The planner: one place for every automatic choice of a run (which
// backend runs each stage, the map size, GL warm-up, the BVH built ahead,
// the heap's huge pages), made from plain facts about the scene and the
// machine and handed to the stages as arguments. `snowmodel info` and
// `snowmodel snow -v` print the plan. The choices that need a stage's own
// figures are plan/rules.h's.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "plan/rules.h"

namespace snow::plan {

/// What the batch job knows of the machine before any context is made.
struct MachineInfo {
  /// Whether GL renders in software (gl::probe_software): empty where only
  /// a context can tell (GLFW, EGL without device enumeration) and where
  /// the backend is named (--gl-backend, SNOWMODEL_GL_BACKEND).
  std::optional<bool> software;
  /// The GL backend is a window (GLFW), which must start on the main thread.
  bool window_backend = false;
  /// CPU cores the stages may use (parallel_for's default_threads()), >= 1.
  unsigned cores = 1;
  /// The (virtual) machine hands free memory back to its host in 2 MiB
  /// blocks (core/heap.h, free_pages_reported): huge pages cost more there.
  bool reports_free_pages = false;
};

/// Fresh snow deeper than this many texels lies on maps far finer than its
/// shapes need: pillows, cornices and repose slopes are about as wide as the
/// snow is deep or wider, while every stage's time grows with the texel
/// count (a small object under deep snow pays for texels that add nothing).
constexpr float kDeepTexels = 64.0f;  // texels of snow depth
/// The depth in texels the automatic map side and the warning aim at.
constexpr float kAimTexels = 32.0f;  // texels of snow depth
/// The automatic map side where the snow is not too deep on it.
constexpr int kAutoMaxSide = 1024;  // texels
/// The smallest automatic map side.
constexpr int kMinAutoSide = 16;  // texels

/// The map side (at least kMinAutoSide) that makes `fall_depth` metres
/// kAimTexels texels deep on a grid whose longer side has `side` texels of
/// `texel` metres.
int side_for_depth(int side, float texel, float fall_depth);

/// Inputs this large load for long enough to hide a GPU driver's start, so
/// a throwaway context is made beside their load.
constexpr uint64_t kWarmUpInputBytes = uint64_t(16) << 20;  // bytes

/// A large job: maps of this many texel columns or more, or an input of
/// this many bytes or more. On a machine that hands free memory back to its
/// host, a large job turns the heap's huge pages off (core/heap.h).
constexpr size_t kLargeJobColumns = size_t(512) * 512;        // texel columns
constexpr uint64_t kLargeJobInputBytes = uint64_t(32) << 20;  // bytes

/// Decimation in pieces: a snow patch whose top has more triangles than
/// this is decimated in pieces of about this many on all cores
/// (PolygonizeSettings::piece_triangles; the same pieces on any machine).
/// Smaller pieces spread over more cores for a few per cent more triangles.
constexpr size_t kPieceTriangles = 25000;  // triangles

/// The live preview's defaults, coarser than the batch job's so that it
/// stays interactive: maps of this many texels on the longer side, and
/// this many fall directions (recomputed on every change of the fall
/// settings).
constexpr int kPreviewMaxSide = 512;    // texels
constexpr int kPreviewDirections = 32;  // fall directions

/// What the user asked for, of the settings the plan depends on.
struct Settings {
  float fall_depth = 0.3f;               // metres of fresh snow
  float texel = 0.0f;                    // metres; 0 = from max_side
  int max_side = 0;                      // texels; 0 = automatic (with texel 0)
  int auto_side = kAutoMaxSide;          // texels: the automatic side before the deep-snow
                                         // rule (kPreviewMaxSide for the live preview)
  std::string peel_device = "auto";      // "auto", "cpu", "gpu"
  std::string coverage_method = "auto";  // CoverageSettings::method
  std::string stabilizer = "auto";       // "auto", "cpu", "gpu"
};

/// The maps' resolution.
struct MapPlan {
  float texel = 0.0f;           // metres, as asked for (0: from max_side)
  int max_side = kAutoMaxSide;  // texels: the peel's max_side (where texel is 0)
  std::string note;             // why an automatic side differs from auto_side (or empty)
};

/// The map side for `settings`: the one asked for, or where it is automatic
/// (max_side 0 and texel 0), settings.auto_side, or where the snow would lie
/// more than kDeepTexels deep on that, the side that makes it kAimTexels
/// deep. `grid_side` (texels) and `grid_texel` (metres) describe the grid at
/// the side asked for (auto_side where automatic), as make_grid makes it.
MapPlan plan_maps(const Settings& settings, int grid_side, float grid_texel);

/// Facts about the scene, as make_grid and the loader find them.
struct SceneStats {
  uint64_t input_bytes = 0;  // bytes of the input files (gltf_input_bytes)
  size_t triangles = 0;
  int asked_grid_side = 0;        // texels, the longer side of the grid plan_maps is given
  float asked_grid_texel = 0.0f;  // metres, its texel
  size_t grid_columns = 0;        // texel columns (width x height) of the grid at plan_maps' side
};

/// Whether a throwaway GL context is made beside the load, so that the
/// first stage's context comes cheaply: on a GPU for inputs of
/// kWarmUpInputBytes or more, and where only a context can tell the
/// renderer; never for a window backend (it must start on the main thread)
/// nor in software (small scenes there need no GL at all).
bool warm_up_gl(const MachineInfo& machine, uint64_t input_bytes);

/// Whether the heap's huge pages go off for a job of `input_bytes` and
/// `columns` texel columns (0 where not known yet): a large job on a
/// machine that hands free memory back to its host (core/heap.h).
bool huge_pages_off(const MachineInfo& machine, uint64_t input_bytes, size_t columns);

/// The choices of a run.
struct RunPlan {
  MapPlan maps;
  GlFacts gl;                     // GL as the stages will find it when the peel begins
  bool bvh_ahead = false;         // build the coverage's BVH on another thread beside the peel
                                  // (on a GPU, whose peel leaves the CPU cores idle)
  bool bvh_morton = false;        // the coverage BVH's build (coverage_bvh_morton)
  bool huge_pages_off = false;    // turn the heap's huge pages off once the maps' size is known
  bool stabilizer_on_cpu = true;  // the batch job's
  bool preview_stabilizer_on_cpu = true;  // the live preview's (StabilizerUse::Live)
  std::string peel;                       // where the peel runs, in words
  std::string coverage;                   // how the coverage is found, in words
};

/// The plan for a run of `settings` on `machine` over a scene with `stats`;
/// `gl_started`: a GL context exists already (a warm-up, a window). Plain
/// data in, plain data out: no GL, no files.
RunPlan plan_run(const SceneStats& stats, const MachineInfo& machine, const Settings& settings,
                 bool gl_started);

/// The plan in lines for people (`snowmodel info`, `snow -v`).
std::vector<std::string> describe(const RunPlan& plan);

}  // namespace snow::plan
