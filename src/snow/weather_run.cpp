// Snowfall driven by a weather series (snow/accumulate.h, accumulate_weather;
// the physics in snow/weather.h and snow/snowpack.h).
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "snow/accumulate.h"
#include "snow/drift.h"
#include "snow/stabilize_cpu.h"
#include "snow/stabilize_step.h"

namespace snow {
namespace {

/// The sun's shadow is drawn at this elevation at least (degrees): the
/// coverage's steepest line of fall (kMaxFallAngleDeg from the vertical).
constexpr float kLowestShadowSun = 90.0f - kMaxFallAngleDeg;

/// The sun of a step at its middle: from the clock and the place where the
/// run has a start, else from the step's own columns, else none.
StepSun sun_of(const WeatherRun& run, const WeatherStep& step) {
  StepSun sun;
  float elevation = step.sun_elev_deg, azimuth = step.sun_azim_deg;
  if (std::isfinite(run.start_unix)) {
    const double middle = run.start_unix + (step.hour + 0.5 * step.hours) * 3600.0;
    const SunPosition p = sun_position(middle, run.latitude_deg, run.longitude_deg);
    elevation = p.elevation_deg;
    azimuth = p.azimuth_deg;
  }
  if (!std::isfinite(elevation) || !std::isfinite(azimuth)) return sun;
  sun.elevation_deg = elevation;
  sun.direction = run.compass.direction(azimuth, elevation);
  return sun;
}

/// Fall settings that draw the shadow of the sun in `direction` (unit,
/// towards the sun): one direction, no flutter, the flakes travelling from
/// the sun.
CoverageSettings sun_shadow_settings(const CoverageSettings& fall, glm::vec3 direction) {
  CoverageSettings s = fall;
  s.directions = 1;
  s.flutter_deg = 0.0f;
  s.fall_speed = 1.0f;
  const float lowest = std::sin(glm::radians(kLowestShadowSun));
  const glm::vec2 horizontal(direction.x, direction.z);
  const float up = std::max(direction.y, lowest);
  s.wind = -horizontal / up * std::sqrt(1.0f - up * up) / std::max(glm::length(horizontal), 1e-6f);
  return s;
}

/// Whether two directions differ by more than kWeatherSunChange.
bool sun_moved(glm::vec3 a, glm::vec3 b) {
  return std::acos(std::clamp(glm::dot(a, b), -1.0f, 1.0f)) >
         float(glm::radians(plan::kWeatherSunChange));
}

template <class AnyStabilizer>
void run_weather(AnyStabilizer& stabilizer, CoverageRenderer& shadows, const SnowMaps& maps,
                 const CoverageSettings& coverage, const StabilizeSettings& stabilize,
                 const WeatherRun& run, SnowPack& pack, const std::vector<uint8_t>& receives,
                 SnowResult& result) {
  std::optional<glm::vec2> fall_wind;   // the wind of result.coverage
  std::optional<glm::vec3> shadow_sun;  // the sun of `sunlit`
  std::vector<float> sunlit;
  // The last frame written before the first step (a resumed run's).
  int frame =
      run.every_hours > 0.0 ? int(std::floor(run.steps.front().hour / run.every_hours + 1e-9)) : 0;
  Progress progress("weather", double(run.steps.size()));
  for (size_t n = 0; n < run.steps.size(); ++n) {
    const WeatherStep& step = run.steps[n];
    const float water = step.precip_mm * 1e-3f;
    const float snow_swe = water * snow_share(step.temp_c);
    const float rain = water - snow_swe;
    if (snow_swe > 0.0f) {
      const glm::vec2 wind = run.compass.wind(step.wind_ms, step.wind_from_deg);
      if (!fall_wind || glm::length(wind - *fall_wind) > float(plan::kWeatherWindChange)) {
        CoverageSettings fall = coverage;
        fall.wind = wind;
        {
          const QuietThread quiet;  // a coverage per wind: the weather's progress shows
          result.coverage = shadows.compute(maps, fall);
        }
        mask_coverage(maps, receives, result.coverage);
        ++result.coverage_updates;
        fall_wind = wind;
      }
      const float density = fresh_snow_density(step.temp_c);
      const float fresh_depth = snow_swe * kWaterDensity / density;
      const double fallen = pack.fallen;
      add_fresh_snow(pack, maps, result.coverage, snow_swe, density);
      result.fallen_volume += (pack.fallen - fallen) * double(kWaterDensity / density);
      std::vector<float> depth = pack.depth;
      const DriftSettings drift =
          drift_for_wind(run.wind_transport ? *fall_wind : glm::vec2(0.0f), run.kind, fresh_depth);
      if (drift.transport > 0.0f) {
        const DriftResult moved = drift_snow(maps, depth, fresh_depth, drift);
        result.drifted += moved.moved;
        result.drifted_in += moved.entered;
        result.drifted_out += moved.left;
      }
      stabilizer.set_depth(depth);
      result.last = stabilize_step(stabilizer, stabilize,
                                   [&](double done) { progress.update(double(n) + done); });
      result.iterations += result.last.iterations;
      account_moves(pack, maps, stabilizer.depth());
    }
    const StepSun sun = sun_of(run, step);
    StepSun lit = sun;
    if (sun.elevation_deg > 0.0f && step.temp_c > kMeltThresholdC) {
      if (!shadow_sun || sun_moved(*shadow_sun, sun.direction)) {
        const QuietThread quiet;
        sunlit = shadows.compute(maps, sun_shadow_settings(coverage, sun.direction));
        shadow_sun = sun.direction;
      }
      lit.sunlit = &sunlit;
    }
    melt_and_settle(pack, maps, step, rain, lit);
    // Frames at the multiples of every_hours since hour 0 (so a resumed
    // run's frames go on counting), and at the end.
    const double end = step.hour + step.hours;
    const bool last = n + 1 == run.steps.size();
    if (run.on_frame && run.every_hours > 0.0) {
      const int due = int(std::floor(end / run.every_hours + 1e-9));
      if (due > frame || last) {
        frame = last && end > double(due) * run.every_hours + 1e-9 ? due + 1 : due;
        run.on_frame(frame, end, pack);
      }
    }
    progress.update(double(n + 1));
  }
  progress.finish();
}

}  // namespace

SnowResult accumulate_weather(const Scene& scene, const SnowMaps& maps,
                              const CoverageSettings& coverage, const StabilizeSettings& stabilize,
                              const WeatherRun& run, SnowPack& pack, const plan::GlFacts& gl,
                              const std::vector<uint8_t>& receives, CoverageBvh* bvh) {
  if (run.steps.empty()) throw InputError("weather: no steps");
  if (pack.depth.size() != maps.ground.size() || pack.swe.size() != maps.ground.size() ||
      pack.albedo.size() != maps.ground.size()) {
    throw InputError("weather: the snowpack does not match the maps");
  }
  SnowResult result;
  std::unique_ptr<CoverageRenderer> shadows = CoverageRenderer::make(scene, maps, gl, bvh);
  result.coverage.assign(maps.ground.size(), 0.0f);
  const bool on_cpu = result.stabilized_on_cpu =
      stabilizes_on_cpu(stabilize, StabilizerUse::Batch, gl);
  const double fallen_before = pack.fallen, melted_before = pack.melted, lost_before = pack.lost;
  if (on_cpu) {
    CpuStabilizer stabilizer(maps, stabilize);
    stabilizer.set_volume_sums(false);
    run_weather(stabilizer, *shadows, maps, coverage, stabilize, run, pack, receives, result);
  } else {
    Stabilizer stabilizer(maps, stabilize);
    stabilizer.set_volume_sums(false);
    run_weather(stabilizer, *shadows, maps, coverage, stabilize, run, pack, receives, result);
  }
  result.depth = pack.depth;
  result.volume = snow_volume(maps, result.depth);
  char line[256];
  std::snprintf(line, sizeof line,
                "weather: %zu steps; water equivalent %.4g m^3 fell as snow, %.4g melted, %.4g "
                "left the maps, %.4g lies",
                run.steps.size(), pack.fallen - fallen_before, pack.melted - melted_before,
                pack.lost - lost_before, pack.lying(maps));
  log_info(line);
  return result;
}

}  // namespace snow
