// Weather over time through the snowfall stage (snow/accumulate.h,
// accumulate_weather; issue 53): accumulation and rain on open ground, melt
// against the documented formula, a gable roof's sunny and shaded slopes, a
// building's shadow, and the water balance, on scenes built in code.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "scene/builder.h"
#include "snow/accumulate.h"
#include "support/gl_context.h"
#include "support/maps.h"

namespace snow {
namespace {

using test::maps_of;

CoverageSettings few_directions() {
  CoverageSettings c;
  c.directions = 16;
  return c;
}

/// `hours` steps of one hour from `from`, all with this weather; the sun at
/// `elevation` degrees from `azimuth` (clockwise from north).
std::vector<WeatherStep> hours_of(double from, int hours, float precip_mm, float temp_c,
                                  float elevation = NAN, float azimuth = NAN) {
  std::vector<WeatherStep> steps;
  for (int h = 0; h < hours; ++h) {
    WeatherStep s;
    s.hour = from + h;
    s.precip_mm = precip_mm;
    s.temp_c = temp_c;
    s.sun_elev_deg = elevation;
    s.sun_azim_deg = azimuth;
    steps.push_back(s);
  }
  return steps;
}

/// Runs `steps` on the scene from `pack` (empty by default).
SnowResult run_weather(const Scene& scene, const SnowMaps& maps, std::vector<WeatherStep> steps,
                       SnowPack& pack) {
  WeatherRun run;
  run.steps = std::move(steps);
  return accumulate_weather(scene, maps, few_directions(), StabilizeSettings{}, run, pack,
                            plan::current_gl());
}

size_t top_at(const SnowMaps& maps, float x, float z) {
  const int i = int((x - maps.grid.origin.x) / maps.grid.texel);
  const int j = int((z - maps.grid.origin.y) / maps.grid.texel);
  return maps.index(0, i, j);
}

Scene open_field() {
  SceneBuilder b;
  b.add_plane("Field", 0.0f, {-5.0f, -5.0f}, {5.0f, 5.0f});
  return b.build();
}

void expect_balanced(const SnowPack& pack, const SnowMaps& maps) {
  EXPECT_NEAR(pack.lying(maps) + pack.melted + pack.lost, pack.fallen, 1e-5 * pack.fallen);
}

// 24 h of 1 mm/h at -5 C: 24 mm of water lies everywhere on open ground, as
// snow between the fresh density (-5 C: 75 kg/m^3) and the settled maximum.
TEST(WeatherRun, OpenGroundHoldsTheWaterThatFellAsSnow) {
  REQUIRE_GL();
  const Scene scene = open_field();
  const SnowMaps maps = maps_of(scene, 0.25f);
  SnowPack pack = SnowPack::empty(maps);
  run_weather(scene, maps, hours_of(0.0, 24, 1.0f, -5.0f), pack);
  const size_t k = top_at(maps, 0.1f, 0.1f);
  EXPECT_NEAR(pack.swe[k], 0.024f, 0.024f * 1e-5f);
  const float density = pack.swe[k] * kWaterDensity / pack.depth[k];
  EXPECT_GT(density, fresh_snow_density(-5.0f));
  EXPECT_LT(density, 300.0f);
  EXPECT_NEAR(pack.fallen, 0.024 * 10.0 * 10.0, 0.024 * 100.0 * 1e-5);
  expect_balanced(pack, maps);
}

TEST(WeatherRun, AtFiveDegreesItRains) {
  REQUIRE_GL();
  const Scene scene = open_field();
  const SnowMaps maps = maps_of(scene, 0.25f);
  SnowPack pack = SnowPack::empty(maps);
  const SnowResult r = run_weather(scene, maps, hours_of(0.0, 24, 1.0f, 5.0f), pack);
  EXPECT_EQ(pack.fallen, 0.0);
  EXPECT_EQ(r.volume, 0.0);
  for (float d : pack.depth) ASSERT_EQ(d, 0.0f);
}

// +4 C under a clear sky, the sun at 40 degrees: each hour melts kTemperature
// Factor * 4 + kShortwaveFactor * (1 - albedo) * G with G the level
// surface's shortwave, and the albedo ages as melting snow; to 1 %.
TEST(WeatherRun, MeltOnOpenGroundFollowsTheTemperatureIndex) {
  REQUIRE_GL();
  const Scene scene = open_field();
  const SnowMaps maps = maps_of(scene, 0.25f);
  SnowPack pack = SnowPack::empty(maps);
  run_weather(scene, maps, hours_of(0.0, 12, 5.0f, -5.0f), pack);  // 60 mm of water
  const size_t k = top_at(maps, 0.1f, 0.1f);
  const float before = pack.swe[k];
  ASSERT_NEAR(before, 0.06f, 1e-6f);
  float albedo = pack.albedo[k];  // fresh, aged by the hours of the snowfall
  run_weather(scene, maps, hours_of(12.0, 10, 0.0f, 4.0f, 40.0f, 180.0f), pack);
  double expected = 0.0;
  for (int h = 0; h < 10; ++h) {
    const float g = shortwave(40.0f, std::sin(glm::radians(40.0f)), 1.0f, 0.0f);
    expected += double(kTemperatureFactor * 4.0f + kShortwaveFactor * (1.0f - albedo) * g);
    albedo = aged_albedo(albedo, 1.0, true, 0.0f);
  }
  EXPECT_NEAR(double(before - pack.swe[k]), expected, 0.01 * expected);
  EXPECT_NEAR(pack.albedo[k], albedo, 1e-4f);
  expect_balanced(pack, maps);
}

// A 30-degree gable roof, ridge along x, one slope facing south (+z, north
// being -z) and one north; snow, then a thaw with the sun in the south at 35
// degrees: the sunny slope keeps less than 0.8 of the shaded one's water.
TEST(WeatherRun, TheSunnySlopeOfAGableRoofMeltsFirst) {
  REQUIRE_GL();
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, {-8.0f, -8.0f}, {8.0f, 8.0f});
  b.add_box("Walls", {-4.0f, 0.0f, -3.0f}, {4.0f, 3.0f, 3.0f});
  b.add_gable_roof("Roof", {-4.0f, 3.0f, -3.0f}, {4.0f, 3.0f, 3.0f}, 30.0f, 0.3f, 0.2f);
  const Scene scene = b.build();
  const SnowMaps maps = maps_of(scene, 0.1f);
  SnowPack pack = SnowPack::empty(maps);
  std::vector<WeatherStep> steps = hours_of(0.0, 24, 1.0f, -5.0f);
  for (const WeatherStep& s : hours_of(24.0, 8, 0.0f, 2.0f, 35.0f, 180.0f)) steps.push_back(s);
  run_weather(scene, maps, steps, pack);
  const float sunny = pack.swe[top_at(maps, 0.05f, 1.55f)];
  const float shaded = pack.swe[top_at(maps, 0.05f, -1.55f)];
  std::printf("roof: sunny slope %.4f, shaded %.4f m of water\n", double(sunny), double(shaded));
  EXPECT_GT(shaded, 0.01f);
  EXPECT_LT(sunny, 0.8f * shaded);
  expect_balanced(pack, maps);
}

// A 4 m block, the sun in the south at 30 degrees: its shadow reaches 6.9 m
// north; 3 m north of it the snow outlasts that 3 m east of it in the sun.
TEST(WeatherRun, ABuildingsShadowKeepsTheSnowBehindIt) {
  REQUIRE_GL();
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, {-12.0f, -12.0f}, {12.0f, 12.0f});
  b.add_box("Block", {-2.0f, 0.0f, -2.0f}, {2.0f, 4.0f, 2.0f});
  const Scene scene = b.build();
  const SnowMaps maps = maps_of(scene, 0.2f);
  SnowPack pack = SnowPack::empty(maps);
  std::vector<WeatherStep> steps = hours_of(0.0, 12, 1.0f, -5.0f);
  for (const WeatherStep& s : hours_of(12.0, 8, 0.0f, 3.0f, 30.0f, 180.0f)) steps.push_back(s);
  run_weather(scene, maps, steps, pack);
  const float shadow = pack.swe[top_at(maps, 0.1f, -5.1f)];
  const float sun = pack.swe[top_at(maps, 5.1f, 0.1f)];
  std::printf("ground: in the shadow %.4f, in the sun %.4f m of water\n", double(shadow),
              double(sun));
  EXPECT_GT(shadow, sun + 0.002f);
  expect_balanced(pack, maps);
}

// Water balance with moves: snow sliding off a steep roof into the void
// beyond the maps and onto the ground, melt, rain; exact to 1e-5.
TEST(WeatherRun, LyingMeltedAndLostAddUpToWhatFell) {
  REQUIRE_GL();
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, {-4.0f, -4.0f}, {4.0f, 4.0f});
  b.add_box("Walls", {-2.0f, 0.0f, -2.0f}, {2.0f, 2.0f, 2.0f});
  b.add_gable_roof("Roof", {-2.0f, 2.0f, -2.0f}, {2.0f, 2.0f, 2.0f}, 55.0f, 0.3f, 0.1f);
  const Scene scene = b.build();
  const SnowMaps maps = maps_of(scene, 0.1f);
  SnowPack pack = SnowPack::empty(maps);
  std::vector<WeatherStep> steps = hours_of(0.0, 10, 4.0f, -3.0f);
  for (const WeatherStep& s : hours_of(10.0, 6, 1.0f, 3.0f, 45.0f, 200.0f)) steps.push_back(s);
  run_weather(scene, maps, steps, pack);
  EXPECT_GT(pack.melted, 0.0);
  expect_balanced(pack, maps);
}

}  // namespace
}  // namespace snow
