// The batch job's weather runs (app/snow_weather.h).
#include "app/snow_weather.h"

#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "snow/cohesion.h"

namespace snow::app {
namespace {

/// The snowpack values a maps folder holds, in this order.
const std::vector<std::string> kPackNames = {"depth", "swe", "albedo"};

}  // namespace

std::optional<WeatherRun> weather_run_of(const PipelineSettings& s) {
  if (s.weather.empty()) return std::nullopt;
  WeatherRun run;
  run.steps = read_weather(s.weather);
  if (!s.start.empty()) run.start_unix = parse_utc(s.start);
  run.latitude_deg = s.latitude;
  run.longitude_deg = s.longitude;
  if (!(glm::length(s.north) > 0.0f)) throw InputError("--north must not be 0,0");
  run.compass.north = s.north;
  run.kind = snow_kind_from_name(s.snow_kind);
  run.wind_transport = s.wind_transport;
  return run;
}

float weather_fall_depth(const WeatherRun& run) {
  double depth = 0.0;
  for (const WeatherStep& step : run.steps) depth += double(fresh_snow_depth(step));
  return float(std::min(depth, 1000.0));
}

SnowPack starting_pack(const std::string& resume_dir, const SnowMaps& maps, double first_hour,
                       double& hour) {
  SnowPack pack = SnowPack::empty(maps);
  hour = 0.0;
  if (resume_dir.empty()) return pack;
  std::vector<std::vector<float>> values;
  const MapsSnowpack read = read_maps_snowpack(resume_dir, maps, kPackNames, values);
  if (read.hour > first_hour + 1e-9) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "--resume: the maps hold %.6g hours of weather; the file starts at hour %.6g "
                  "(its hours go on from the first run's)",
                  read.hour, first_hour);
    throw InputError(line);
  }
  pack.depth = std::move(values[0]);
  pack.swe = std::move(values[1]);
  pack.albedo = std::move(values[2]);
  for (size_t k = 0; k < pack.swe.size(); ++k) {
    // Snow water where no depth is left, and the reverse, are rounding.
    if (!(pack.depth[k] > 0.0f) || !(pack.swe[k] > 0.0f)) pack.depth[k] = pack.swe[k] = 0.0f;
    if (!(pack.albedo[k] > 0.0f)) pack.albedo[k] = kFreshAlbedo;
  }
  pack.fallen = read.fallen;
  pack.melted = read.melted;
  pack.lost = read.lost;
  hour = read.hour;
  return pack;
}

}  // namespace snow::app
