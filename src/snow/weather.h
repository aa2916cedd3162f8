#pragma once
// Weather over time: a series of time steps read from a CSV file, and the
// snowpack physics each step applies (GL-free). The snowpack is tracked as
// snow water equivalent (SWE, metres of water) per layer texel with a bulk
// density; depth = SWE * kWaterDensity / density (snow/snowpack.h).
//  - Rain or snow: the share of the precipitation that falls as snow is 1 at
//    or below kSnowAllBelowC, 0 at or above kRainAllAboveC, linear between.
//  - Fresh snow density from the air temperature (Hedstrom & Pomeroy 1998,
//    Hydrological Processes 12, eq. 3): 67.92 + 51.25 exp(T / 2.59) kg/m^3
//    for T <= 0 C, the 0 C value above.
//  - Settling: the density relaxes exponentially towards a maximum, 300
//    kg/m^3 for cold snow and 500 kg/m^3 for melting snow, with an e-folding
//    time of 100 hours (Verseghy 1991, Int. J. Climatol. 11, the CLASS
//    land-surface scheme: rho <- (rho - rho_max) exp(-0.01 dt/h) + rho_max).
//  - Albedo ageing (Douville et al. 1995, Climate Dynamics 12): fresh snow
//    0.85; dry snow loses 0.008 per day down to 0.5; melting snow relaxes to
//    0.5 by exp(-0.24 per day); a snowfall of s metres of water equivalent
//    raises it by (0.85 - albedo) * min(1, s / 0.01).
//  - Melt (the enhanced temperature-index model of Pellicciotti et al. 2005,
//    J. Glaciol. 51, eq. 2): above kMeltThresholdC, melt per hour in metres
//    of water = kTemperatureFactor * T + kShortwaveFactor * (1 - albedo) * G,
//    G the shortwave radiation reaching the surface (W/m^2, shortwave()).
//    Rain on snow adds the heat the rain brings: rain * c_w * T / L_f.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace snow {

constexpr float kWaterDensity = 1000.0f;  // kg/m^3
constexpr float kSnowAllBelowC = 0.0f;    // C: all precipitation is snow at or below this
constexpr float kRainAllAboveC = 2.0f;    // C: all of it is rain at or above this
constexpr float kMeltThresholdC = 1.0f;   // C: no melt at or below this air temperature
// Pellicciotti et al. (2005), Haut Glacier d'Arolla: TF = 0.05 mm/(h C),
// SRF = 0.0094 mm m^2/(h W), here in metres of water.
constexpr float kTemperatureFactor = 0.05e-3f;    // m w.e. per hour per C
constexpr float kShortwaveFactor = 0.0094e-3f;    // m w.e. per hour per W/m^2 absorbed
constexpr float kFreshAlbedo = 0.85f;             // Douville et al. (1995)
constexpr float kOldAlbedo = 0.5f;                // the albedo ageing tends to
constexpr float kSolarConstant = 1361.0f;         // W/m^2 at the top of the atmosphere
constexpr float kClearSkyTransmissivity = 0.75f;  // per air mass, direct beam (Hock 1999)
constexpr float kDiffuseShare = 0.15f;            // diffuse radiation on a level surface, share
                                                  // of the top-of-atmosphere radiation x
                                                  // sin(elevation), clear sky

/// The largest weather file read: bytes, and rows (an hourly century).
constexpr size_t kMaxWeatherFileBytes = size_t(64) << 20;
constexpr size_t kMaxWeatherRows = 1000000;

/// One row of the weather file: the weather of the step from `hour` to the
/// next row's hour (the last row lasts as long as the row before it, 1 h
/// when it is the only one).
struct WeatherStep {
  double hour = 0.0;           // hours since the series' start (strictly increasing,
                               // 0..1e6)
  float precip_mm = 0.0f;      // mm of water equivalent fallen during the step (0..500)
  float temp_c = 0.0f;         // air temperature, C (-90..60)
  float wind_ms = 0.0f;        // wind speed, m/s (0..25)
  float wind_from_deg = 0.0f;  // where the wind comes from, degrees clockwise from north
                               // (0..360)
  float cloud = 0.0f;          // cloud cover, 0 (clear) .. 1 (overcast)
  float sun_elev_deg = NAN;    // optional: sun elevation, degrees (-90..90); NaN when the
                               // file has no sun columns (then sun_position())
  float sun_azim_deg = NAN;    // optional: sun azimuth, degrees clockwise from north (0..360)
  double hours = 1.0;          // the step's length in hours (> 0), from the rows' hours
};

/// Reads a weather CSV: a header line naming the columns (any order, names
/// as in WeatherStep: hour, precip_mm, temp_c, wind_ms, wind_from_deg, cloud
/// required; sun_elev_deg and sun_azim_deg optional, both or neither), then
/// one row per step. Blank lines and lines starting with '#' are skipped.
/// Throws InputError with one line naming the file, the line number and the
/// column for a missing column, a field that is not a number, a value out of
/// range (the ranges above), hours not strictly increasing, or no rows;
/// IOError when the file cannot be read. Files over kMaxWeatherFileBytes or
/// kMaxWeatherRows rows are refused.
std::vector<WeatherStep> read_weather(const std::filesystem::path& path);
/// The same from the file's text; `name` stands for the file in errors.
std::vector<WeatherStep> parse_weather(const std::string& text, const std::string& name);

/// Share of the precipitation that falls as snow at air temperature `temp_c`.
float snow_share(float temp_c);
/// Density of fresh snow (kg/m^3) falling at air temperature `temp_c`.
float fresh_snow_density(float temp_c);
/// Metres of water that fall as snow in `step` (its share of the
/// precipitation), and the depth (m) of fresh snow they make.
float snow_water(const WeatherStep& step);
float fresh_snow_depth(const WeatherStep& step);
/// The density (kg/m^3) of snow of density `density` after settling `hours`,
/// melting or not.
float settled_density(float density, double hours, bool melting);
/// The albedo after `hours` of ageing, melting or not, and a snowfall of
/// `fresh_swe` metres of water equivalent at the step's start.
float aged_albedo(float albedo, double hours, bool melting, float fresh_swe);
/// Melt in metres of water equivalent over `hours` at air temperature
/// `temp_c` with `absorbed_shortwave` W/m^2 (already times 1 - albedo), plus
/// the melt by `rain` metres of rain at that temperature; 0 at or below
/// kMeltThresholdC (rain melts above 0 C).
float melt_swe(float temp_c, float absorbed_shortwave, double hours, float rain);

/// Sun position: elevation above the horizon and azimuth clockwise from
/// north, degrees.
struct SunPosition {
  float elevation_deg = 0.0f;
  float azimuth_deg = 0.0f;
};
/// The sun seen from latitude `lat_deg` (north positive), longitude
/// `lon_deg` (east positive) at `unix_seconds` UTC (the NOAA solar
/// calculator's equations: declination and equation of time from the
/// fractional year; within about 0.5 degrees, refraction ignored).
SunPosition sun_position(double unix_seconds, double lat_deg, double lon_deg);
/// Seconds since 1970-01-01 UTC of "YYYY-MM-DDTHH:MM[:SS][Z]" (UTC; a space
/// may stand for the T). Throws InputError naming the text otherwise.
double parse_utc(const std::string& text);

/// Clear-sky and cloud terms of the shortwave radiation (W/m^2) on a surface
/// whose unit normal makes cos_incidence with the direction to the sun
/// (negative: facing away), the sun at `elevation_deg`, lit by the direct
/// beam where sunlit = 1 (0 in shadow; fractions blend): direct beam
/// kSolarConstant * kClearSkyTransmissivity^(1 / sin(elevation)) *
/// max(cos_incidence, 0) * sunlit, plus diffuse kDiffuseShare *
/// kSolarConstant * sin(elevation), all times the cloud factor 1 - 0.75
/// cloud^3.4 (Kasten & Czeplak 1980). 0 with the sun below the horizon.
float shortwave(float elevation_deg, float cos_incidence, float sunlit, float cloud);

/// World directions (+Y up) from the scene's north: `north` is the scene's
/// north in the horizontal plane (x, z), any nonzero length; east is
/// north x up.
struct Compass {
  glm::vec2 north{0.0f, -1.0f};
  /// Unit vector (world, +Y up) towards a point at `azimuth_deg` clockwise
  /// from north and `elevation_deg` above the horizon.
  glm::vec3 direction(float azimuth_deg, float elevation_deg) const;
  /// The horizontal wind (x, z), m/s, of a wind of `speed` coming from
  /// `from_deg` clockwise from north (it blows towards from_deg + 180).
  glm::vec2 wind(float speed, float from_deg) const;
};

}  // namespace snow
