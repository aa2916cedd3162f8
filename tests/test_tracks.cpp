// Tracks in the snow (snow/tracks.h) on scenes built in code: a wheel
// rolled through 0.3 m of snow, a cleared path, the compaction model.
#include <gtest/gtest.h>

#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include "core/error.h"
#include "scene/builder.h"
#include "snow/tracks.h"
#include "support/maps.h"  // tests/support/maps.h

namespace snow {
namespace {

constexpr float kTexel = 0.02f;  // m
constexpr float kSnow = 0.3f;    // m of snow lying before the tracks
constexpr float kCm = 0.01f;     // m

struct Field {
  SnowMaps maps;
  SnowPack pack;
};

/// 0.3 m of settled snow on an open 6 x 6 m plane at 2 cm texels.
Field snowed_plane() {
  Field f;
  f.maps = test::maps_of(make_open_plane(6.0f), kTexel);
  f.pack = settled_pack(f.maps, std::vector<float>(f.maps.ground.size(), kSnow));
  return f;
}

/// The texel column at world (x, z) of layer 0.
size_t at(const SnowMaps& m, float x, float z) {
  const int i = int(std::floor((x - m.grid.origin.x) / m.grid.texel));
  const int j = int(std::floor((z - m.grid.origin.y) / m.grid.texel));
  return m.index(0, i, j);
}

double water(const SnowPack& pack) {
  double sum = 0.0;
  for (float s : pack.swe) sum += double(s);
  return sum;
}

/// A wheel of `radius` and `width` (along z), its axle along z at height
/// `radius` above x = `x`, z = 0: a closed 32-sided prism lying on its side.
std::vector<glm::vec3> wheel(float x, float radius, float width) {
  SceneBuilder b;
  b.add_cylinder("Wheel", glm::vec3(0.0f), radius, width, 32);
  const Scene s = b.build();
  const glm::mat4 lay = glm::translate(glm::mat4(1.0f), glm::vec3(x, radius, -0.5f * width)) *
                        glm::rotate(glm::mat4(1.0f), glm::radians(90.0f), glm::vec3(1, 0, 0));
  std::vector<glm::vec3> out;
  for (const glm::vec3& p : s.positions) out.emplace_back(lay * glm::vec4(p, 1.0f));
  return out;
}

TEST(Tracks, TheCompactionModelFollowsItsFormula) {
  // 150 kg/m^3 under 200 kPa: 550 - 400 e^-2.
  EXPECT_NEAR(compacted_density(150.0f, 200.0f), 550.0f - 400.0f * std::exp(-2.0f), 0.01f);
  EXPECT_FLOAT_EQ(compacted_density(600.0f, 200.0f), 600.0f);  // denser already
  const float rho_f = compacted_density(150.0f, 200.0f);
  // All compacted (no share aside): the rut keeps d * rho / rho_f (Richmond et al. 1995).
  EXPECT_NEAR(pressed_depth(0.3f, 150.0f, 200.0f, 0.0f), 0.3f * 150.0f / rho_f, 1e-6f);
  // A footprint (20 kPa) sinks less deep than a tyre (200 kPa).
  EXPECT_GT(pressed_depth(0.3f, 150.0f, 20.0f, 0.2f), pressed_depth(0.3f, 150.0f, 200.0f, 0.2f));
  EXPECT_FLOAT_EQ(pressed_depth(0.3f, 600.0f, 200.0f, 0.2f), 0.3f);
}

TEST(Tracks, AWheelRolledThroughTheSnowPressesATrackWithBerms) {
  Field f = snowed_plane();
  const float radius = 0.35f, width = 0.2f;
  TrackSource s;
  s.name = "Wheel";
  s.triangles = wheel(-2.0f, radius, width);
  Bounds rest;
  for (const glm::vec3& p : s.triangles) rest.extend(p);
  s.poses = track_poses({glm::mat4(1.0f), glm::translate(glm::mat4(1.0f), glm::vec3(4, 0, 0))},
                        rest, 0.5f * kTexel, 100000, s.name);
  ASSERT_GE(s.poses.size(), size_t(4.0f / (0.5f * kTexel)));
  const TrackSettings settings;
  const double before = water(f.pack);
  std::vector<float> compaction;
  const TrackResult r = make_tracks(f.maps, f.pack, {s}, settings, &compaction);

  // Mass: the water is where it was, kept, or moved aside.
  EXPECT_NEAR(water(f.pack), before, 1e-5 * before);
  EXPECT_NEAR(r.lying + r.compacted + r.moved, r.fallen, 1e-5 * r.fallen);
  EXPECT_GT(r.moved, 0.0);

  // A cross-section at x = 0: the rut as deep as the model, as wide as the wheel.
  const float model =
      pressed_depth(kSnow, kSettledSnowDensity, settings.pressure_kpa, settings.displaced_share);
  int rut = 0;
  float left_berm = 0.0f, right_berm = 0.0f;
  for (float z = -0.5f; z < 0.5f; z += kTexel) {
    const size_t k = at(f.maps, 0.0f, z + 0.5f * kTexel);
    const float d = f.pack.depth[k];
    if (d < kSnow - kCm) ++rut;
    if (std::abs(z + 0.5f * kTexel) < 0.5f * width - kTexel) {
      EXPECT_NEAR(d, model, kCm) << "z " << z;
      EXPECT_GT(compaction[k], 0.5f);
    }
    if (z < -0.5f * width) left_berm = std::max(left_berm, d);
    if (z > 0.5f * width) right_berm = std::max(right_berm, d);
  }
  EXPECT_NEAR(float(rut) * kTexel, width, 1.5f * kTexel);
  EXPECT_GT(left_berm, kSnow + kCm);
  EXPECT_GT(right_berm, kSnow + kCm);
  // Untouched far from the track.
  EXPECT_FLOAT_EQ(f.pack.depth[at(f.maps, 0.0f, 2.0f)], kSnow);
  // The density in the rut is the compacted density.
  const size_t k = at(f.maps, 0.0f, 0.001f);
  EXPECT_NEAR(f.pack.swe[k] / f.pack.depth[k] * kWaterDensity,
              compacted_density(kSettledSnowDensity, settings.pressure_kpa), 1.0f);
}

TEST(Tracks, AClearedPathHasNoSnowAndPilesBesideItHoldWhatWasRemoved) {
  Field f = snowed_plane();
  TrackSource s;
  s.name = "Path";
  s.mode = TrackMode::Clear;
  s.segments = {glm::vec3(-2.0f, 0.0f, 0.0f), glm::vec3(2.0f, 0.0f, 0.0f)};
  s.width = 1.0f;
  const std::vector<float> before = f.pack.depth;
  const double water_before = water(f.pack);
  const TrackSettings settings;
  const TrackResult r = make_tracks(f.maps, f.pack, {s}, settings);
  EXPECT_GT(r.cleared, size_t(0));
  EXPECT_NEAR(water(f.pack), water_before, 1e-5 * water_before);

  double removed = 0.0, piled = 0.0;
  for (size_t k = 0; k < before.size(); ++k) {
    const float d = f.pack.depth[k] - before[k];
    (d < 0.0f ? removed : piled) += std::abs(double(d));
  }
  EXPECT_NEAR(piled, removed, 1e-4 * removed);
  // No snow on the path, between its ends.
  for (float z = -0.45f; z < 0.45f; z += kTexel) {
    EXPECT_EQ(f.pack.depth[at(f.maps, 0.0f, z)], 0.0f) << "z " << z;
  }
  // Piles on both sides at the repose angle: per metre each side holds half
  // the path's 0.3 m^2, as a pile sqrt(A tan(repose)) high.
  const float slope = std::tan(glm::radians(settings.repose_deg));
  const float peak = std::sqrt(0.5f * kSnow * slope);
  for (float side : {-1.0f, 1.0f}) {
    float high = 0.0f, steepest = 0.0f;
    float last = kSnow;
    for (float z = 0.5f + 0.5f * kTexel; z < 1.8f; z += kTexel) {
      const float d = f.pack.depth[at(f.maps, 0.0f, side * z)];
      high = std::max(high, d - kSnow);
      steepest = std::max(steepest, std::abs(d - last) / kTexel);
      last = d;
    }
    EXPECT_NEAR(high, peak, 0.2f * peak) << "side " << side;
    EXPECT_LT(steepest, 1.3f * slope) << "side " << side;
  }
}

// A sole with two cleats (boxes reaching 3 cm lower than the plate between
// them) pressed where it stands: the cleats press to the compacted floor,
// the groove between them leaves 3 cm more snow, and beside the sole the
// snow is as it was but for the berms.
TEST(Tracks, TheContactsShapePrintsIntoTheSnow) {
  Field f = snowed_plane();
  SceneBuilder b;
  b.add_box("Cleat", {-0.15f, 0.0f, -0.1f}, {-0.05f, 0.05f, 0.1f});
  b.add_box("Cleat", {0.05f, 0.0f, -0.1f}, {0.15f, 0.05f, 0.1f});
  b.add_box("Plate", {-0.15f, 0.03f, -0.1f}, {0.15f, 0.08f, 0.1f});
  TrackSource s;
  s.name = "Sole";
  s.triangles = b.build().positions;
  TrackSettings settings;
  settings.pressure_kpa = 20.0f;  // a boot
  make_tracks(f.maps, f.pack, {s}, settings);
  const float model =
      pressed_depth(kSnow, kSettledSnowDensity, settings.pressure_kpa, settings.displaced_share);
  EXPECT_NEAR(f.pack.depth[at(f.maps, -0.1f, 0.01f)], model, 0.005f);
  EXPECT_NEAR(f.pack.depth[at(f.maps, 0.1f, 0.01f)], model, 0.005f);
  EXPECT_NEAR(f.pack.depth[at(f.maps, 0.0f, 0.01f)], model + 0.03f, 0.005f);
  EXPECT_LT(model, kSnow - 0.05f);
}

TEST(Tracks, ShapesAndSettingsOutOfRangeAreOneLineErrors) {
  Field f = snowed_plane();
  TrackSource empty;
  empty.name = "Nothing";
  EXPECT_THROW(make_tracks(f.maps, f.pack, {empty}, {}), InputError);
  TrackSource lines;
  lines.name = "Line";
  lines.segments = {glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f)};
  EXPECT_THROW(make_tracks(f.maps, f.pack, {lines}, {}), InputError);
  lines.width = 0.5f;
  TrackSettings bad;
  bad.displaced_share = 2.0f;
  EXPECT_THROW(make_tracks(f.maps, f.pack, {lines}, bad), InputError);
  EXPECT_THROW(track_poses({glm::mat4(1.0f), glm::translate(glm::mat4(1.0f), glm::vec3(1e6f))},
                           Bounds{glm::vec3(0.0f), glm::vec3(1.0f)}, 0.01f, 1000, "Far"),
               InputError);
}

}  // namespace
}  // namespace snow
