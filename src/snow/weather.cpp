// Weather over time (contract: snow/weather.h): the weather CSV reader, the
// snowpack physics of one step (Hedstrom & Pomeroy 1998 fresh density,
// Verseghy 1991 settling, Douville et al. 1995 albedo, Pellicciotti et al.
// 2005 enhanced temperature-index melt, Kasten & Czeplak 1980 cloud factor),
// the sun's position (NOAA Global Monitoring Division, "General Solar
// Position Calculations": the fractional-year series of Spencer 1971 for the
// declination and the equation of time) and the scene's compass.
#include "snow/weather.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string_view>
#include <system_error>

#include "core/error.h"

namespace snow {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// Rain melt: the heat rain at T C brings, c_w * T per kg, melts c_w * T / L_f
// kg of ice (specific heat of water J/(kg K), latent heat of fusion J/kg).
constexpr double kWaterHeatCapacity = 4186.0;
constexpr double kLatentHeatFusion = 333550.0;

// Douville et al. (1995): dry snow loses this much albedo per day, melting
// snow relaxes at this rate per day, and this much snowfall (m w.e.) renews
// the surface fully.
constexpr double kDryAlbedoLossPerDay = 0.008;
constexpr double kMeltAlbedoRatePerDay = 0.24;
constexpr double kRenewingSnowfall = 0.01;

// Verseghy (1991): settled density limits (kg/m^3) and e-folding rate (1/h).
constexpr double kDryMaxDensity = 300.0;
constexpr double kWetMaxDensity = 500.0;
constexpr double kSettlingRate = 0.01;

// ---- text helpers -----------------------------------------------------------

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

// `text` fit for a one-line message: control bytes shown as '?', cut at 40
// characters.
std::string shown(std::string_view text) {
  constexpr size_t kMax = 40;
  std::string out = "\"";
  for (size_t i = 0; i < text.size() && i < kMax; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    out += (c < 0x20 || c == 0x7f) ? '?' : char(c);
  }
  if (text.size() > kMax) out += "...";
  return out + "\"";
}

// The shortest text that reads back as `v`.
std::string number_text(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

enum class NumberStatus { Ok, NotANumber, NotFinite };

// Parses all of `field` (already trimmed) as a decimal number: an optional
// sign, digits with an optional point, an optional exponent. NaN, infinities
// and overflows are NotFinite.
NumberStatus parse_number(std::string_view field, double& out) {
  if (field.empty()) return NumberStatus::NotANumber;
  std::string_view digits = field;
  if (digits.front() == '+') {
    digits.remove_prefix(1);
    if (digits.empty() || digits.front() == '-' || digits.front() == '+')
      return NumberStatus::NotANumber;
  }
  double v = 0.0;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (r.ptr != digits.data() + digits.size()) return NumberStatus::NotANumber;
  if (r.ec == std::errc::result_out_of_range) return NumberStatus::NotFinite;
  if (r.ec != std::errc()) return NumberStatus::NotANumber;
  if (!std::isfinite(v)) return NumberStatus::NotFinite;
  out = v;
  return NumberStatus::Ok;
}

// ---- the weather file's columns ---------------------------------------------

enum Column {
  kHour,
  kPrecip,
  kTemp,
  kWind,
  kWindFrom,
  kCloud,
  kSunElev,
  kSunAzim,
  kColumnCount,
};

struct ColumnSpec {
  const char* name;
  double min, max;
  const char* range;  // as the error messages show it
  bool required;
};

constexpr ColumnSpec kColumns[kColumnCount] = {
    {"hour", 0.0, 1.0e6, "0..1000000", true},        {"precip_mm", 0.0, 500.0, "0..500", true},
    {"temp_c", -90.0, 60.0, "-90..60", true},        {"wind_ms", 0.0, 25.0, "0..25", true},
    {"wind_from_deg", 0.0, 360.0, "0..360", true},   {"cloud", 0.0, 1.0, "0..1", true},
    {"sun_elev_deg", -90.0, 90.0, "-90..90", false}, {"sun_azim_deg", 0.0, 360.0, "0..360", false},
};

// Splits `line` at commas into trimmed fields.
void split_fields(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(trim(line.substr(start)));
      return;
    }
    fields.push_back(trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
}

// Days since 1970-01-01 of the proleptic Gregorian date y-m-d (Hinnant's
// days_from_civil).
int64_t days_from_civil(int64_t y, int m, int d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const int64_t yoe = y - era * 400;
  const int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

// The year of day `z` since 1970-01-01 (Hinnant's civil_from_days, year only).
int64_t year_of_day(int64_t z) {
  z += 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const int64_t doe = z - era * 146097;
  const int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const int64_t mp = (5 * doy + 2) / 153;
  const int m = int(mp < 10 ? mp + 3 : mp - 9);
  return yoe + era * 400 + (m <= 2);
}

bool is_leap(int64_t y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }

int days_in_month(int64_t y, int m) {
  static constexpr int kDays[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && is_leap(y) ? 29 : kDays[m - 1];
}

}  // namespace

// ---- reading the weather file -----------------------------------------------

std::vector<WeatherStep> parse_weather(const std::string& text, const std::string& name) {
  auto fail = [&](size_t line, const std::string& what) {
    throw InputError(name + ":" + std::to_string(line) + ": " + what);
  };

  std::string_view rest(text);
  if (rest.substr(0, 3) == "\xEF\xBB\xBF") rest.remove_prefix(3);  // UTF-8 byte order mark
  size_t line_no = 0;
  // The next line that is neither blank nor a comment, trimmed; false at the end.
  auto next_line = [&](std::string_view& line) {
    while (!rest.empty()) {
      const size_t nl = rest.find('\n');
      const std::string_view raw = rest.substr(0, nl);
      rest.remove_prefix(nl == std::string_view::npos ? rest.size() : nl + 1);
      ++line_no;
      line = trim(raw);
      if (!line.empty() && line.front() != '#') return true;
    }
    return false;
  };

  std::string_view line;
  if (!next_line(line)) throw InputError(name + ": no header line naming the weather columns");

  // The header: which column each field is.
  std::vector<std::string_view> fields;
  split_fields(line, fields);
  const size_t header_line = line_no;
  const size_t field_count = fields.size();
  std::vector<int> column_of(field_count, -1);
  int field_of[kColumnCount];
  std::fill(field_of, field_of + kColumnCount, -1);
  std::string unknown;
  size_t unknown_count = 0;
  for (size_t f = 0; f < field_count; ++f) {
    if (fields[f].empty()) fail(header_line, "field " + std::to_string(f + 1) + " has no name");
    int c = 0;
    while (c < kColumnCount && fields[f] != kColumns[c].name) ++c;
    if (c == kColumnCount) {
      unknown += (unknown_count++ ? ", '" : "'") + std::string(fields[f].substr(0, 40)) + "'";
      continue;
    }
    if (field_of[c] >= 0) fail(header_line, "column '" + std::string(kColumns[c].name) + "' twice");
    field_of[c] = int(f);
    column_of[f] = c;
  }
  if (unknown_count > 0) {
    fail(header_line, std::string(unknown_count > 1 ? "unknown columns " : "unknown column ") +
                          unknown +
                          " (known: hour, precip_mm, temp_c, wind_ms, wind_from_deg, cloud, "
                          "sun_elev_deg, sun_azim_deg)");
  }
  for (int c = 0; c < kColumnCount; ++c) {
    if (kColumns[c].required && field_of[c] < 0)
      fail(header_line, "missing column '" + std::string(kColumns[c].name) + "'");
  }
  if ((field_of[kSunElev] >= 0) != (field_of[kSunAzim] >= 0)) {
    const bool elev = field_of[kSunElev] >= 0;
    fail(header_line, std::string("column '") + (elev ? "sun_elev_deg" : "sun_azim_deg") +
                          "' without '" + (elev ? "sun_azim_deg" : "sun_elev_deg") +
                          "': give both sun columns or neither");
  }

  // The rows.
  std::vector<WeatherStep> steps;
  double values[kColumnCount];
  while (next_line(line)) {
    split_fields(line, fields);
    if (fields.size() != field_count) {
      fail(line_no, std::to_string(fields.size()) + " field" + (fields.size() == 1 ? "" : "s") +
                        ", the header names " + std::to_string(field_count));
    }
    if (steps.size() == kMaxWeatherRows)
      fail(line_no, "more than " + std::to_string(kMaxWeatherRows) + " weather rows");
    std::fill(values, values + kColumnCount, double(NAN));
    for (size_t f = 0; f < field_count; ++f) {
      const ColumnSpec& spec = kColumns[column_of[f]];
      const std::string column = std::string("column '") + spec.name + "': ";
      double v = 0.0;
      switch (parse_number(fields[f], v)) {
        case NumberStatus::Ok:
          break;
        case NumberStatus::NotANumber:
          fail(line_no, column + shown(fields[f]) + " is not a number");
          break;
        case NumberStatus::NotFinite:
          fail(line_no, column + shown(fields[f]) + " is not a finite number");
          break;
      }
      if (!(v >= spec.min && v <= spec.max)) {
        const std::string value = fields[f].size() <= 40 ? std::string(fields[f]) : number_text(v);
        fail(line_no, column + value + " is out of range " + spec.range);
      }
      values[column_of[f]] = v;
    }
    if (!steps.empty() && !(values[kHour] > steps.back().hour)) {
      fail(line_no, "hours must increase: " + number_text(values[kHour]) + " after " +
                        number_text(steps.back().hour));
    }
    WeatherStep s;
    s.hour = values[kHour];
    s.precip_mm = float(values[kPrecip]);
    s.temp_c = float(values[kTemp]);
    s.wind_ms = float(values[kWind]);
    s.wind_from_deg = float(values[kWindFrom]);
    s.cloud = float(values[kCloud]);
    s.sun_elev_deg = float(values[kSunElev]);
    s.sun_azim_deg = float(values[kSunAzim]);
    steps.push_back(s);
  }
  if (steps.empty()) throw InputError(name + ": no weather rows");

  // Step lengths: to the next row's hour; the last as long as the one before.
  for (size_t i = 0; i + 1 < steps.size(); ++i) steps[i].hours = steps[i + 1].hour - steps[i].hour;
  steps.back().hours = steps.size() > 1 ? steps[steps.size() - 2].hours : 1.0;
  return steps;
}

std::vector<WeatherStep> read_weather(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw IOError("cannot read " + name + ": it is a folder");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IOError("cannot read " + name + ": " + std::strerror(errno));
  // Read in pieces up to one byte past the limit: no trust in a size that a
  // pipe or a special file reports.
  std::string text;
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    text.append(buf, size_t(in.gcount()));
    if (text.size() > kMaxWeatherFileBytes)
      throw InputError(name + ": over 64 MiB, too large for a weather file");
  }
  if (in.bad()) throw IOError("cannot read " + name + ": read error");
  return parse_weather(text, name);
}

// ---- snowpack physics -------------------------------------------------------

float snow_share(float temp_c) {
  if (temp_c <= kSnowAllBelowC) return 1.0f;
  if (temp_c >= kRainAllAboveC) return 0.0f;
  return (kRainAllAboveC - temp_c) / (kRainAllAboveC - kSnowAllBelowC);
}

float snow_water(const WeatherStep& step) {
  return step.precip_mm * 1e-3f * snow_share(step.temp_c);
}

float fresh_snow_depth(const WeatherStep& step) {
  return snow_water(step) * kWaterDensity / fresh_snow_density(step.temp_c);
}

float fresh_snow_density(float temp_c) {
  // Hedstrom & Pomeroy (1998), eq. 3; above 0 C its 0 C value.
  const double t = std::min(double(temp_c), 0.0);
  return float(67.92 + 51.25 * std::exp(t / 2.59));
}

float settled_density(float density, double hours, bool melting) {
  // Verseghy (1991): snow denser than the maximum stays as it is (settling
  // never loosens it).
  const double max = melting ? kWetMaxDensity : kDryMaxDensity;
  if (!(double(density) < max) || !(hours > 0.0)) return density;
  return float((double(density) - max) * std::exp(-kSettlingRate * hours) + max);
}

float aged_albedo(float albedo, double hours, bool melting, float fresh_swe) {
  // The snowfall lands at the step's start, so it renews the surface first
  // and the renewed surface ages through the step.
  double a = albedo;
  if (fresh_swe > 0.0f)
    a += (double(kFreshAlbedo) - a) * std::min(1.0, double(fresh_swe) / kRenewingSnowfall);
  const double days = std::max(hours, 0.0) / 24.0;
  const double old = kOldAlbedo;
  if (melting) {
    a = (a - old) * std::exp(-kMeltAlbedoRatePerDay * days) + old;
  } else if (a > old) {
    // Dry ageing stops at the old-snow albedo; it never raises a darker one.
    a = std::max(a - kDryAlbedoLossPerDay * days, old);
  }
  return float(a);
}

float melt_swe(float temp_c, float absorbed_shortwave, double hours, float rain) {
  double melt = 0.0;
  if (temp_c > kMeltThresholdC) {
    melt = (double(kTemperatureFactor) * temp_c +
            double(kShortwaveFactor) * double(absorbed_shortwave)) *
           hours;
  }
  if (temp_c > 0.0f && rain > 0.0f)
    melt += double(rain) * kWaterHeatCapacity * temp_c / kLatentHeatFusion;
  return float(std::max(melt, 0.0));
}

float shortwave(float elevation_deg, float cos_incidence, float sunlit, float cloud) {
  if (!(elevation_deg > 0.0f)) return 0.0f;
  const double sin_e = std::sin(double(elevation_deg) * kDeg);
  const double direct = double(kSolarConstant) *
                        std::pow(double(kClearSkyTransmissivity), 1.0 / sin_e) *
                        std::max(double(cos_incidence), 0.0) * double(sunlit);
  const double diffuse = double(kDiffuseShare) * double(kSolarConstant) * sin_e;
  const double cloud_factor = 1.0 - 0.75 * std::pow(std::clamp(double(cloud), 0.0, 1.0), 3.4);
  return float((direct + diffuse) * cloud_factor);
}

// ---- the sun ----------------------------------------------------------------

SunPosition sun_position(double unix_seconds, double lat_deg, double lon_deg) {
  if (!(std::abs(unix_seconds) < 1.0e15)) return {NAN, NAN};  // NaN, or past any calendar here
  const double day_floor = std::floor(unix_seconds / 86400.0);
  const int64_t day = int64_t(day_floor);
  const double hour_utc = (unix_seconds - day_floor * 86400.0) / 3600.0;
  const int64_t year = year_of_day(day);
  const double day_of_year = double(day - days_from_civil(year, 1, 1) + 1);  // 1 on January 1
  const double year_days = is_leap(year) ? 366.0 : 365.0;

  // Fractional year (radians).
  const double g = 2.0 * kPi / year_days * (day_of_year - 1.0 + (hour_utc - 12.0) / 24.0);
  // Equation of time (minutes) and solar declination (radians).
  const double eqtime = 229.18 * (0.000075 + 0.001868 * std::cos(g) - 0.032077 * std::sin(g) -
                                  0.014615 * std::cos(2.0 * g) - 0.040849 * std::sin(2.0 * g));
  const double decl = 0.006918 - 0.399912 * std::cos(g) + 0.070257 * std::sin(g) -
                      0.006758 * std::cos(2.0 * g) + 0.000907 * std::sin(2.0 * g) -
                      0.002697 * std::cos(3.0 * g) + 0.00148 * std::sin(3.0 * g);
  // True solar time (minutes) and hour angle (radians, 0 at solar noon).
  const double true_solar_minutes = hour_utc * 60.0 + eqtime + 4.0 * lon_deg;
  const double ha = (true_solar_minutes / 4.0 - 180.0) * kDeg;

  // The direction to the sun in the local east, north, up frame.
  const double lat = lat_deg * kDeg;
  const double east = -std::cos(decl) * std::sin(ha);
  const double north =
      std::sin(decl) * std::cos(lat) - std::cos(decl) * std::sin(lat) * std::cos(ha);
  const double up = std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(ha);

  SunPosition sun;
  sun.elevation_deg = float(std::atan2(up, std::hypot(east, north)) / kDeg);
  double azimuth = std::atan2(east, north) / kDeg;  // clockwise from north
  if (azimuth < 0.0) azimuth += 360.0;
  sun.azimuth_deg = float(azimuth >= 360.0 ? 0.0 : azimuth);
  return sun;
}

double parse_utc(const std::string& text) {
  auto bad = [&](const std::string& why) -> double {
    throw InputError("time " + shown(text) + " " + why);
  };
  const std::string_view s(text);
  // Reads `count` digits at `at` into `out`.
  auto digits = [&](size_t at, size_t count, int& out) {
    if (at + count > s.size()) return false;
    out = 0;
    for (size_t i = at; i < at + count; ++i) {
      if (s[i] < '0' || s[i] > '9') return false;
      out = out * 10 + (s[i] - '0');
    }
    return true;
  };
  const char* form = "is not UTC in the form YYYY-MM-DDTHH:MM[:SS][Z]";
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
  if (!digits(0, 4, year) || s.size() < 16 || s[4] != '-' || !digits(5, 2, month) || s[7] != '-' ||
      !digits(8, 2, day) || (s[10] != 'T' && s[10] != ' ') || !digits(11, 2, hour) ||
      s[13] != ':' || !digits(14, 2, minute)) {
    return bad(form);
  }
  size_t at = 16;
  if (at < s.size() && s[at] == ':') {
    if (!digits(at + 1, 2, second)) return bad(form);
    at += 3;
  }
  if (at < s.size() && s[at] == 'Z') ++at;
  if (at != s.size()) return bad(form);
  if (month < 1 || month > 12) return bad("has no month " + std::to_string(month));
  if (day < 1 || day > days_in_month(year, month)) {
    return bad("has no day " + std::to_string(day) + " in month " + std::to_string(month));
  }
  if (hour > 23 || minute > 59 || second > 59) return bad("is not a time of day (00:00..23:59:59)");
  return double(days_from_civil(year, month, day)) * 86400.0 + hour * 3600.0 + minute * 60.0 +
         second;
}

// ---- the compass ------------------------------------------------------------

glm::vec3 Compass::direction(float azimuth_deg, float elevation_deg) const {
  const glm::vec3 up(0.0f, 1.0f, 0.0f);
  const glm::vec3 n = glm::normalize(glm::vec3(north.x, 0.0f, north.y));
  const glm::vec3 east = glm::cross(n, up);
  const double az = double(azimuth_deg) * kDeg;
  const double el = double(elevation_deg) * kDeg;
  const float horizontal = float(std::cos(el));
  return horizontal * (float(std::cos(az)) * n + float(std::sin(az)) * east) +
         float(std::sin(el)) * up;
}

glm::vec2 Compass::wind(float speed, float from_deg) const {
  const glm::vec3 towards = direction(from_deg + 180.0f, 0.0f);
  return speed * glm::vec2(towards.x, towards.z);
}

}  // namespace snow
