// Tracks in the live preview (live/live_sim.h, LiveSim::make_tracks and
// pick; issue 56): the brush's disc pressed where a view ray meets the
// snow, as deep as the compaction model, kept by the passes after it, and in
// a weather series kept in the snowpack's water balance and filled by the
// snow that falls after it.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "live/live_sim.h"
#include "scene/builder.h"
#include "snow/accumulate.h"
#include "support/gl_context.h"

namespace snow {
namespace {

constexpr float kCm = 0.01f;

Scene yard() {
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, {-4.0f, -4.0f}, {4.0f, 4.0f});
  b.add_box("Shed", {1.0f, 0.0f, 1.0f}, {3.0f, 2.0f, 3.0f});
  return b.build();
}

live::LiveSettings settings() {
  live::LiveSettings s;
  s.peel.max_side = 128;
  s.peel.margin = 0.0f;
  s.coverage.directions = 16;
  s.passes_per_frame = 16;
  s.total_depth = 0.3f;
  s.fall_rate = 1.0f;  // 0.3 m in 9 frames
  return s;
}

/// The brush: a disc `radius` wide pressing (or clearing) at `at`.
TrackSource disc(glm::vec3 at, float radius, TrackMode mode) {
  TrackSource s;
  s.name = "brush";
  s.mode = mode;
  s.segments = {at, at};
  s.width = 2.0f * radius;
  return s;
}

size_t texel_at(const SnowMaps& m, float x, float z) {
  return m.index(0, int((x - m.grid.origin.x) / m.grid.texel),
                 int((z - m.grid.origin.y) / m.grid.texel));
}

TEST(LiveTracks, TheBrushPressesWhereTheViewRayMeetsTheSnow) {
  REQUIRE_GL();
  const Scene scene = yard();
  live::LiveSim sim(scene, settings(), plan::current_gl());
  for (int f = 0; f < 40; ++f) sim.step();
  const SnowMaps& maps = sim.maps();
  const size_t k = texel_at(maps, -2.0f, -2.0f);
  const float lying = sim.depth()[k];
  ASSERT_GT(lying, 0.2f);
  // A ray from above and aside meets the snow top at the brush's centre.
  const glm::vec3 target(-2.0f, lying, -2.0f), eye(-6.0f, 6.0f, -5.0f);
  const std::optional<glm::vec3> at = sim.pick(eye, target - eye);
  ASSERT_TRUE(at.has_value());
  EXPECT_NEAR(glm::distance(*at, target), 0.0f, 2.0f * maps.grid.texel);
  EXPECT_FALSE(sim.pick(eye, eye - target).has_value());  // away from the maps

  const TrackSettings track;
  const TrackResult r = sim.make_tracks({disc(*at, 0.4f, TrackMode::Press)}, track);
  EXPECT_NEAR(r.lying + r.compacted + r.moved, r.fallen, 1e-5 * r.fallen);
  const float model =
      pressed_depth(lying, kSettledSnowDensity, track.pressure_kpa, track.displaced_share);
  EXPECT_NEAR(sim.depth()[k], model, kCm);
  // The passes after it keep it (the tracks' snow is held).
  for (int f = 0; f < 20; ++f) sim.step();
  EXPECT_NEAR(sim.depth()[k], model, kCm);
  // Clearing takes it all.
  sim.make_tracks({disc(*at, 0.4f, TrackMode::Clear)}, track);
  EXPECT_EQ(sim.depth()[k], 0.0f);
}

TEST(LiveTracks, InAWeatherSeriesTheTrackIsInTheBalanceAndFillsWithLaterSnow) {
  REQUIRE_GL();
  const Scene scene = yard();
  live::LiveSettings s = settings();
  auto run = std::make_shared<WeatherRun>();
  for (int h = 0; h < 12; ++h) {
    WeatherStep step;
    step.hour = h;
    step.precip_mm = 2.0f;
    step.temp_c = -5.0f;
    run->steps.push_back(step);
  }
  s.weather = run;
  live::LiveSim sim(scene, s, plan::current_gl());
  sim.seek(6.0);
  const size_t k = texel_at(sim.maps(), -2.0f, -2.0f);
  const glm::vec3 at(-2.0f, sim.depth()[k], -2.0f);
  sim.make_tracks({disc(at, 0.4f, TrackMode::Press)}, TrackSettings());
  sim.sync_snowpack();
  const SnowPack& pack = *sim.snowpack();
  EXPECT_NEAR(pack.lying(sim.maps()) + pack.melted + pack.lost, pack.fallen, 1e-5 * pack.fallen);
  const float pressed = sim.depth()[k];
  const float beside = sim.depth()[texel_at(sim.maps(), -3.0f, -2.0f)];
  EXPECT_LT(pressed, beside - 0.05f);
  sim.seek(12.0);
  EXPECT_GT(sim.depth()[k], pressed + 0.05f);  // six more hours of snow lie in it
}

}  // namespace
}  // namespace snow
