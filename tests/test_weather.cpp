// Weather over time (snow/weather.h): the weather CSV reader and its errors,
// the snowpack physics of a step against the papers' formulas, the sun's
// position against reference positions, UTC parsing and the scene's compass.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.h"
#include "snow/weather.h"
#include "support/files.h"

namespace snow {
namespace {

namespace fs = std::filesystem;

// ---- physics ----------------------------------------------------------------

TEST(WeatherPhysics, SnowShareFallsLinearlyFromZeroToTwoDegrees) {
  EXPECT_EQ(snow_share(-1.0f), 1.0f);
  EXPECT_EQ(snow_share(0.0f), 1.0f);
  EXPECT_FLOAT_EQ(snow_share(1.0f), 0.5f);
  EXPECT_EQ(snow_share(2.0f), 0.0f);
  EXPECT_EQ(snow_share(3.0f), 0.0f);
}

TEST(WeatherPhysics, FreshDensityFollowsHedstromPomeroy) {
  EXPECT_NEAR(fresh_snow_density(0.0f), 119.17f, 1e-3f);
  EXPECT_NEAR(fresh_snow_density(5.0f), 119.17f, 1e-3f);  // the 0 C value above 0 C
  EXPECT_NEAR(fresh_snow_density(-20.0f), 67.92f + 51.25f * std::exp(-20.0f / 2.59f), 1e-3f);
  EXPECT_NEAR(fresh_snow_density(-20.0f), 68.0f, 0.5f);
  // Colder snow is lighter.
  EXPECT_LT(fresh_snow_density(-5.0f), fresh_snow_density(-1.0f));
  // 10 mm of water makes the 8-15 cm of new snow forecasters expect.
  for (float t : {0.0f, -5.0f, -20.0f}) {
    const float depth = 0.010f * kWaterDensity / fresh_snow_density(t);
    EXPECT_GE(depth, 0.08f) << t;
    EXPECT_LE(depth, 0.15f) << t;
  }
}

TEST(WeatherPhysics, SettlingMovesOneMinusOneOverEOfTheWayPerHundredHours) {
  const float e = std::exp(-1.0f);
  EXPECT_NEAR(settled_density(100.0f, 100.0, false), 300.0f - 200.0f * e, 1e-3f);
  EXPECT_NEAR(settled_density(100.0f, 100.0, true), 500.0f - 400.0f * e, 1e-3f);
  EXPECT_EQ(settled_density(100.0f, 0.0, false), 100.0f);
  // Two steps of 50 h settle as one of 100 h.
  EXPECT_NEAR(settled_density(settled_density(100.0f, 50.0, false), 50.0, false),
              settled_density(100.0f, 100.0, false), 1e-3f);
  // Snow denser than the dry maximum does not loosen.
  EXPECT_EQ(settled_density(400.0f, 100.0, false), 400.0f);
  EXPECT_GT(settled_density(400.0f, 100.0, true), 400.0f);
}

TEST(WeatherPhysics, MeltFollowsTheEnhancedTemperatureIndex) {
  // +4 C, no sun: TF * T per hour.
  EXPECT_NEAR(melt_swe(4.0f, 0.0f, 1.0, 0.0f), 4.0 * 0.05e-3, 4.0 * 0.05e-3 * 1e-6);
  EXPECT_NEAR(melt_swe(4.0f, 0.0f, 3.0, 0.0f), 3.0 * 4.0 * 0.05e-3, 3.0 * 4.0 * 0.05e-3 * 1e-6);
  // With 200 W/m^2 absorbed: plus SRF * G.
  EXPECT_NEAR(melt_swe(4.0f, 200.0f, 1.0, 0.0f), 4.0 * 0.05e-3 + 200.0 * 0.0094e-3, 1e-9);
  // At or below the threshold: nothing, however bright.
  EXPECT_EQ(melt_swe(1.0f, 0.0f, 1.0, 0.0f), 0.0f);
  EXPECT_EQ(melt_swe(1.0f, 500.0f, 1.0, 0.0f), 0.0f);
  EXPECT_EQ(melt_swe(-5.0f, 500.0f, 1.0, 0.0f), 0.0f);
  // Never negative.
  EXPECT_EQ(melt_swe(2.0f, -1000.0f, 1.0, 0.0f), 0.0f);
}

TEST(WeatherPhysics, RainMeltsByTheHeatItBrings) {
  const float rain = 0.010f;  // 10 mm
  // Above 0 C but below the melt threshold: the rain's heat alone.
  EXPECT_NEAR(melt_swe(0.5f, 0.0f, 1.0, rain), 0.010 * 4186.0 * 0.5 / 333550.0, 1e-9);
  EXPECT_NEAR(melt_swe(5.0f, 0.0f, 1.0, rain), 5.0 * 0.05e-3 + 0.010 * 4186.0 * 5.0 / 333550.0,
              1e-9);
  EXPECT_EQ(melt_swe(-1.0f, 0.0f, 1.0, rain), 0.0f);
}

TEST(WeatherPhysics, AlbedoAgesAsDouville) {
  // Dry: 0.008 per day, down to 0.5.
  EXPECT_NEAR(aged_albedo(0.85f, 24.0, false, 0.0f), 0.842f, 1e-5f);
  EXPECT_NEAR(aged_albedo(0.85f, 24.0 * 100.0, false, 0.0f), 0.5f, 1e-6f);
  EXPECT_NEAR(aged_albedo(0.45f, 24.0, false, 0.0f), 0.45f, 1e-6f);  // never brightens
  // Melting: towards 0.5 by exp(-0.24 per day).
  EXPECT_NEAR(aged_albedo(0.85f, 24.0, true, 0.0f), 0.5f + 0.35f * std::exp(-0.24f), 1e-5f);
  EXPECT_NEAR(aged_albedo(0.85f, 24.0 * 60.0, true, 0.0f), 0.5f, 1e-4f);
  // A snowfall renews the surface: half of 10 mm halfway, 10 mm or more fully.
  EXPECT_NEAR(aged_albedo(0.6f, 0.0, false, 0.005f), 0.725f, 1e-5f);
  EXPECT_NEAR(aged_albedo(0.6f, 0.0, false, 0.010f), 0.85f, 1e-5f);
  EXPECT_NEAR(aged_albedo(0.6f, 0.0, false, 0.050f), 0.85f, 1e-5f);
  // The snowfall lands at the step's start, then the new surface ages.
  EXPECT_NEAR(aged_albedo(0.6f, 24.0, false, 0.010f), 0.842f, 1e-5f);
}

TEST(WeatherPhysics, ShortwaveIsZeroAtNightAndAQuarterUnderFullCloud) {
  EXPECT_EQ(shortwave(-5.0f, 1.0f, 1.0f, 0.0f), 0.0f);
  EXPECT_EQ(shortwave(0.0f, 1.0f, 1.0f, 0.0f), 0.0f);
  // Sun overhead, clear: the beam through one air mass plus the diffuse share.
  const float clear = shortwave(90.0f, 1.0f, 1.0f, 0.0f);
  EXPECT_NEAR(clear, 1361.0f * (0.75f + 0.15f), 0.01f);
  EXPECT_NEAR(shortwave(90.0f, 1.0f, 1.0f, 1.0f), 0.25f * clear, 0.01f);
  EXPECT_NEAR(shortwave(30.0f, 0.5f, 1.0f, 1.0f), 0.25f * shortwave(30.0f, 0.5f, 1.0f, 0.0f),
              0.01f);
  // In shadow, or facing away: the diffuse part only.
  const float diffuse = 0.15f * 1361.0f * 0.5f;
  EXPECT_NEAR(shortwave(30.0f, 1.0f, 0.0f, 0.0f), diffuse, 0.01f);
  EXPECT_NEAR(shortwave(30.0f, -0.5f, 1.0f, 0.0f), diffuse, 0.01f);
  // A low sun crosses more air: 30 degrees is two air masses.
  EXPECT_NEAR(shortwave(30.0f, 1.0f, 1.0f, 0.0f), 1361.0f * 0.75f * 0.75f + diffuse, 0.01f);
}

// ---- the sun ----------------------------------------------------------------

// Reference positions from the Astronomical Almanac's low-precision solar
// formulas (about 0.01 degrees; an algorithm other than NOAA's), which agree
// with the NOAA solar calculator (Boulder at its June solstice noon: 73.4).
// The fractional-year series is furthest off near the equinoxes, where the
// declination changes fastest and the leap-year cycle shifts the equinox
// against the calendar by up to a day (0.4 degrees of declination).
struct SunCase {
  const char* what;
  const char* utc;
  double lat, lon;
  float elevation, azimuth;  // degrees; azimuth NaN: not compared
};

TEST(WeatherSun, PositionsMatchReferenceWithinHalfADegree) {
  const SunCase cases[] = {
      {"Boulder, June solstice, solar noon", "2026-06-21T19:00Z", 40.0, -105.0, 73.430f, 178.48f},
      {"Boulder, June solstice, morning", "2026-06-21T13:00Z", 40.0, -105.0, 14.478f, 71.365f},
      {"Boulder, midnight", "2026-06-22T07:00Z", 40.0, -105.0, -26.566f, 359.49f},
      {"equator, March equinox, solar noon", "2026-03-20T12:07Z", 0.0, 0.0, 89.877f, NAN},
      {"Sydney, December solstice, noon", "2025-12-21T02:00Z", -33.87, 151.21, 79.457f, 351.37f},
      {"Tromso, polar night, noon", "2025-12-21T10:00Z", 69.65, 18.96, -3.396f, 170.29f},
      {"London, January, 9 UTC", "2026-01-15T09:00Z", 51.5, -0.13, 6.375f, 136.22f},
      {"north pole, June solstice", "2026-06-21T12:00Z", 90.0, 0.0, 23.435f, NAN},
      {"south pole, June solstice", "2026-06-21T12:00Z", -90.0, 0.0, -23.435f, NAN},
  };
  for (const SunCase& c : cases) {
    const SunPosition sun = sun_position(parse_utc(c.utc), c.lat, c.lon);
    EXPECT_NEAR(sun.elevation_deg, c.elevation, 0.5f) << c.what;
    if (!std::isnan(c.azimuth)) {
      float d = std::fabs(sun.azimuth_deg - c.azimuth);
      d = std::fmin(d, 360.0f - d);
      EXPECT_LT(d, 0.5f) << c.what << ": azimuth " << sun.azimuth_deg;
    }
    EXPECT_GE(sun.azimuth_deg, 0.0f) << c.what;
    EXPECT_LT(sun.azimuth_deg, 360.0f) << c.what;
  }
}

TEST(WeatherSun, NoonSunIsSouthInTheNorthAndNorthInTheSouth) {
  // Solar noon at longitude 0 in mid-January is about 12:09 UTC.
  const double noon = parse_utc("2026-01-15T12:09");
  EXPECT_NEAR(sun_position(noon, 47.0, 0.0).azimuth_deg, 180.0f, 1.0f);
  const float south = sun_position(noon, -47.0, 0.0).azimuth_deg;
  EXPECT_LT(std::fmin(south, 360.0f - south), 1.0f);
  // Noon is the day's highest sun; midnight is below the horizon.
  const float high = sun_position(noon, 47.0, 0.0).elevation_deg;
  for (double dh : {-3.0, -1.0, 1.0, 3.0})
    EXPECT_LT(sun_position(noon + dh * 3600.0, 47.0, 0.0).elevation_deg, high);
  EXPECT_LT(sun_position(noon + 12.0 * 3600.0, 47.0, 0.0).elevation_deg, 0.0f);
}

TEST(WeatherSun, ParseUtcReadsKnownInstants) {
  EXPECT_EQ(parse_utc("1970-01-01T00:00"), 0.0);
  EXPECT_EQ(parse_utc("2000-03-01T00:00Z"), 951868800.0);
  EXPECT_EQ(parse_utc("2000-02-29T00:00Z"), 951868800.0 - 86400.0);
  EXPECT_EQ(parse_utc("2026-01-15T06:00:30Z"), parse_utc("2026-01-15T06:00") + 30.0);
  EXPECT_EQ(parse_utc("2026-01-15 06:00"), parse_utc("2026-01-15T06:00"));
  EXPECT_EQ(parse_utc("1969-12-31T23:59:59"), -1.0);
}

TEST(WeatherSun, ParseUtcRejectsWhatIsNotAnInstant) {
  for (const char* bad : {"2026-13-01T00:00", "2026-00-01T00:00", "2026-02-29T00:00",
                          "2026-04-31T00:00", "2026-01-15T24:00", "2026-01-15T06:60",
                          "2026-01-15T06:00:60", "yesterday", "", "2026-01-15", "2026-1-15T06:00",
                          "2026-01-15T06:00+01:00", "2026-01-15T06:00Zx", " 2026-01-15T06:00"}) {
    try {
      parse_utc(bad);
      ADD_FAILURE() << "accepted \"" << bad << "\"";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string("\"") + bad), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}

// ---- the compass ------------------------------------------------------------

void expect_vec_near(const glm::vec3& a, const glm::vec3& b, const char* what) {
  EXPECT_NEAR(a.x, b.x, 1e-5f) << what;
  EXPECT_NEAR(a.y, b.y, 1e-5f) << what;
  EXPECT_NEAR(a.z, b.z, 1e-5f) << what;
}

TEST(WeatherCompass, DefaultNorthIsMinusZAndEastPlusX) {
  const Compass c;
  expect_vec_near(c.direction(0.0f, 0.0f), {0, 0, -1}, "north");
  expect_vec_near(c.direction(90.0f, 0.0f), {1, 0, 0}, "east");
  expect_vec_near(c.direction(180.0f, 0.0f), {0, 0, 1}, "south");
  expect_vec_near(c.direction(270.0f, 0.0f), {-1, 0, 0}, "west");
  expect_vec_near(c.direction(123.0f, 90.0f), {0, 1, 0}, "zenith");
  const float h = std::sqrt(0.5f);
  expect_vec_near(c.direction(90.0f, 45.0f), {h, h, 0}, "east, 45 up");
  // A wind from the north blows south, towards +Z; from the west, towards +X.
  const glm::vec2 from_north = c.wind(5.0f, 0.0f);
  EXPECT_NEAR(from_north.x, 0.0f, 1e-5f);
  EXPECT_NEAR(from_north.y, 5.0f, 1e-5f);
  const glm::vec2 from_west = c.wind(3.0f, 270.0f);
  EXPECT_NEAR(from_west.x, 3.0f, 1e-5f);
  EXPECT_NEAR(from_west.y, 0.0f, 1e-5f);
}

TEST(WeatherCompass, ACustomNorthRotatesEverything) {
  Compass c;
  c.north = {2.0f, 0.0f};  // any length: north is +X, so east (north x up) is +Z
  expect_vec_near(c.direction(0.0f, 0.0f), {1, 0, 0}, "north");
  expect_vec_near(c.direction(90.0f, 0.0f), {0, 0, 1}, "east");
  expect_vec_near(c.direction(0.0f, 90.0f), {0, 1, 0}, "zenith");
  const glm::vec2 from_north = c.wind(2.0f, 0.0f);
  EXPECT_NEAR(from_north.x, -2.0f, 1e-5f);
  EXPECT_NEAR(from_north.y, 0.0f, 1e-5f);
}

// ---- the weather file -------------------------------------------------------

// The what() of the InputError that parsing `text` throws ("" when none).
std::string parse_error(const std::string& text) {
  try {
    parse_weather(text, "w.csv");
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    return what;
  }
  ADD_FAILURE() << "accepted:\n" << text;
  return "";
}

#define EXPECT_HAS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << (text) << "\n lacks: " << (part)

const char* const kHeader = "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud\n";

TEST(WeatherFile, ReadsReorderedColumnsCommentsAndStepLengths) {
  const std::string text =
      "# a storm, then sun\r\n"
      "\n"
      " cloud , temp_c,hour,wind_from_deg,precip_mm,wind_ms \r\n"
      "1, -4.5, 0, 270, 2.5, 6\r\n"
      "# the front passes\n"
      "0.5,-2,3,300,1e0,4\n"
      "   \n"
      "0,+1.25,4.5,0,0,0\n";
  const std::vector<WeatherStep> w = parse_weather(text, "storm.csv");
  ASSERT_EQ(w.size(), 3u);
  EXPECT_EQ(w[0].hour, 0.0);
  EXPECT_EQ(w[0].cloud, 1.0f);
  EXPECT_EQ(w[0].temp_c, -4.5f);
  EXPECT_EQ(w[0].wind_from_deg, 270.0f);
  EXPECT_EQ(w[0].precip_mm, 2.5f);
  EXPECT_EQ(w[0].wind_ms, 6.0f);
  EXPECT_TRUE(std::isnan(w[0].sun_elev_deg));
  EXPECT_TRUE(std::isnan(w[0].sun_azim_deg));
  EXPECT_EQ(w[1].precip_mm, 1.0f);
  EXPECT_EQ(w[2].temp_c, 1.25f);
  // Each step lasts to the next row's hour; the last as long as the one before.
  EXPECT_EQ(w[0].hours, 3.0);
  EXPECT_EQ(w[1].hours, 1.5);
  EXPECT_EQ(w[2].hours, 1.5);
}

TEST(WeatherFile, OneRowLastsAnHour) {
  const auto w = parse_weather(std::string(kHeader) + "7,0,0,0,0,0", "w.csv");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].hour, 7.0);
  EXPECT_EQ(w[0].hours, 1.0);
}

TEST(WeatherFile, ReadsTheSunColumnsWhenBothAreThere) {
  const auto w = parse_weather(
      "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud,sun_azim_deg,sun_elev_deg\n"
      "0,0,-1,0,0,0,135,12.5\n",
      "w.csv");
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].sun_elev_deg, 12.5f);
  EXPECT_EQ(w[0].sun_azim_deg, 135.0f);
}

TEST(WeatherFile, MalformedFilesNameTheLineAndTheColumn) {
  std::string e = parse_error("hour,precip_mm,wind_ms,wind_from_deg,cloud\n0,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:1:");
  EXPECT_HAS(e, "missing column 'temp_c'");

  e = parse_error("# comment first\nhour,precip_mm,temp_c,wind_ms,cloud\n0,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:2: missing column 'wind_from_deg'");

  e = parse_error(std::string(kHeader) + "0,0,0,0,0,0\n1,0,0,0,0,0\n2,0,abc,0,0,0\n");
  EXPECT_HAS(e, "w.csv:4:");
  EXPECT_HAS(e, "column 'temp_c': \"abc\" is not a number");

  for (const char* not_number : {"", "1.5.2", "3x", "0x10", "--1", "+-1", "1 5"}) {
    e = parse_error(std::string(kHeader) + "0,0," + not_number + ",0,0,0\n");
    EXPECT_HAS(e, "w.csv:2:");
    EXPECT_HAS(e, "temp_c");
  }
  for (const char* not_finite : {"nan", "inf", "-Infinity", "1e999"}) {
    e = parse_error(std::string(kHeader) + "0,0," + not_finite + ",0,0,0\n");
    EXPECT_HAS(e, "w.csv:2: column 'temp_c': \"" + std::string(not_finite) + "\" is not");
  }

  e = parse_error(std::string(kHeader) + "0,0,0,0,0,0\n5,0,0,0,0,0\n# x\n3,0,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:5: hours must increase: 3 after 5");
  e = parse_error(std::string(kHeader) + "1,0,0,0,0,0\n1,0,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:3: hours must increase: 1 after 1");

  e = parse_error(std::string(kHeader) + "0,0,500,0,0,0\n");
  EXPECT_HAS(e, "w.csv:2: column 'temp_c': 500 is out of range -90..60");
  e = parse_error(std::string(kHeader) + "0,0,0,0,0,1.5\n");
  EXPECT_HAS(e, "w.csv:2: column 'cloud': 1.5 is out of range 0..1");
  e = parse_error(std::string(kHeader) + "0,0,0,0,0,2\n");
  EXPECT_HAS(e, "column 'cloud': 2 is out of range");
  e = parse_error(std::string(kHeader) + "-1,0,0,0,0,0\n");
  EXPECT_HAS(e, "column 'hour': -1 is out of range");
  e = parse_error(std::string(kHeader) + "2e6,0,0,0,0,0\n");
  EXPECT_HAS(e, "column 'hour': 2e6 is out of range");
  e = parse_error(std::string(kHeader) + "0,-1,0,0,0,0\n");
  EXPECT_HAS(e, "column 'precip_mm'");
  e = parse_error(std::string(kHeader) + "0,0,0,40,0,0\n");
  EXPECT_HAS(e, "column 'wind_ms'");
  e = parse_error(std::string(kHeader) + "0,0,0,0,361,0\n");
  EXPECT_HAS(e, "column 'wind_from_deg'");

  e = parse_error(
      "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud,sun_elev_deg\n"
      "0,0,0,0,0,0,10\n");
  EXPECT_HAS(e, "w.csv:1:");
  EXPECT_HAS(e, "'sun_elev_deg' without 'sun_azim_deg'");
  e = parse_error(
      "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud,sun_azim_deg\n"
      "0,0,0,0,0,0,10\n");
  EXPECT_HAS(e, "'sun_azim_deg' without 'sun_elev_deg'");
  e = parse_error(
      "hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud,sun_elev_deg,sun_azim_deg\n"
      "0,0,0,0,0,0,95,10\n");
  EXPECT_HAS(e, "w.csv:2: column 'sun_elev_deg': 95 is out of range -90..90");

  e = parse_error("hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud,tmep_c\n0,0,0,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:1: unknown column 'tmep_c'");
  e = parse_error("hour,precip,temp_c,wind_ms,wind_from_deg,cloud,gust\n0,0,0,0,0,0,0\n");
  EXPECT_HAS(e, "unknown columns 'precip', 'gust'");
  e = parse_error("hour,hour,precip_mm,temp_c,wind_ms,wind_from_deg,cloud\n0,0,0,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:1: column 'hour' twice");

  e = parse_error(std::string(kHeader) + "0,0,0,0,0,0\n1,0,0,0,0\n");
  EXPECT_HAS(e, "w.csv:3: 5 fields, the header names 6");
  e = parse_error(std::string(kHeader) + "0,0,0,0,0,0,\n");
  EXPECT_HAS(e, "w.csv:2: 7 fields, the header names 6");

  e = parse_error(std::string(kHeader) + "# nothing yet\n\n");
  EXPECT_HAS(e, "w.csv: no weather rows");
  e = parse_error("");
  EXPECT_HAS(e, "w.csv:");
  e = parse_error("# only a comment\n");
  EXPECT_HAS(e, "w.csv:");
}

TEST(WeatherFile, ErrorsStayOnOneLine) {
  // A field with control bytes and a very long one are shown cut and tamed.
  std::string e = parse_error(std::string(kHeader) + "0,0,a\rb\x01," + "0,0,0\n");
  EXPECT_HAS(e, "column 'temp_c'");
  e = parse_error(std::string(kHeader) + "0,0," + std::string(5000, '7') + "x,0,0,0\n");
  EXPECT_HAS(e, "column 'temp_c'");
  EXPECT_LT(e.size(), 200u);
}

TEST(WeatherFile, RefusesMoreThanAMillionRows) {
  std::string text = kHeader;
  text.reserve(16 * 1000002);
  for (int i = 0; i <= 1000000; ++i) text += std::to_string(i) + ",0,0,0,0,0\n";
  EXPECT_HAS(parse_error(text), "w.csv:1000002: more than 1000000 weather rows");
}

class WeatherFileOnDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("snow_test_weather_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(WeatherFileOnDisk, ReadsAFileAndNamesItInErrors) {
  const fs::path good = dir_ / "good.csv";
  test::write_all(good, std::string(kHeader) + "0,1,-3,2,90,0.5\n2,0,-1,2,90,0.5\n");
  const auto w = read_weather(good);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0].hours, 2.0);
  EXPECT_EQ(w[1].temp_c, -1.0f);

  const fs::path bad = dir_ / "bad.csv";
  test::write_all(bad, std::string(kHeader) + "0,1,-3,2,90,cloudy\n");
  try {
    read_weather(bad);
    ADD_FAILURE() << "accepted " << bad;
  } catch (const InputError& e) {
    EXPECT_HAS(e.what(), bad.string() + ":2: column 'cloud': \"cloudy\" is not a number");
  }
}

TEST_F(WeatherFileOnDisk, MissingFileOrFolderIsAnIOError) {
  EXPECT_THROW(read_weather(dir_ / "absent.csv"), IOError);
  EXPECT_THROW(read_weather(dir_), IOError);
}

TEST_F(WeatherFileOnDisk, RefusesFilesOver64MiB) {
  const fs::path big = dir_ / "big.csv";
  test::write_all(big, kHeader);
  fs::resize_file(big, (size_t(64) << 20) + 1);  // a sparse tail of zero bytes
  try {
    read_weather(big);
    ADD_FAILURE() << "accepted a file over 64 MiB";
  } catch (const InputError& e) {
    EXPECT_HAS(e.what(), big.string());
    EXPECT_HAS(e.what(), "64 MiB");
  }
}

}  // namespace
}  // namespace snow
