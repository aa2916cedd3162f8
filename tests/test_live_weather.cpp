// The live preview playing a weather series (live/live_sim.h,
// LiveSettings::weather; issue 53): its clock and speed, scrubbing forward
// and back, and the snowpack it ends with against the batch job's
// (accumulate_weather) on the same maps, on a scene built in code.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "live/live_sim.h"
#include "scene/builder.h"
#include "snow/accumulate.h"
#include "support/gl_context.h"
#include "support/stabilize_maps.h"

namespace snow {
namespace {

/// A 16 m yard with a 50-degree gable roof (snow slides off it), ridge
/// along x.
Scene gable_yard() {
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, {-8.0f, -8.0f}, {8.0f, 8.0f});
  b.add_box("Walls", {-4.0f, 0.0f, -3.0f}, {4.0f, 3.0f, 3.0f});
  b.add_gable_roof("Roof", {-4.0f, 3.0f, -3.0f}, {4.0f, 3.0f, 3.0f}, 50.0f, 0.3f, 0.2f);
  return b.build();
}

/// 12 h of snow at -5 C with a light wind, then 8 h of thaw at +3 C with
/// the sun in the south at 35 degrees.
std::shared_ptr<const WeatherRun> storm_and_thaw() {
  auto run = std::make_shared<WeatherRun>();
  for (int h = 0; h < 20; ++h) {
    WeatherStep s;
    s.hour = h;
    s.precip_mm = h < 12 ? 2.0f : 0.0f;
    s.temp_c = h < 12 ? -5.0f : 3.0f;
    s.wind_ms = 2.0f;
    s.wind_from_deg = 270.0f;
    s.sun_elev_deg = h < 12 ? -10.0f : 35.0f;
    s.sun_azim_deg = 180.0f;
    run->steps.push_back(s);
  }
  return run;
}

/// One weather hour per frame, 64 passes per frame.
live::LiveSettings weather_settings() {
  live::LiveSettings s;
  s.peel.max_side = 128;
  s.peel.margin = 0.0f;
  s.coverage.directions = 16;
  s.passes_per_frame = 64;
  s.frame_time = 0.5f;
  s.weather_speed = 2.0f;
  s.weather = storm_and_thaw();
  return s;
}

void expect_balanced(const SnowPack& pack, const SnowMaps& maps) {
  EXPECT_NEAR(pack.lying(maps) + pack.melted + pack.lost, pack.fallen, 1e-5 * pack.fallen);
}

// Played frame by frame to the end (a weather hour a frame, the passes
// spread over the frames), the preview's snowpack matches the batch job's
// on the same maps: the same water fell (the same coverage), and what
// melted and what lies agree within 3 % (the batch job stabilizes each
// step to rest before its melt, the preview over the frames).
TEST(LiveWeather, PlaysTheSeriesLikeTheBatchJob) {
  REQUIRE_GL();
  const Scene scene = gable_yard();
  const live::LiveSettings settings = weather_settings();
  live::LiveSim sim(scene, settings, plan::current_gl());
  for (int f = 0; f < 24; ++f) sim.step();
  EXPECT_DOUBLE_EQ(sim.weather_hour(), 20.0);
  EXPECT_DOUBLE_EQ(sim.snowpack_hour(), 20.0);
  EXPECT_EQ(sim.weather_now(), nullptr);
  sim.sync_snowpack();
  const SnowMaps& maps = sim.maps();
  const SnowPack& live = *sim.snowpack();
  SnowPack batch = SnowPack::empty(maps);
  accumulate_weather(scene, maps, settings.coverage, settings.stabilize, *settings.weather, batch,
                     plan::current_gl());
  std::printf("water m^3: fell %.4f / %.4f, melted %.4f / %.4f, lies %.4f / %.4f (live / batch)\n",
              live.fallen, batch.fallen, live.melted, batch.melted, live.lying(maps),
              batch.lying(maps));
  ASSERT_GT(batch.melted, 0.0);
  EXPECT_NEAR(live.fallen, batch.fallen, 1e-6 * batch.fallen);
  EXPECT_NEAR(live.melted, batch.melted, 0.03 * batch.melted);
  EXPECT_NEAR(live.lying(maps), batch.lying(maps), 0.03 * batch.lying(maps));
  expect_balanced(live, maps);
  // The depth drawn is the pack's.
  const std::vector<float> depth = sim.depth();
  for (size_t k = 0; k < depth.size(); ++k) ASSERT_EQ(depth[k], live.depth[k]) << k;
  // The GPU stabilizer plays it the same within the backends' tolerance.
  live::LiveSettings on_gpu = settings;
  on_gpu.stabilize.device = "gpu";
  live::LiveSim gpu(scene, on_gpu, plan::current_gl());
  for (int f = 0; f < 24; ++f) gpu.step();
  gpu.sync_snowpack();
  test::expect_agree(maps, gpu.depth(), depth);
  EXPECT_NEAR(gpu.snowpack()->melted, live.melted, test::kBackendVolumeTolerance * live.fallen);
}

// The clock: speed x frame time per frame, a step applied when the clock
// passes its end; speed 0 holds it (with the window's pause, what stops
// the weather).
TEST(LiveWeather, TheClockRunsAtTheSpeed) {
  REQUIRE_GL();
  const Scene scene = gable_yard();
  live::LiveSettings settings = weather_settings();
  settings.weather_speed = 0.5f;  // a quarter hour per frame
  live::LiveSim sim(scene, settings, plan::current_gl());
  for (int f = 0; f < 3; ++f) sim.step();
  EXPECT_DOUBLE_EQ(sim.weather_hour(), 0.75);
  EXPECT_DOUBLE_EQ(sim.snowpack_hour(), 0.0);
  EXPECT_EQ(sim.snowpack()->fallen, 0.0);
  ASSERT_NE(sim.weather_now(), nullptr);
  EXPECT_TRUE(sim.snowing());
  sim.step();
  EXPECT_DOUBLE_EQ(sim.snowpack_hour(), 1.0);
  EXPECT_GT(sim.snowpack()->fallen, 0.0);
  settings.weather_speed = 0.0f;
  sim.apply(settings);
  for (int f = 0; f < 3; ++f) sim.step();
  EXPECT_DOUBLE_EQ(sim.weather_hour(), 1.0);
  settings.weather_speed = -1.0f;
  EXPECT_THROW(sim.apply(settings), InputError);
}

// Scrubbing: forward applies the steps passed at once; back replays from
// the first step, so the pack equals a fresh preview's scrubbed straight
// there; past the end stops at the end.
TEST(LiveWeather, ScrubbingForwardAndBack) {
  REQUIRE_GL();
  const Scene scene = gable_yard();
  const live::LiveSettings settings = weather_settings();
  live::LiveSim sim(scene, settings, plan::current_gl());
  sim.seek(16.0);
  EXPECT_DOUBLE_EQ(sim.snowpack_hour(), 16.0);
  EXPECT_GT(sim.snowpack()->melted, 0.0);
  expect_balanced(*sim.snowpack(), sim.maps());
  sim.step();  // passes on the snow of 16 steps
  sim.seek(6.5);
  EXPECT_DOUBLE_EQ(sim.weather_hour(), 6.5);
  EXPECT_DOUBLE_EQ(sim.snowpack_hour(), 6.0);
  EXPECT_EQ(sim.snowpack()->melted, 0.0);
  live::LiveSim fresh(scene, settings, plan::current_gl());
  fresh.seek(6.5);
  EXPECT_EQ(sim.snowpack()->swe, fresh.snowpack()->swe);
  EXPECT_EQ(sim.depth(), fresh.depth());
  sim.seek(1e6);
  EXPECT_DOUBLE_EQ(sim.weather_hour(), 20.0);
  EXPECT_DOUBLE_EQ(sim.snowpack_hour(), 20.0);
  EXPECT_FALSE(sim.snowing());
}

}  // namespace
}  // namespace snow
