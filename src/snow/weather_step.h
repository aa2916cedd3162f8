#pragma once
// One step of a weather series (snow/weather.h) on the maps, shared by the
// batch job (accumulate_weather) and the live preview: the snowfall of the
// step (fresh snow along the coverage of the step's wind, then the wind's
// transport) and the melt after it (the sun's shadow from one more shadow
// map: the coverage with one direction towards the sun). Stabilizing sits
// between the two and is the caller's: the batch job runs it to rest, the
// preview spreads it over frames.
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "snow/accumulate.h"
#include "snow/coverage.h"
#include "snow/maps.h"
#include "snow/snowpack.h"
#include "snow/weather.h"

namespace snow {

/// The sun of `step` at its middle: from the run's clock and place where it
/// has a start, else from the step's own sun columns, else none (below the
/// horizon).
StepSun sun_of(const WeatherRun& run, const WeatherStep& step);

/// Carries what a series reuses from step to step: the coverage of the last
/// snowfall's wind (recomputed when the wind changes by more than
/// plan::kWeatherWindChange) and the sun's shadow (recomputed when the sun
/// moves by more than plan::kWeatherSunChange). Keeps references to all its
/// arguments, which must outlive it.
class WeatherStepper {
 public:
  /// `fall`: the fall's settings but the wind (each step's own).
  /// `receives[object]` == 0 keeps fresh snow off that object (may be empty).
  WeatherStepper(CoverageRenderer& shadows, const SnowMaps& maps, const CoverageSettings& fall,
                 const WeatherRun& run, const std::vector<uint8_t>& receives);

  /// The snow part of `step`: fresh snow added to `pack` along the coverage
  /// of the step's wind; returns the depth after the wind moved it (the
  /// pack's depth where no wind transports; not yet accounted: pass the
  /// depth after stabilizing to account_moves), or nothing when no snow
  /// falls. Adds the fresh snow's volume and the wind's moves to `stats`
  /// (fallen_volume, drifted, drifted_in, drifted_out, coverage_updates).
  std::optional<std::vector<float>> snowfall(const WeatherStep& step, SnowPack& pack,
                                             SnowResult& stats);
  /// The melt, settling and ageing of `step` on `pack` (melt_and_settle),
  /// the rain being the part of the precipitation that is not snow.
  void melt(const WeatherStep& step, SnowPack& pack);
  /// The coverage of the last snowfall (all 0 before the first).
  const std::vector<float>& coverage() const { return coverage_; }
  /// Forgets the coverage and the shadow (the fall's settings changed).
  void forget();

 private:
  CoverageRenderer& shadows_;
  const SnowMaps& maps_;
  const CoverageSettings& fall_;
  const WeatherRun& run_;
  const std::vector<uint8_t>& receives_;
  std::vector<float> coverage_;
  std::optional<glm::vec2> fall_wind_;   // the wind of coverage_
  std::optional<glm::vec3> shadow_sun_;  // the sun of sunlit_
  std::vector<float> sunlit_;
};

}  // namespace snow
