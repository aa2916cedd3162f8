// One weather step on the maps (snow/weather_step.h).
#include "snow/weather_step.h"

#include <algorithm>
#include <cmath>

#include "core/log.h"
#include "snow/drift.h"

namespace snow {
namespace {

/// The sun's shadow is drawn at this elevation at least (degrees): the
/// coverage's steepest line of fall (kMaxFallAngleDeg from the vertical).
constexpr float kLowestShadowSun = 90.0f - kMaxFallAngleDeg;

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

}  // namespace

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

WeatherStepper::WeatherStepper(CoverageRenderer& shadows, const SnowMaps& maps,
                               const CoverageSettings& fall, const WeatherRun& run,
                               const std::vector<uint8_t>& receives)
    : shadows_(shadows),
      maps_(maps),
      fall_(fall),
      run_(run),
      receives_(receives),
      coverage_(maps.ground.size(), 0.0f) {}

void WeatherStepper::forget() {
  fall_wind_.reset();
  shadow_sun_.reset();
}

std::optional<std::vector<float>> WeatherStepper::snowfall(const WeatherStep& step, SnowPack& pack,
                                                           SnowResult& stats) {
  const float snow_swe = snow_water(step);
  if (!(snow_swe > 0.0f)) return std::nullopt;
  const glm::vec2 wind = run_.compass.wind(step.wind_ms, step.wind_from_deg);
  if (!fall_wind_ || glm::length(wind - *fall_wind_) > float(plan::kWeatherWindChange)) {
    CoverageSettings fall = fall_;
    fall.wind = wind;
    {
      const QuietThread quiet;  // a coverage per wind: the weather's progress shows
      coverage_ = shadows_.compute(maps_, fall);
    }
    mask_coverage(maps_, receives_, coverage_);
    ++stats.coverage_updates;
    fall_wind_ = wind;
  }
  const float density = fresh_snow_density(step.temp_c);
  const float fresh_depth = fresh_snow_depth(step);
  const double fallen = pack.fallen;
  add_fresh_snow(pack, maps_, coverage_, snow_swe, density);
  stats.fallen_volume += (pack.fallen - fallen) * double(kWaterDensity / density);
  std::vector<float> depth = pack.depth;
  const DriftSettings drift =
      drift_for_wind(run_.wind_transport ? *fall_wind_ : glm::vec2(0.0f), run_.kind, fresh_depth);
  if (drift.transport > 0.0f) {
    const DriftResult moved = drift_snow(maps_, depth, fresh_depth, drift);
    stats.drifted += moved.moved;
    stats.drifted_in += moved.entered;
    stats.drifted_out += moved.left;
  }
  return depth;
}

void WeatherStepper::melt(const WeatherStep& step, SnowPack& pack) {
  const float rain = step.precip_mm * 1e-3f - snow_water(step);
  const StepSun sun = sun_of(run_, step);
  StepSun lit = sun;
  if (sun.elevation_deg > 0.0f && step.temp_c > kMeltThresholdC) {
    if (!shadow_sun_ || sun_moved(*shadow_sun_, sun.direction)) {
      const QuietThread quiet;
      sunlit_ = shadows_.compute(maps_, sun_shadow_settings(fall_, sun.direction));
      shadow_sun_ = sun.direction;
    }
    lit.sunlit = &sunlit_;
  }
  melt_and_settle(pack, maps_, step, rain, lit);
}

}  // namespace snow
