// Tests of the stabilizer (src/snow/stabilize.h) and its CPU reference
// (src/snow/stabilize_cpu.h): the landing rule, the stride schedule, mass
// conservation, convergence to rest, GPU against CPU, the automatic device
// and the active tiles. Piles, drains and the rest the snow reaches on
// shapes and scenes: test_stabilize_piles.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "gl/context.h"
#include "scene/builder.h"
#include "snow/column.h"
#include "snow/maps.h"
#include "snow/stabilize.h"
#include "snow/stabilize_cpu.h"
#include "support/stabilize_maps.h"

namespace snow::test {
namespace {

// --- The landing rule --------------------------------------------------------

TEST(Column, LandingRule) {
  // Column 0: a table (top 0.75 up, underside 0.7 down) over a floor at 0;
  // column 1: floor only; column 2: nothing.
  const SnowMaps maps = make_maps(3, 1, 0.1f, 4, [](float x, float) {
    std::vector<Surface> s;
    if (x < 0.1f) {
      s.push_back({0.75f, kUp});
      s.push_back({0.7f, kDown});
    }
    if (x < 0.2f) s.push_back({0.0f, kUp});
    return s;
  });
  std::vector<float> depth(maps.ground.size(), 0.0f);
  EXPECT_EQ(landing(maps, depth.data(), 0, 0, 1.0f), 0);              // on the table top
  EXPECT_EQ(landing(maps, depth.data(), 0, 0, 0.72f), kLandBlocked);  // inside the top slab
  EXPECT_EQ(landing(maps, depth.data(), 0, 0, 0.3f), 2);              // on the floor under it
  EXPECT_EQ(landing(maps, depth.data(), 2, 0, 0.3f), kLandVoid);      // empty column
  EXPECT_EQ(landing(maps, depth.data(), 3, 0, 0.3f), kLandVoid);      // off the map
  EXPECT_EQ(landing_layer(maps, depth.data(), 0, 0, 0.72f), -1);
  depth[maps.index(0, 1, 0)] = 0.2f;  // snow on the floor of column 1
  EXPECT_EQ(landing(maps, depth.data(), 1, 0, 0.1f), kLandBlocked);  // inside that snow
  EXPECT_EQ(landing(maps, depth.data(), 1, 0, 0.25f), 0);
  // Continuity: snow resting at 0.68 must not pass under a ceiling 0.02 m
  // above its support (the same thin surface continuing).
  EXPECT_EQ(landing(maps, depth.data(), 0, 0, 0.3f, 0.69f), kLandBlocked);
  EXPECT_EQ(landing(maps, depth.data(), 0, 0, 0.3f, 0.0f), 2);
}

// --- CPU reference on analytic maps ------------------------------------------

TEST(StrideSchedule, LengthensOnlyWhereTheSnowCreeps) {
  StabilizeSettings settings = loose_settings();  // max_stride 4
  settings.check_every = 16;
  StrideSchedule schedule(settings);
  const auto run = [&](int passes, float residual) {
    std::vector<int> strides;
    for (int p = 0; p < passes; ++p) strides.push_back(schedule.next());
    schedule.checked(strides.back(), residual);
    return strides;
  };
  EXPECT_EQ(run(16, 1e-2f), std::vector<int>(16, 1));  // single steps first
  EXPECT_EQ(run(16, 1e-3f), std::vector<int>(16, 1));  // fell tenfold: stays
  EXPECT_EQ(schedule.largest(), 1);
  EXPECT_FALSE(schedule.creeping());
  EXPECT_FALSE(drain_due(settings, schedule, 1e-3f, 1e-3f));
  run(16, 0.9e-3f);  // fell by a tenth only: creeping, strides up to 2
  EXPECT_EQ(schedule.largest(), 2);
  EXPECT_TRUE(schedule.creeping());
  // Draining: creeping, and a quarter of the largest move went into the void.
  EXPECT_TRUE(drain_due(settings, schedule, 0.9e-3f, 0.25f * 0.9e-3f));
  EXPECT_FALSE(drain_due(settings, schedule, 0.9e-3f, 0.2e-3f));
  StabilizeSettings no_drain = settings;
  no_drain.drain_edges = false;
  EXPECT_FALSE(drain_due(no_drain, schedule, 0.9e-3f, 0.9e-3f));
  EXPECT_EQ(run(6, 0.0f), (std::vector<int>{2, 1, 2, 1, 2, 1}));
  schedule.checked(2, 1.0f);  // checks after a strided pass do not count
  EXPECT_EQ(schedule.largest(), 2);
  EXPECT_FALSE(schedule.creeping());
  run(16, 0.85e-3f);  // slow again: 4
  run(18, 0.8e-3f);   // and again, but 4 is the most
  EXPECT_EQ(schedule.largest(), 4);
  EXPECT_EQ(run(6, 0.0f), (std::vector<int>{4, 2, 1, 4, 2, 1}));
  schedule.restart();  // snow added
  EXPECT_EQ(schedule.largest(), 1);
  EXPECT_EQ(schedule.next(), 1);

  settings.adaptive_stride = false;
  StrideSchedule fixed(settings);
  EXPECT_EQ(fixed.largest(), 4);
  for (int expected : {4, 2, 1, 4, 2, 1}) EXPECT_EQ(fixed.next(), expected);
  fixed.checked(1, 1.0f);
  fixed.restart();
  EXPECT_EQ(fixed.next(), 4);
}

TEST(StabilizeResult, AddFoldsInALaterCall) {
  StabilizeResult a;
  a.iterations = 30;
  a.residual = 1e-2f;
  a.route_passes = 5;
  a.routed_volume = 2.0;
  a.lost_volume = 0.5;
  a.volume = 10.0;
  a.route_seconds = 1.0;
  a.tile_share = 1.0;
  StabilizeResult b;
  b.iterations = 10;
  b.residual = 1e-5f;
  b.converged = true;
  b.route_passes = 3;
  b.routed_volume = 0.25;
  b.lost_volume = 0.25;
  b.volume = 9.5;
  b.route_seconds = 0.5;
  b.tile_share = 0.2;
  a.add(b);
  EXPECT_EQ(a.iterations, 40);
  EXPECT_EQ(a.residual, 1e-5f);
  EXPECT_TRUE(a.converged);
  EXPECT_EQ(a.route_passes, 8);
  EXPECT_DOUBLE_EQ(a.routed_volume, 2.25);
  EXPECT_DOUBLE_EQ(a.lost_volume, 0.75);
  EXPECT_DOUBLE_EQ(a.volume, 9.5);
  EXPECT_DOUBLE_EQ(a.route_seconds, 1.5);
  EXPECT_DOUBLE_EQ(a.tile_share, (30 * 1.0 + 10 * 0.2) / 40);
}

TEST(StabilizeReference, MassIsConserved) {
  const SnowMaps maps = bumpy_maps(64, 4);
  std::vector<float> depth = random_snow(maps, 0.5f, 7);
  const double before = snow_volume(maps, depth);
  StabilizeSettings settings = loose_settings();
  settings.tolerance = 0.0f;  // run every pass
  settings.max_iterations = 600;
  const StabilizeResult r = stabilize_cpu(maps, depth, settings);
  const double after = snow_volume(maps, depth);
  const double drift = std::abs(after + r.lost_volume - before) / before;
  std::printf("mass: before %.6f after %.6f lost %.6f routed %.6f drift %.2e (%d passes)\n", before,
              after, r.lost_volume, r.routed_volume, drift, r.iterations);
  EXPECT_EQ(r.iterations, 600);
  EXPECT_GT(r.lost_volume, 0.0);  // the hole and the map edges swallow some
  EXPECT_GT(r.routed_volume, 0.0);
  // r.volume counts the float rounding residues below zero that the output
  // clears (a few nanometres over the texels that gave all their snow).
  EXPECT_NEAR(r.volume, after, 1e-8 * before);
  EXPECT_LT(drift, 1e-5);
}

// Far from the origin the snow's top rounds: at a ground of 6.7e6 m, floats
// 0.5 m apart, 0.3 m of snow tops out 0.5 m up. A routed texel (here every
// one: the map's border sheds into the void) gives up its snow, never more
// (tools/fuzz found -0.2 m left behind, and more snow lost than fell).
TEST(StabilizeReference, RoutingFarFromTheOriginGivesUpNoMoreThanTheSnow) {
  const SnowMaps maps = make_maps(6, 6, 0.05f, 1, [](float, float) {
    return std::vector<Surface>{{6661632.0f, kUp}};
  });
  const std::vector<float> start = snow_on_top(maps, 0.3f);
  const double before = snow_volume(maps, start);
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = 50;
  CpuStabilizer stabilizer(maps, settings);
  stabilizer.set_depth(start);
  const StabilizeResult r = stabilizer.iterate(settings.max_iterations);
  const std::vector<float> cpu = stabilizer.depth();
  for (float d : cpu) EXPECT_GE(d, 0.0f);
  EXPECT_GT(r.lost_volume, 0.0);
  EXPECT_NEAR(snow_volume(maps, cpu) + r.lost_volume, before, 1e-6 * before);
  if (!test::context()) return;
  std::vector<float> gpu = start;
  stabilize(maps, gpu, settings);
  expect_agree(maps, gpu, cpu);
}

// With volume sums off (the batch job, which sums once at the end),
// iterate() leaves volume and lost_volume 0 and does the same passes.
template <class AnyStabilizer>
void expect_volume_sums_change_only_the_sums(const SnowMaps& maps, AnyStabilizer& summed,
                                             AnyStabilizer& quiet) {
  const std::vector<float> start = random_snow(maps, 0.5f, 7);
  summed.set_depth(start);
  quiet.set_depth(start);
  quiet.set_volume_sums(false);
  for (int chunk = 0; chunk < 3; ++chunk) {
    const StabilizeResult a = summed.iterate(40), b = quiet.iterate(40);
    EXPECT_GT(a.volume, 0.0);
    if (chunk == 0) {
      EXPECT_GT(a.lost_volume, 0.0);  // the hole and the edges swallow some
    }
    EXPECT_EQ(b.volume, 0.0);
    EXPECT_EQ(b.lost_volume, 0.0);
    EXPECT_EQ(b.iterations, a.iterations);
    EXPECT_EQ(b.residual, a.residual);
    EXPECT_EQ(quiet.depth(), summed.depth());
  }
  EXPECT_EQ(quiet.lost_volume(), summed.lost_volume());
}

TEST(StabilizeCpu, VolumeSumsOffChangeOnlyTheSums) {
  const SnowMaps maps = bumpy_maps(64, 4);
  StabilizeSettings settings = loose_settings();
  settings.tolerance = 0.0f;  // run every pass
  CpuStabilizer summed(maps, settings), quiet(maps, settings);
  expect_volume_sums_change_only_the_sums(maps, summed, quiet);
}

TEST(StabilizeGpu, VolumeSumsOffChangeOnlyTheSums) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(64, 4);
  StabilizeSettings settings = loose_settings();
  settings.tolerance = 0.0f;
  Stabilizer summed(maps, settings), quiet(maps, settings);
  expect_volume_sums_change_only_the_sums(maps, summed, quiet);
}

// A kept snow amount (set_snow_amount, then add_snow(scale): the live
// preview's frames, which then upload nothing) adds what add_snow(amount,
// scale) adds, bit for bit on the same backend, and the passes after it
// move the same snow (NaN and negative amounts included: they add nothing
// either way).
template <class AnyStabilizer>
void expect_kept_amount_adds_the_same(const SnowMaps& maps, AnyStabilizer& given,
                                      AnyStabilizer& kept) {
  std::vector<float> amount = random_snow(maps, 1.0f, 11);
  amount[maps.index(0, 3, 3)] = std::nanf("");
  amount[maps.index(0, 4, 3)] = -1.0f;
  kept.set_snow_amount(amount);
  for (int step = 0; step < 3; ++step) {
    given.add_snow(amount, 0.05f);
    kept.add_snow(0.05f);
    EXPECT_EQ(kept.depth(), given.depth());
    const StabilizeResult a = given.iterate(20), b = kept.iterate(20);
    EXPECT_EQ(b.iterations, a.iterations);
    EXPECT_EQ(kept.depth(), given.depth());
  }
}

TEST(StabilizeCpu, KeptSnowAmountAddsWhatAddSnowAdds) {
  const SnowMaps maps = bumpy_maps(32, 4);
  const StabilizeSettings settings = loose_settings();
  CpuStabilizer given(maps, settings), kept(maps, settings);
  expect_kept_amount_adds_the_same(maps, given, kept);
}

TEST(StabilizeGpu, KeptSnowAmountAddsWhatAddSnowAdds) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(32, 4);
  const StabilizeSettings settings = loose_settings();
  Stabilizer given(maps, settings), kept(maps, settings);
  expect_kept_amount_adds_the_same(maps, given, kept);
}

// Asynchronous checks (the live preview's): snow stabilized in calls of 8
// passes, as frames run them, with each check deciding by the one before.
// It comes to the same rest as with every check reading its own pass, within
// the backends' tolerance (1 mm per texel, 0.1 % of the volume), and knows
// it within two checks and a call of the synchronous run.
// Routing creeping snow is decided at the first check at or after each
// kCreepRouteEvery passes, on the check before (late: the last one read).
TEST(StrideSchedule, CreepingSnowIsRoutedAtFixedPasses) {
  StabilizeSettings settings = loose_settings();
  settings.check_every = 4;
  StrideSchedule schedule(settings);
  std::vector<int> routed;
  float residual = 1e-2f;
  for (int pass = 1; pass <= 100; ++pass) {
    schedule.next();
    if (pass % 6 != 0) continue;  // a check every 6 passes
    residual *= 0.99f;            // creeping: falls by far less than half per check
    schedule.checked(1, residual);
    if (creep_route_due(settings, schedule, false)) routed.push_back(pass);
  }
  EXPECT_EQ(routed, (std::vector<int>{36, 66, 96}));  // at 32, 64, 96 or after
  StabilizeSettings off = settings;
  off.route_creep = false;
  StrideSchedule quiet(off);
  for (int pass = 1; pass <= 40; ++pass) quiet.next();
  quiet.checked(1, 1e-2f);
  quiet.checked(1, 0.99e-2f);
  EXPECT_FALSE(creep_route_due(off, quiet, true));
}

// The same rest with the checks' decisions a check late. Routing creeping
// snow is left out: a discrete step, it lands the snow a few millimetres
// apart when drains before it came a check apart (creep routing is checked
// by CreepingSnowIsRoutedAtFixedPasses and StabilizePiles).
TEST(StabilizeGpu, AsynchronousChecksComeToTheSameRest) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(64, 4);
  const std::vector<float> start = random_snow(maps, 0.5f, 5);
  StabilizeSettings settings = loose_settings();
  settings.route_creep = false;
  Stabilizer sync(maps, settings), async(maps, settings);
  async.set_async_checks(true);
  sync.set_depth(start);
  async.set_depth(start);
  StabilizeResult a, b;
  for (int call = 0; call < 500 && !(a.converged && b.converged); ++call) {
    if (!a.converged) a.add(sync.iterate(8));
    if (!b.converged) b.add(async.iterate(8));
  }
  std::printf("at rest after %d passes (synchronous) and %d (asynchronous)\n", a.iterations,
              b.iterations);
  ASSERT_TRUE(a.converged);
  ASSERT_TRUE(b.converged);
  EXPECT_GE(b.iterations, a.iterations);
  EXPECT_LE(b.iterations, a.iterations + 2 * settings.check_every + 8);
  const std::vector<float> da = sync.depth(), db = async.depth();
  expect_agree(maps, db, da);
  EXPECT_NEAR(snow_volume(maps, db), snow_volume(maps, da),
              kBackendVolumeTolerance * snow_volume(maps, da));
}

TEST(StabilizeReference, ConvergedSnowIsAtRest) {
  const SnowMaps maps = bumpy_maps(64, 4);
  std::vector<float> depth = random_snow(maps, 0.5f, 11);
  StabilizeSettings settings = loose_settings();
  const StabilizeResult r = stabilize_cpu(maps, depth, settings);
  ASSERT_TRUE(r.converged) << "residual " << r.residual;
  // The last pass may still bring up to about a tolerance of snow to a texel.
  const float excess = largest_excess(maps, depth, settings, 2.0f * settings.tolerance);
  std::printf("at rest: %d passes, residual %.2e, largest excess %.2e m\n", r.iterations,
              r.residual, excess);
  EXPECT_LE(excess, 2.0f * settings.tolerance);
  // Nothing above a ceiling.
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k])) {
      EXPECT_LE(maps.ground[k] + depth[k], maps.ceiling[k] + 1e-4f);
    }
  }
}

// Calls of any length converge to the same rest: only a check after a
// single step may find the snow converged (a strided pass moves nothing
// where its paths are blocked, while single steps still move snow there).
TEST(StabilizeReference, ConvergenceIsCheckedOnSingleSteps) {
  const SnowMaps maps = bumpy_maps(64, 4);
  const std::vector<float> start = random_snow(maps, 0.5f, 11);
  StabilizeSettings settings = loose_settings();
  settings.max_stride = 8;
  for (int chunk : {2, 3, 5, 64}) {
    CpuStabilizer stabilizer(maps, settings);
    stabilizer.set_depth(start);
    StabilizeResult total;
    while (!total.converged && total.iterations < settings.max_iterations) {
      total.add(stabilizer.iterate(chunk));
    }
    std::vector<float> depth = stabilizer.depth();
    for (float& d : depth) d = std::max(d, 0.0f);
    const float excess = largest_excess(maps, depth, settings, 2.0f * settings.tolerance);
    std::printf("calls of %d passes: converged after %d, largest excess %.2e m\n", chunk,
                total.iterations, excess);
    EXPECT_TRUE(total.converged) << chunk;
    EXPECT_LE(excess, 2.0f * settings.tolerance) << chunk;
  }
}

// --- GPU against the CPU reference -------------------------------------------

TEST(StabilizeGpu, MatchesReference) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(64, 4);
  const std::vector<float> start = random_snow(maps, 0.5f, 3);
  StabilizeSettings settings = loose_settings();
  settings.tolerance = 0.0f;
  // Adaptive strides (single steps here) and strides 4, 2, 1 from the start.
  for (const bool adaptive : {true, false})
    for (int passes : {0, 1, 2, 7, 60}) {
      settings.adaptive_stride = adaptive;
      settings.max_iterations = passes;
      std::vector<float> cpu = start, gpu = start;
      const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
      const StabilizeResult rg = stabilize(maps, gpu, settings);
      SCOPED_TRACE(adaptive);
      SCOPED_TRACE(passes);
      EXPECT_EQ(rg.iterations, rc.iterations);
      // (Not the routing's passes: the CPU erodes in place, in fewer rounds.)
      EXPECT_NEAR(rg.residual, rc.residual,
                  kBackendTexelTolerance);  // the last pass's largest move
      EXPECT_NEAR(rg.lost_volume, rc.lost_volume, 1e-4);
      EXPECT_NEAR(rg.volume, rc.volume, 1e-4);
      expect_agree(maps, gpu, cpu);
    }
}

// Cohesive snow (snow/cohesion.h): the GPU holds what the CPU holds, within
// the stated tolerance of 1 mm per texel and 0.1 % of the volume, on bumpy
// supports whose slopes shed part of the snow and with snow deeper than the
// standing height in places.
TEST(StabilizeGpu, CohesiveSnowMatchesReference) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(64, 4);
  const std::vector<float> start = random_snow(maps, 0.5f, 3);
  for (const SnowKind kind : {SnowKind::Powder, SnowKind::Fresh}) {
    StabilizeSettings settings;
    settings.cohesion = cohesion_of(kind);
    std::vector<float> cpu = start, gpu = start;
    const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
    const StabilizeResult rg = stabilize(maps, gpu, settings);
    SCOPED_TRACE(snow_kind_name(kind));
    EXPECT_TRUE(rc.converged);
    EXPECT_TRUE(rg.converged);
    EXPECT_NEAR(rg.volume, rc.volume, 1e-3 * rc.volume);
    EXPECT_NEAR(rg.lost_volume, rc.lost_volume, 1e-3 * rc.volume);
    expect_agree(maps, gpu, cpu);
  }
}

TEST(StabilizeGpu, RoutingLeavesASlabEdgeAtRest) {
  REQUIRE_GL();
  // A 1.6 m slab, a shallow dish rising 5 % towards its edges, with 0.3 m of
  // snow; beyond its edges (the map's) is the void. Routing alone cuts the
  // repose ramp down to the edge: the edge texels shed everything, so the
  // landing rule must see what they keep, not the snow about to leave them
  // (which stands higher than the snow beside it).
  const SnowMaps maps = make_maps(32, 32, 0.05f, 1, [](float x, float z) {
    return std::vector<Surface>{{0.05f * std::max(std::abs(x - 0.8f), std::abs(z - 0.8f)), kUp}};
  });
  const std::vector<float> start = snow_on_top(maps, 0.3f);
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = 0;  // routing only
  std::vector<float> cpu = start, gpu = start;
  stabilize_cpu(maps, cpu, settings);
  stabilize(maps, gpu, settings);
  expect_agree(maps, gpu, cpu);
  const float excess = largest_excess(maps, gpu, settings, 1e-6f);
  std::printf("slab edge after routing: largest excess %.2e m, edge %.4f m, next %.4f m\n", excess,
              gpu[maps.index(0, 0, 16)], gpu[maps.index(0, 1, 16)]);
  EXPECT_LE(excess, 1e-5f);
  EXPECT_EQ(gpu[maps.index(0, 0, 16)], 0.0f);
  EXPECT_NEAR(gpu[maps.index(0, 16, 16)], 0.3f, 1e-6f);
}

TEST(StabilizeGpu, RoutingPressesSnowOutFromUnderACeiling) {
  REQUIRE_GL();
  // The shelf of LowCeilingCapsDepth, 0.1 m above the floor, with 0.3 m of
  // snow forced under it and 0.08 m around it. The routing moves the snow
  // above the ceiling at the shelf's edge out to the lower snow beside it,
  // though no erosion pass changes what the edge keeps (the snow beside it
  // is lower by less than the repose allows), and the shelf's edge is a
  // tile edge: the same with or without active tiles.
  const SnowMaps maps = shelf_maps();
  std::vector<float> start(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < start.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ground[k] == 0.0f) {
      start[k] = maps.ceiling[k] < 1.0f ? 0.3f : 0.08f;
    }
  }
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = 0;  // routing only
  std::vector<float> cpu = start, tiled = start, full = start;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rt = stabilize(maps, tiled, settings);
  settings.active_tiles = false;
  const StabilizeResult rf = stabilize(maps, full, settings);
  EXPECT_GT(rc.routed_volume, 0.0);
  EXPECT_EQ(rt.route_passes, rf.route_passes);
  expect_agree(maps, tiled, cpu);
  expect_identical(tiled, full);
  // Under the shelf's edge (texel column 16 is its first), the snow reaches
  // up to the ceiling.
  ASSERT_TRUE(maps.has_surface(2, 16, 24));
  ASSERT_FALSE(maps.has_surface(2, 15, 24));
  EXPECT_LE(tiled[maps.index(2, 16, 24)], 0.1f);
}

// Flat ground, 1 cm texels, 0.3 m of snow and a 12 mm bump at (8, 8): its
// excess over the edge neighbours is 0.9..2 mm (45 +- 3 degrees), so a pass
// moves about half of that. The map edges drain into the void, 6 texels away.
struct Bump {
  SnowMaps maps = make_maps(16, 16, 0.01f, 1, [](float, float) {
    return std::vector<Surface>{{0.0f, kUp}};
  });
  size_t at = maps.index(0, 8, 8);
  std::vector<float> start = [this] {
    std::vector<float> depth = snow_on_top(maps, 0.3f);
    depth[at] += 0.012f;
    return depth;
  }();
  // After two single-step passes: the bump stays, or it has moved.
  void expect(const std::vector<float>& after, bool stays) const {
    if (stays) {
      EXPECT_EQ(after[at], start[at]);
    } else {
      EXPECT_LT(after[at], start[at] - 3e-4f);
    }
  }
};

TEST(StabilizeGpu, MovesUnderMinMoveAreNotMade) {
  REQUIRE_GL();
  // Two single-step passes on the bump without routing.
  const Bump bump;
  StabilizeSettings settings = loose_settings();
  settings.route_steep = false;
  settings.max_stride = 1;
  settings.tolerance = 0.0f;
  settings.max_iterations = 2;
  for (float min_move : {0.0f, 0.002f}) {
    SCOPED_TRACE(min_move);
    settings.min_move = min_move;
    std::vector<float> cpu = bump.start, gpu = bump.start;
    stabilize_cpu(bump.maps, cpu, settings);
    stabilize(bump.maps, gpu, settings);
    expect_agree(bump.maps, gpu, cpu);
    bump.expect(gpu, min_move > 0.0f);
  }
}

// The default min_move is automatic: a tenth of the tolerance. On the bump
// above (single steps of 0.45-1 mm), a tolerance of 20 mm makes it 2 mm and
// the bump stays, as with min_move 0.002; a tolerance of 1 mm makes it
// 0.1 mm and the bump moves. An explicit min_move is kept.
TEST(StabilizeCpu, AutomaticMinMoveIsATenthOfTheTolerance) {
  StabilizeSettings settings = loose_settings();
  EXPECT_LT(settings.min_move, 0.0f);
  EXPECT_FLOAT_EQ(min_move_of(settings), 0.1f * settings.tolerance);
  settings.min_move = 0.0f;
  EXPECT_EQ(min_move_of(settings), 0.0f);
  settings.min_move = std::nanf("");
  EXPECT_THROW(check_stabilize_settings(settings), InputError);

  const Bump bump;
  settings = loose_settings();
  settings.route_steep = false;
  settings.max_stride = 1;
  settings.max_iterations = 2;
  check_stabilize_settings(settings);
  for (float tolerance : {0.02f, 0.001f}) {
    SCOPED_TRACE(tolerance);
    settings.tolerance = tolerance;
    std::vector<float> depth = bump.start;
    stabilize_cpu(bump.maps, depth, settings);
    bump.expect(depth, tolerance > 0.01f);
  }
}

// --stabilizer auto: the batch job takes the CPU's passes whatever renders;
// the live preview takes the GPU's unless the renderer is software.
TEST(StabilizeDevice, AutoIsTheCpuForTheBatchJobAndTheRendererForThePreview) {
  StabilizeSettings settings = loose_settings();
  EXPECT_EQ(settings.device, "auto");
  for (const bool software : {false, true}) {
    SCOPED_TRACE(software);
    const plan::GlFacts gl{software, false};
    settings.device = "auto";
    EXPECT_TRUE(stabilizes_on_cpu(settings, StabilizerUse::Batch, gl));
    EXPECT_EQ(stabilizes_on_cpu(settings, StabilizerUse::Live, gl), software);
    for (const StabilizerUse use : {StabilizerUse::Batch, StabilizerUse::Live}) {
      settings.device = "gpu";
      EXPECT_FALSE(stabilizes_on_cpu(settings, use, gl));
      settings.device = "cpu";
      EXPECT_TRUE(stabilizes_on_cpu(settings, use, gl));
    }
  }
}

// --- Active tiles (builder scenes) -------------------------------------------

// Active tiles skip only tiles whose passes would move nothing: the depth is
// bit for bit that of full passes, on scenes and through time steps. `run` is
// stabilize or stabilize_cpu.
template <class Run>
void expect_active_tiles_exact(Run run) {
  HouseDims house;
  house.roof_pitch_deg = 60.0f;
  const std::vector<std::pair<const char*, Scene>> scenes = {
      {"house", make_house_scene(house)},
      {"table", make_table_scene()},
      {"stairs", make_stairs_scene(StairsDims{})}};
  for (const auto& [name, scene] : scenes) {
    const SnowMaps maps = scene_maps(scene, 96, 6);
    // Fixed cycles run strided passes from the first; adaptive strides start
    // with single steps, and their first strided passes draw only the tiles
    // stamped since the last single-step pass.
    for (const auto& [max_stride, adaptive] :
         {std::pair{4, false}, std::pair{32, false}, std::pair{4, true}}) {
      StabilizeSettings settings = loose_settings();
      settings.max_stride = max_stride;
      settings.adaptive_stride = adaptive;
      settings.count_tiles = true;
      settings.max_iterations = 150;
      std::vector<float> on = snow_on_top(maps, 0.3f), off = on;
      const StabilizeResult r_on = run(maps, on, settings);
      settings.active_tiles = false;
      const StabilizeResult r_off = run(maps, off, settings);
      std::printf(
          "%s, max_stride %d, adaptive %d: %d passes (+%d routing), tiles computed %.1f %%\n", name,
          max_stride, int(adaptive), r_on.iterations, r_on.route_passes, 100.0 * r_on.tile_share);
      SCOPED_TRACE(name);
      SCOPED_TRACE(max_stride);
      SCOPED_TRACE(adaptive);
      EXPECT_EQ(r_on.iterations, r_off.iterations);
      EXPECT_EQ(r_on.route_passes, r_off.route_passes);
      EXPECT_EQ(r_on.residual, r_off.residual);
      EXPECT_EQ(r_on.converged, r_off.converged);
      EXPECT_EQ(r_off.tile_share, 1.0);
      EXPECT_LE(r_on.tile_share, 1.0);
      // On these small maps the creep of the piles along the floor's edges (snow
      // falls off the world there) reaches nearly every tile; the house's roof
      // and the floor beside it come to rest, once a fixed cycle's first
      // strides (max_stride, ..., 2, 1: each computes every tile) are past.
      const int first_cycle = adaptive ? 0 : int(std::log2(max_stride)) + 1;
      if (std::string(name) == "house" && r_on.iterations > first_cycle) {
        EXPECT_LT(r_on.tile_share, 0.99);
      }
      expect_identical(on, off);
    }
  }
}

TEST(StabilizeGpu, ActiveTilesAreExact) {
  REQUIRE_GL();
  expect_active_tiles_exact(
      [](const SnowMaps& maps, std::vector<float>& depth, const StabilizeSettings& settings) {
        return stabilize(maps, depth, settings);
      });
}

TEST(StabilizeCpu, ActiveTilesAreExact) {
  expect_active_tiles_exact(
      [](const SnowMaps& maps, std::vector<float>& depth, const StabilizeSettings& settings) {
        return stabilize_cpu(maps, depth, settings);
      });
}

// Snow added in steps, a few passes per call (the live preview's use):
// resets, routing between passes and stride cycles cut by the calls. `on` and
// `off` are two stabilizers of one kind, with active tiles on and off.
template <class AnyStabilizer>
void expect_active_tiles_exact_through_time_steps(const SnowMaps& maps, AnyStabilizer& on,
                                                  AnyStabilizer& off) {
  const std::vector<float> amount = random_snow(maps, 0.2f, 11);
  for (int step = 0; step < 4; ++step) {
    on.add_snow(amount, 0.5f);
    off.add_snow(amount, 0.5f);
    for (int passes : {7, 1, 20}) {
      const StabilizeResult a = on.iterate(passes), b = off.iterate(passes);
      EXPECT_EQ(a.iterations, b.iterations);
      EXPECT_EQ(a.route_passes, b.route_passes);
      EXPECT_EQ(a.residual, b.residual);
    }
    SCOPED_TRACE(step);
    expect_identical(on.depth(), off.depth());
  }
  EXPECT_EQ(on.lost_volume(), off.lost_volume());
}

StabilizeSettings time_step_settings(bool active_tiles) {
  StabilizeSettings settings = loose_settings();
  settings.check_every = 5;
  settings.active_tiles = active_tiles;
  return settings;
}

TEST(StabilizeGpu, ActiveTilesAreExactThroughTimeSteps) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(84, 4);  // not whole tiles: the edge tiles are cut
  Stabilizer on(maps, time_step_settings(true)), off(maps, time_step_settings(false));
  expect_active_tiles_exact_through_time_steps(maps, on, off);
}

TEST(StabilizeCpu, ActiveTilesAndThreadsAreExactThroughTimeSteps) {
  const SnowMaps maps = bumpy_maps(84, 4);  // not whole tiles: the edge tiles are cut
  // Active tiles on 3 threads against full passes on one.
  CpuStabilizer on(maps, time_step_settings(true), 3), off(maps, time_step_settings(false), 1);
  expect_active_tiles_exact_through_time_steps(maps, on, off);
}

}  // namespace
}  // namespace snow::test
