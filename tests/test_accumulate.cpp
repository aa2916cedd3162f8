// Tests of time-stepped accumulation (src/snow/accumulate.h): coverage times
// fresh snow per step, stabilized after each step; mass bookkeeping, steps,
// snow on snow, closed things stay empty.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <vector>

#include "core/error.h"
#include "gl/context.h"
#include "scene/builder.h"
#include "snow/accumulate.h"
#include "snow/peel.h"
#include "snow/reference/peel_ref.h"
#include "support/gl_context.h"

namespace snow {
namespace {

SnowMaps scene_maps(const Scene& scene, int side, int layers = 6) {
  PeelSettings settings;
  settings.max_side = side;
  settings.layers = layers;
  return reference::peel_layers(scene, make_grid(scene.bounds, settings), layers);
}

CoverageSettings few_directions() {
  CoverageSettings c;
  c.directions = 8;
  return c;
}

TEST(Accumulate, MassAddsUp) {
  REQUIRE_GL();
  const Scene scene = make_table_scene();
  const SnowMaps maps = scene_maps(scene, 64);
  AccumulateSettings settings;
  settings.fall_depth = 0.3f;
  settings.steps = 3;
  const SnowResult r =
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, settings, plan::current_gl());
  std::printf("fell %.5f, lies %.5f, lost %.5f m^3 (%d passes)\n", r.fallen_volume, r.volume,
              r.lost_volume, r.iterations);
  ASSERT_GT(r.fallen_volume, 0.0);
  EXPECT_NEAR(r.volume + r.lost_volume, r.fallen_volume, 1e-5 * r.fallen_volume);
  EXPECT_NEAR(r.volume, snow_volume(maps, r.depth), 1e-9);
  EXPECT_EQ(r.coverage_updates, 1);
  // Open floor far from the table and the map edges holds the fall depth.
  const int i = maps.grid.width / 8, j = maps.grid.height / 2;
  ASSERT_TRUE(maps.has_surface(0, i + 4, j));
  EXPECT_NEAR(r.depth[maps.index(0, i + 4, j)], 0.3f, 0.01f);
}

// On a GPU whose driver has not started, a small scene is peeled and
// snowed on the CPU without a GL context: the first context would load the
// driver (0.09-0.17 s on an H100), more than such a scene's whole run. A GPU
// is stood in for by an OnDemandContext told it is not software; making it
// throws. A larger peel does ask for it.
TEST(Accumulate, SmallSceneOnAColdGpuMakesNoContext) {
  if (gl::context_made()) GTEST_SKIP() << "a context was made earlier in this process";
  gl::OnDemandContext gpu(
      []() -> std::unique_ptr<gl::Context> { throw std::logic_error("a pass asked for GL"); },
      false);
  const Scene scene = make_table_scene();
  PeelSettings peel;
  peel.max_side = 64;
  const SnowMaps maps = peel_layers(scene, peel, plan::current_gl());
  const SnowMaps cpu = scene_maps(scene, 64, peel.layers);  // the CPU peel's maps
  ASSERT_EQ(maps.ground.size(), cpu.ground.size());
  EXPECT_EQ(std::memcmp(maps.ground.data(), cpu.ground.data(), cpu.ground.size() * sizeof(float)),
            0);
  AccumulateSettings settings;
  settings.fall_depth = 0.3f;
  const SnowResult r = accumulate(scene, maps, CoverageSettings{}, StabilizeSettings{}, settings,
                                  plan::current_gl());
  EXPECT_FALSE(gpu.made());
  EXPECT_GT(r.volume, 0.0);
  peel.max_side = 1024;  // the floor alone: about a million texel centres in its boxes
  EXPECT_THROW(peel_layers(scene, peel, plan::current_gl()), std::logic_error);
}

// The coverage's BVH built ahead (as the batch job builds it beside the
// peel on a GPU), of either kind, gives the same snow.
TEST(Accumulate, BvhBuiltAheadGivesTheSameSnow) {
  REQUIRE_GL();
  const Scene scene = make_table_scene();
  const SnowMaps maps = scene_maps(scene, 64);
  AccumulateSettings settings;
  const SnowResult plain =
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, settings, plan::current_gl());
  for (const Bvh::Build build : {Bvh::Build::Sah, Bvh::Build::Morton}) {
    CoverageBvh bvh = build_coverage_bvh(scene, build);
    EXPECT_EQ(bvh.bvh.triangle_count(), scene.triangle_count());
    const SnowResult ahead = accumulate(scene, maps, few_directions(), StabilizeSettings{},
                                        settings, plan::current_gl(), {}, &bvh);
    ASSERT_EQ(ahead.depth.size(), plain.depth.size());
    EXPECT_EQ(
        std::memcmp(ahead.depth.data(), plain.depth.data(), plain.depth.size() * sizeof(float)), 0);
    EXPECT_EQ(ahead.coverage, plain.coverage);
  }
}

TEST(Accumulate, StepsSplitTheFall) {
  REQUIRE_GL();
  const Scene scene = make_table_scene();
  const SnowMaps maps = scene_maps(scene, 64);
  AccumulateSettings one, four;
  four.steps = 4;
  const SnowResult a =
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, one, plan::current_gl());
  const SnowResult b =
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, four, plan::current_gl());
  // Without snow on snow the coverage is the same, so the same snow falls.
  EXPECT_NEAR(a.fallen_volume, b.fallen_volume, 1e-5 * a.fallen_volume);
  EXPECT_NEAR(a.volume + a.lost_volume, b.volume + b.lost_volume, 1e-4 * a.fallen_volume);
  EXPECT_GE(b.iterations, a.iterations);
}

TEST(Accumulate, SnowOnSnowUpdatesCoverage) {
  REQUIRE_GL();
  const Scene scene = make_table_scene();
  const SnowMaps maps = scene_maps(scene, 64);
  AccumulateSettings settings;
  settings.steps = 5;
  settings.snow_on_snow_every = 2;
  const SnowResult r =
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, settings, plan::current_gl());
  EXPECT_EQ(r.coverage_updates, 3);  // before step 0, 2 and 4
  EXPECT_NEAR(r.volume + r.lost_volume, r.fallen_volume, 1e-5 * r.fallen_volume);
}

TEST(Accumulate, ClosedBoxStaysEmpty) {
  REQUIRE_GL();
  const Scene scene = make_closed_box_scene();
  const SnowMaps maps = scene_maps(scene, 64);
  AccumulateSettings settings;
  settings.steps = 2;
  const SnowResult r =
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, settings, plan::current_gl());
  // The cavity (the inside of the walls, below the lid) gets nothing.
  const ClosedBoxDims dims;
  const float inner = dims.size / 2 - dims.wall;
  double inside = 0.0;
  for (int l = 1; l < maps.layers; ++l) {
    for (int j = 0; j < maps.grid.height; ++j) {
      for (int i = 0; i < maps.grid.width; ++i) {
        const glm::vec2 c = maps.grid.center(i, j);
        const size_t k = maps.index(l, i, j);
        if (std::abs(c.x) < inner && std::abs(c.y) < inner && maps.has_surface(l, i, j) &&
            maps.ground[k] < dims.size - dims.wall) {
          inside += r.depth[k];
        }
      }
    }
  }
  EXPECT_EQ(inside, 0.0);
  EXPECT_GT(r.volume, 0.0);
}

// A cushion modelled as two sheets 8 mm apart (thinner than the shadow
// maps' bias on 5 cm texels; the cover of 1 cm triangles, so that no one
// triangle shelters the lining's texels along every direction) takes the
// fall once: 0.3 m lies on it, and what fell is the floor's area times 0.3
// m (the cushion shelters the floor under it), up to the lining's outermost
// ring of texels, which the shadow maps still light (0.06 m^3 here). When
// the whole lining took the fall again, 0.3 m^3 more fell.
TEST(Accumulate, DoubleSheetedCushionTakesTheFallOnce) {
  REQUIRE_GL();
  SceneBuilder b;
  b.add_plane("Floor", 0.0f, {-1.5f, -1.5f}, {1.5f, 1.5f});
  constexpr int kCells = 100;  // per side of the 1 m cover
  std::vector<glm::vec3> corners;
  std::vector<uint32_t> indices;
  for (int j = 0; j <= kCells; ++j) {
    for (int i = 0; i <= kCells; ++i) {
      corners.push_back({-0.5f + float(i) / kCells, 0.5f, -0.5f + float(j) / kCells});
    }
  }
  for (int j = 0; j < kCells; ++j) {
    for (int i = 0; i < kCells; ++i) {
      const uint32_t c = uint32_t(j * (kCells + 1) + i), n = uint32_t(kCells + 1);
      indices.insert(indices.end(), {c, c + n, c + 1, c + 1, c + n, c + n + 1});  // facing up
    }
  }
  b.add_mesh("Cover", corners, indices);
  b.add_plane("Lining", 0.492f, {-0.5f, -0.5f}, {0.5f, 0.5f});
  const Scene scene = b.build();
  const SnowMaps maps = scene_maps(scene, 64);
  CoverageSettings coverage = few_directions();
  coverage.method = "cpu-shadow-maps";  // rays would tell the sheets apart anyway
  const SnowResult r = accumulate(scene, maps, coverage, StabilizeSettings{}, AccumulateSettings{},
                                  plan::current_gl());
  std::printf("fell %.4f m^3 (the floor's 3 x 3 m times 0.3 m: 2.7)\n", r.fallen_volume);
  EXPECT_NEAR(r.fallen_volume, 2.7, 0.1);
  const glm::ivec2 mid(maps.grid.width / 2, maps.grid.height / 2);
  ASSERT_NEAR(maps.ground[maps.index(1, mid.x, mid.y)], 0.492f, 1e-4f);  // two sheets
  EXPECT_NEAR(r.depth[maps.index(0, mid.x, mid.y)], 0.3f, 0.01f);
}

TEST(Accumulate, RejectsBadSettings) {
  REQUIRE_GL();
  const Scene scene = make_open_plane(2.0f);
  const SnowMaps maps = scene_maps(scene, 16, 2);
  AccumulateSettings bad;
  bad.steps = 0;
  EXPECT_THROW(
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, bad, plan::current_gl()),
      InputError);
  bad = AccumulateSettings{};
  bad.fall_depth = -1.0f;
  EXPECT_THROW(
      accumulate(scene, maps, few_directions(), StabilizeSettings{}, bad, plan::current_gl()),
      InputError);
  StabilizeSettings bad_stabilize;
  bad_stabilize.repose_deg = 95.0f;
  EXPECT_THROW(accumulate(scene, maps, few_directions(), bad_stabilize, AccumulateSettings{},
                          plan::current_gl()),
               InputError);
}

}  // namespace
}  // namespace snow
