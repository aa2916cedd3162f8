#pragma once
// Snowfall over time: each step adds fresh snow in proportion to the
// coverage and stabilizes it (docs/ARCHITECTURE.md, "Pipeline and data" and "Stabilizer").
// With snow on snow, the lying snow is drawn into the shadow maps every few
// steps, so drifts shade what lies behind them (Fearing 2000, section 4).
#include <cstdint>
#include <functional>
#include <vector>

#include "scene/scene.h"
#include "snow/coverage.h"
#include "snow/drift.h"
#include "snow/maps.h"
#include "snow/snowpack.h"
#include "snow/stabilize.h"
#include "snow/weather.h"

namespace snow {

/// Most time steps of a run: each step stabilizes the maps (up to
/// StabilizeSettings::max_iterations passes), so the count bounds the run.
constexpr int kMaxSnowSteps = 1000;

struct AccumulateSettings {
  float fall_depth = 0.3f;     // metres of fresh snow on open flat ground, all steps together
                               // (0..1000)
  int steps = 1;               // time steps (1..kMaxSnowSteps); each adds fall_depth/steps *
                               // coverage
  int snow_on_snow_every = 0;  // steps between coverage updates that include the lying snow
                               // (0..kMaxSnowSteps); 0 = off (coverage computed once, from the
                               // bare scene)
  DriftSettings drift;         // the wind's transport of each step's snow before it is stabilized
                               // (snow/drift.h; transport 0: none)
};

struct SnowResult {
  std::vector<float> depth;        // metres per layer texel (maps' layout)
  std::vector<float> coverage;     // the last coverage used, [0,1] (maps' layout)
  StabilizeResult last;            // stabilizer result of the last step
  int iterations = 0;              // stabilizer passes over all steps, count
  int coverage_updates = 0;        // coverage computations (1 + snow-on-snow updates), count
  bool stabilized_on_cpu = false;  // the stabilizer ran on the CPU (StabilizeSettings::device)
  CoverageMethod coverage_method = CoverageMethod::ShadowMaps;  // of the first coverage
  double fallen_volume = 0.0;  // m^3 of snow added, plus what the wind carried in over the
                               // maps' border (drifted_in)
  double lost_volume = 0.0;    // m^3 that left the maps (off the domain), the wind's included
  double drifted_in = 0.0;     // m^3 the wind carried in over the maps' border
  double drifted_out = 0.0;    // m^3 the wind carried off the maps
  double drifted = 0.0;        // m^3 the wind eroded and carried on the maps
  double volume = 0.0;         // m^3 lying at the end; fallen = volume + lost (up to rounding)
};

/// Lets the wind move the snow lying on `stabilizer` (a Stabilizer or a
/// CpuStabilizer): its depth through drift_snow (`fall_depth` metres fell
/// since the last call) and back. set_depth restarts the stabilizer's count
/// of what left the maps, so that count is added to `lost` first.
template <class AnyStabilizer>
DriftResult drift_lying_snow(AnyStabilizer& stabilizer, const SnowMaps& maps, float fall_depth,
                             const DriftSettings& drift, double& lost) {
  lost += stabilizer.lost_volume();
  std::vector<float> depth = stabilizer.depth();
  const DriftResult result = drift_snow(maps, depth, fall_depth, drift);
  stabilizer.set_depth(depth);
  return result;
}

/// Runs the snowfall: coverage once (or every
/// snow_on_snow_every steps with the lying snow included), then per step
/// add fall_depth/steps * coverage, let the wind move it (settings.drift)
/// and stabilize (Stabilizer::iterate in
/// chunks, as Stabilizer::run, for progress reports; on the GPU, or on the
/// CPU as stabilize.device says). Objects
/// with receives[object] == 0 get no fresh snow (snow sliding onto them
/// still rests there). Reports progress. Needs a current GL context, or a
/// gl::OnDemandContext that the passes make when they use GL. `bvh`, if
/// given, is the coverage's BVH built ahead over `scene` (build_coverage_bvh;
/// taken from). `gl`: what GL renders on and whether it has started, as the
/// caller's plan knows it (CoverageRenderer::set_gl, stabilizes_on_cpu).
/// Throws InputError for bad settings, GLError for GL trouble.
SnowResult accumulate(const Scene& scene, const SnowMaps& maps, const CoverageSettings& coverage,
                      const StabilizeSettings& stabilize, const AccumulateSettings& settings,
                      const plan::GlFacts& gl, const std::vector<uint8_t>& receives = {},
                      CoverageBvh* bvh = nullptr);

/// A snowfall driven by a weather series (snow/weather.h): per step, the
/// snow part of the precipitation falls with the step's wind (its coverage,
/// and above the drift threshold its transport), the stabilizer settles it,
/// then the pack melts in the sun (one shadow map towards the sun: the
/// coverage with one direction) and settles (snow/snowpack.h).
struct WeatherRun {
  std::vector<WeatherStep> steps;   // read_weather's
  double start_unix = NAN;          // UTC seconds of hour 0; NaN: the sun from the steps' own
                                    // sun columns (none there: no sunshine)
  double latitude_deg = 0.0;        // -90..90, north positive
  double longitude_deg = 0.0;       // -180..180, east positive
  Compass compass;                  // the scene's north
  SnowKind kind = SnowKind::Fresh;  // its drift threshold (drift_for_wind)
  bool wind_transport = true;       // false: the wind only tilts the fall
  /// With every_hours > 0, called at the end of each step whose end (the
  /// steps' hours count from 0) reaches a multiple n * every_hours not
  /// reached before, with that n, and after the last step (n + 1 where it
  /// ends past n * every_hours), with the hour and the pack (its depth is
  /// what lies).
  double every_hours = 0.0;
  std::function<void(int frame, double hour, const SnowPack& pack)> on_frame;
  /// Called once, with the pack, at the end of the first step that ends at
  /// or after tracks_hour (the steps' hours), before that step's frame:
  /// what it changes in the pack (tracks pressed into it) lies under the
  /// snow of the steps after.
  double tracks_hour = 0.0;
  std::function<void(SnowPack& pack)> on_tracks;
};

/// Runs `run` from `pack` (an empty pack, SnowPack::empty, or a resumed
/// one; on return the pack at the end). `coverage` gives the fall's other
/// settings (directions, flutter, fall speed, seed); its wind is each
/// step's. SnowResult's depth is the pack's, its coverage the last
/// snowfall's, fallen_volume the fresh snow's volume (m^3) and volume what
/// lies; melt and settling change volumes, so the balance is the pack's, in
/// water (lost_volume stays 0). Throws as accumulate.
SnowResult accumulate_weather(const Scene& scene, const SnowMaps& maps,
                              const CoverageSettings& coverage, const StabilizeSettings& stabilize,
                              const WeatherRun& run, SnowPack& pack, const plan::GlFacts& gl,
                              const std::vector<uint8_t>& receives = {},
                              CoverageBvh* bvh = nullptr);

}  // namespace snow
