// Tests of the stabilizer (src/snow/stabilize.h) and its CPU reference
// (src/snow/stabilize_cpu.h): mass conservation, the repose slope
// after convergence, sliding off steep supports, falling through to lower
// maps, and GPU against CPU.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/error.h"
#include "gl/context.h"
#include "scene/builder.h"
#include "snow/column.h"
#include "snow/deposit.h"
#include "snow/maps.h"
#include "snow/peel.h"
#include "snow/reference/peel_ref.h"
#include "snow/stabilize.h"
#include "snow/stabilize_cpu.h"

namespace snow {
namespace {

constexpr float kDeg = 3.14159265358979f / 180.0f;

// --- Analytic maps ----------------------------------------------------------

struct Surface {
  float y;      // metres
  glm::vec3 n;  // normal as wound
};
// The surfaces of the column through (x, z), from the top down.
using ColumnFn = std::function<std::vector<Surface>(float x, float z)>;

const glm::vec3 kUp(0.0f, 1.0f, 0.0f);
const glm::vec3 kDown(0.0f, -1.0f, 0.0f);

SnowMaps make_maps(int width, int height, float texel, int layers, const ColumnFn& column) {
  SnowMaps maps;
  MapGrid grid;
  grid.origin = glm::vec2(0.0f);
  grid.texel = texel;
  grid.width = width;
  grid.height = height;
  maps.allocate(grid, layers);
  for (int j = 0; j < height; ++j) {
    for (int i = 0; i < width; ++i) {
      const glm::vec2 c = grid.center(i, j);
      std::vector<Surface> s = column(c.x, c.y);
      std::stable_sort(s.begin(), s.end(),
                       [](const Surface& a, const Surface& b) { return a.y > b.y; });
      float last = kOpenSky;
      for (int l = 0; l < std::min<int>(layers, int(s.size())); ++l) {
        const size_t k = maps.index(l, i, j);
        maps.ground[k] = s[l].y;
        maps.ceiling[k] = last;
        maps.normal[k] = glm::normalize(s[l].n);
        maps.object[k] = 0;
        last = s[l].y;
      }
    }
  }
  return maps;
}

// `amount` metres on every layer-0 texel (snow falling straight down onto
// the top surfaces).
std::vector<float> snow_on_top(const SnowMaps& maps, float amount) {
  std::vector<float> depth(size_t(maps.layers) * maps.grid.texels(), 0.0f);
  for (int j = 0; j < maps.grid.height; ++j) {
    for (int i = 0; i < maps.grid.width; ++i) {
      if (maps.has_surface(0, i, j)) depth[maps.index(0, i, j)] = amount;
    }
  }
  return depth;
}

// A lean-to roof of `pitch_deg` over x in [x0, x1] (eave at x1, height
// eave_y there, rising towards x0), a one-sided plane, over a floor at y = 0.
ColumnFn lean_to_roof(float x0, float x1, float z0, float z1, float eave_y, float pitch_deg) {
  const float t = std::tan(pitch_deg * kDeg);
  const glm::vec3 n(std::sin(pitch_deg * kDeg), std::cos(pitch_deg * kDeg), 0.0f);
  return [=](float x, float z) {
    std::vector<Surface> s;
    if (x >= x0 && x < x1 && z >= z0 && z < z1) s.push_back({eave_y + (x1 - x) * t, n});
    s.push_back({0.0f, kUp});
    return s;
  };
}

// A table: a closed slab (top up-facing, underside down-facing) over a floor.
ColumnFn table(float cx, float cz, float half, float top_y, float thickness) {
  return [=](float x, float z) {
    std::vector<Surface> s;
    if (std::abs(x - cx) < half && std::abs(z - cz) < half) {
      s.push_back({top_y, kUp});
      s.push_back({top_y - thickness, kDown});
    }
    s.push_back({0.0f, kUp});
    return s;
  };
}

// Per-texel movable excess of a converged state: for every texel with more
// than `min_depth` of snow, the largest (h - h_land) - distance * tan(repose)
// over its neighbours that it can reach (a void neighbour counts as infinite).
float largest_excess(const SnowMaps& maps, const std::vector<float>& depth,
                     const StabilizeSettings& settings, float min_depth) {
  const std::vector<glm::vec4> cells = stabilize_cells(maps, settings);
  float largest = 0.0f;
  for (int l = 0; l < maps.layers; ++l) {
    for (int j = 0; j < maps.grid.height; ++j) {
      for (int i = 0; i < maps.grid.width; ++i) {
        const size_t k = maps.index(l, i, j);
        if (!maps.has_surface(l, i, j) || !(depth[k] > min_depth)) continue;
        const float h = std::min(maps.ground[k] + depth[k], maps.ceiling[k] - kCeilingClearance);
        for (int n = 0; n < 8; ++n) {
          const int ni = i + kDirI[n], nj = j + kDirJ[n];
          const int land = landing(maps, depth.data(), ni, nj, h, maps.ground[k]);
          if (land == kLandVoid) return INFINITY;
          if (land < 0) continue;
          const size_t kt = maps.index(land, ni, nj);
          const float dist = maps.grid.texel * (n < 4 ? 1.0f : std::sqrt(2.0f));
          const float e = h - (maps.ground[kt] + depth[kt]) - dist * cells[k].z;
          largest = std::max(largest, std::min(e, depth[k]));
        }
      }
    }
  }
  return largest;
}

double sum_where(const SnowMaps& maps, const std::vector<float>& depth,
                 const std::function<bool(int l, int i, int j)>& pick) {
  double sum = 0.0;
  for (int l = 0; l < maps.layers; ++l) {
    for (int j = 0; j < maps.grid.height; ++j) {
      for (int i = 0; i < maps.grid.width; ++i) {
        if (pick(l, i, j)) sum += double(depth[maps.index(l, i, j)]);
      }
    }
  }
  return sum * double(maps.grid.texel) * double(maps.grid.texel);
}

gl::Context* context() {
  static std::unique_ptr<gl::Context> ctx = []() -> std::unique_ptr<gl::Context> {
    try {
      return gl::create_context();
    } catch (const Error& e) {
      std::fprintf(stderr, "no GL context: %s\n", e.what());
      return nullptr;
    }
  }();
  return ctx.get();
}
#define REQUIRE_GL() \
  if (!context()) GTEST_SKIP() << "no OpenGL context"

// Bumpy terrain with holes (void columns), a floating slab (three layers)
// and a low shelf, for the property tests.
SnowMaps bumpy_maps(int size, int layers) {
  return make_maps(size, size, 0.05f, layers, [size](float x, float z) {
    std::vector<Surface> s;
    const float u = x / (0.05f * float(size)), v = z / (0.05f * float(size));
    if (std::abs(u - 0.7f) < 0.04f && std::abs(v - 0.3f) < 0.04f) return s;  // a hole
    if (u > 0.2f && u < 0.5f && v > 0.55f && v < 0.8f) {                     // a slab
      s.push_back({0.9f + 0.4f * u, glm::vec3(-0.4f, 1.0f, 0.0f)});
      s.push_back({0.8f + 0.4f * u, kDown});
    }
    if (u > 0.6f && u < 0.9f && v > 0.6f && v < 0.7f) {  // a shelf
      s.push_back({1.35f, kUp});
      s.push_back({1.3f, kDown});
    }
    const float g = 0.3f * std::sin(6.0f * u) * std::cos(5.0f * v) + 0.6f * u * u;
    const glm::vec3 n = glm::normalize(glm::vec3(
        -(1.8f * std::cos(6.0f * u) * std::cos(5.0f * v) + 1.2f * u) / (0.05f * float(size)), 1.0f,
        0.0f));
    s.push_back({g, n});
    return s;
  });
}

std::vector<float> random_snow(const SnowMaps& maps, float max_depth, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, max_depth);
  std::vector<float> depth(size_t(maps.layers) * maps.grid.texels(), 0.0f);
  for (int l = 0; l < maps.layers; ++l) {
    for (int j = 0; j < maps.grid.height; ++j) {
      for (int i = 0; i < maps.grid.width; ++i) {
        const size_t k = maps.index(l, i, j);
        const float d = u(rng);  // drawn for every texel, so seeds give the same field
        if (maps.has_surface(l, i, j) && !gap_is_solid(maps, l, i, j)) depth[k] = d;
      }
    }
  }
  return depth;
}

// --- The landing rule ---------------------------------------------------------

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

// --- CPU reference on analytic maps -----------------------------------------

TEST(StrideSchedule, LengthensOnlyWhereTheSnowCreeps) {
  StabilizeSettings settings;  // max_stride 4
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
  StabilizeSettings settings;
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
  StabilizeSettings settings;
  settings.max_iterations = 50;
  CpuStabilizer stabilizer(maps, settings);
  stabilizer.set_depth(start);
  const StabilizeResult r = stabilizer.iterate(settings.max_iterations);
  const std::vector<float> cpu = stabilizer.depth();
  for (float d : cpu) EXPECT_GE(d, 0.0f);
  EXPECT_GT(r.lost_volume, 0.0);
  EXPECT_NEAR(snow_volume(maps, cpu) + r.lost_volume, before, 1e-6 * before);
  if (!context()) return;
  std::vector<float> gpu = start;
  stabilize(maps, gpu, settings);
  EXPECT_EQ(gpu, cpu);
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
  StabilizeSettings settings;
  settings.tolerance = 0.0f;  // run every pass
  CpuStabilizer summed(maps, settings), quiet(maps, settings);
  expect_volume_sums_change_only_the_sums(maps, summed, quiet);
}

TEST(StabilizeGpu, VolumeSumsOffChangeOnlyTheSums) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(64, 4);
  StabilizeSettings settings;
  settings.tolerance = 0.0f;
  Stabilizer summed(maps, settings), quiet(maps, settings);
  expect_volume_sums_change_only_the_sums(maps, summed, quiet);
}

TEST(StabilizeReference, ConvergedSnowIsAtRest) {
  const SnowMaps maps = bumpy_maps(64, 4);
  std::vector<float> depth = random_snow(maps, 0.5f, 11);
  StabilizeSettings settings;
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
  StabilizeSettings settings;
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

// A spike of routed snow on a snowy floor under the open sky, poured as a pile:
// the volume is exact, the pile is a cone at rest (no neighbour above
// another by more than distance * tan(repose)), and the relaxation that
// follows has little left to do, where it takes many passes to flatten the
// spike.
TEST(StabilizeReference, RoutedSnowIsPouredAsAConeAtRest) {
  const float texel = 0.05f;
  const int side = 41, mid = 20;
  const SnowMaps maps = make_maps(side, side, texel, 2, [](float, float) {
    return std::vector<Surface>{{0.0f, kUp}};
  });
  StabilizeSettings settings;
  settings.repose_jitter_deg = 0.0f;  // tan = 1: the cone's heights are known
  const std::vector<glm::vec4> cells = stabilize_cells(maps, settings);
  const float lying = 0.3f;
  std::vector<float> depth = snow_on_top(maps, lying), arrive(cells.size(), 0.0f);
  const std::vector<float> before = depth;
  const size_t centre = maps.index(0, mid, mid);
  const float volume = 2.0f;  // metres of depth on one texel: 40 texels high
  arrive[centre] = volume;
  ASSERT_EQ(
      deposit_piles(cells.data(), depth.data(), arrive.data(), DepositGrid{side, side, 2, texel}),
      1u);
  double added = 0.0;
  for (size_t k = 0; k < depth.size(); ++k) added += double(depth[k]) - double(before[k]);
  EXPECT_NEAR(added, double(volume), 1e-5);
  std::printf("pile: %.3f m at the apex (a spike: %.3f m), %.3f m one texel out\n",
              depth[centre] - lying, volume, depth[maps.index(0, mid + 1, mid)] - lying);
  EXPECT_LT(depth[centre] - lying, 0.2f * volume);
  EXPECT_GT(depth[maps.index(0, mid + 3, mid)], lying);
  EXPECT_NEAR(depth[maps.index(0, mid + 3, mid)], depth[maps.index(0, mid - 3, mid)], 1e-6f);
  EXPECT_NEAR(depth[maps.index(0, mid, mid + 3)], depth[maps.index(0, mid - 3, mid)], 1e-6f);
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i + 1 < side; ++i) {
      EXPECT_LE(std::abs(depth[maps.index(0, i, j)] - depth[maps.index(0, i + 1, j)]),
                texel * 1.0f + 1e-5f)
          << i << ", " << j;
    }
  }
  // The whole stabilizer on the spike, with the routed snow poured or left
  // on its terminal.
  std::vector<float> poured = before, left = before;
  poured[centre] += volume;
  left[centre] += volume;
  const StabilizeResult with = stabilize_cpu(maps, poured, settings);
  settings.deposit_piles = false;
  const StabilizeResult without = stabilize_cpu(maps, left, settings);
  std::printf("relaxation: %d passes with the pile poured, %d without\n", with.iterations,
              without.iterations);
  EXPECT_TRUE(with.converged);
  EXPECT_LT(with.iterations, without.iterations);
}

// A 2.4 m floor (48 texels of 5 cm) with a square slab over x, z in (lo,
// hi): top 0.15 m, underside 0.1 m above the floor.
SnowMaps slab_maps(float lo, float hi) {
  return make_maps(48, 48, 0.05f, 4, [=](float x, float z) {
    std::vector<Surface> s;
    if (x > lo && x < hi && z > lo && z < hi) {
      s.push_back({0.15f, kUp});
      s.push_back({0.1f, kDown});
    }
    s.push_back({0.0f, kUp});
    return s;
  });
}

// A 0.8 m square shelf over the middle (texel columns 16 to 31).
SnowMaps shelf_maps() { return slab_maps(0.8f, 1.6f); }

// Under a ceiling, what fits stays on the terminal; what would be pressed
// above the ceiling is poured as a pile that fills the gap up to the
// ceiling around it (snow sliding off a tree's tiers into the low gap under
// them: metres of depth on one texel, squeezed out over a thousand passes).
TEST(StabilizeReference, RoutedSnowUnderACeilingFillsTheGap) {
  const SnowMaps maps = shelf_maps();  // 0.1 m gap under the shelf
  const std::vector<glm::vec4> cells = stabilize_cells(maps, StabilizeSettings{});
  std::vector<float> depth(cells.size(), 0.0f), arrive(cells.size(), 0.0f);
  const size_t under = maps.index(2, 24, 24);  // the floor under the shelf's middle
  ASSERT_TRUE(maps.has_surface(2, 24, 24));
  ASSERT_NEAR(maps.ceiling[under] - maps.ground[under], 0.1f, 1e-6f);
  arrive[under] = 2.0f;
  deposit_piles(cells.data(), depth.data(), arrive.data(), DepositGrid{48, 48, 4, 0.05f});
  double sum = 0.0;
  int covered = 0;
  for (size_t k = 0; k < depth.size(); ++k) {
    sum += depth[k];
    if (depth[k] == 0.0f) continue;
    ++covered;
    EXPECT_LE(maps.ground[k] + depth[k], maps.ceiling[k] - kCeilingClearance + 1e-6f) << k;
  }
  EXPECT_NEAR(sum, 2.0, 1e-5);
  EXPECT_GE(covered, 20);  // 2 m of depth in a 0.1 m gap
  EXPECT_NEAR(depth[under], 0.1f - kCeilingClearance, 1e-6f);
}

// Maps of 512 rows and more pour their piles by bands of rows, the bands of
// a phase on several threads: the same bits as on one thread, where the
// bands' piles stay apart (poured in parallel) and where two of them meet
// (the phase undone and poured again serially), and the volume is exact.
TEST(StabilizeReference, PilesPouredByBandsAreTheSameOnAnyThreads) {
  const int width = 24, height = 512;  // bands of 64 rows
  const float texel = 0.05f;
  const SnowMaps maps = make_maps(width, height, texel, 2, [](float, float) {
    return std::vector<Surface>{{0.0f, kUp}};
  });
  const std::vector<glm::vec4> cells = stabilize_cells(maps, StabilizeSettings{});
  const std::vector<float> lying = snow_on_top(maps, 0.1f);
  const DepositGrid grid{width, height, 2, texel};
  struct Pile {
    int i, j;
    float metres;
  };
  const auto pour = [&](const std::vector<Pile>& piles, unsigned threads, DepositStats& stats) {
    std::vector<float> depth = lying, arrive(depth.size(), 0.0f);
    std::vector<uint32_t> terminals;
    for (const Pile& p : piles) {
      const size_t k = maps.index(0, p.i, p.j);
      arrive[k] = p.metres;
      terminals.push_back(uint32_t(k));
    }
    EXPECT_EQ(
        deposit_piles(cells.data(), depth.data(), arrive.data(), terminals, grid, threads, &stats),
        piles.size());
    double added = 0.0;
    for (size_t k = 0; k < depth.size(); ++k) added += double(depth[k]) - double(lying[k]);
    double poured = 0.0;
    for (const Pile& p : piles) poured += p.metres;
    EXPECT_NEAR(added, poured, 1e-4 * poured);
    return depth;
  };
  // Three piles in the middle rows of each band, about 7 texels in radius,
  // overlapping (their order matters).
  std::vector<Pile> apart;
  for (int band = 0; band < 8; ++band) {
    apart.push_back({7, 64 * band + 30, 20.0f});
    apart.push_back({12, 64 * band + 32, 10.0f});
    apart.push_back({17, 64 * band + 34, 20.0f});
  }
  // Two piles of 10 m^3 each at the near edges of bands 0 and 2: both spread
  // over band 1, between them. Band 0's small piles come first, so they are
  // poured (and must be undone) before its large pile can meet band 2's.
  const std::vector<Pile> meeting = {
      {12, 10, 5.0f}, {12, 20, 5.0f}, {12, 60, 4000.0f}, {12, 132, 4000.0f}, {12, 290, 5.0f}};
  for (const auto& [name, piles, parallel] :
       {std::make_tuple("apart", apart, true), std::make_tuple("meeting", meeting, false)}) {
    SCOPED_TRACE(name);
    DepositStats one, many;
    const std::vector<float> serial = pour(piles, 1, one);
    const std::vector<float> banded = pour(piles, 4, many);
    EXPECT_EQ(one.piles_in_parallel, 0u);
    EXPECT_EQ(many.piles_in_parallel, parallel ? piles.size() : 0u);
    ASSERT_EQ(serial.size(), banded.size());
    EXPECT_EQ(std::memcmp(serial.data(), banded.data(), serial.size() * sizeof(float)), 0);
  }
}

// A 0.2 m box on a plate of side * 1 cm (0.48 m by default), the void
// beyond: snow routed off the box piles at its walls and spreads out to the
// plate's edge, where it creeps off.
SnowMaps box_on_plate_maps(int side = 48) {
  const float texel = 0.01f, half = 0.12f, mid = 0.24f;
  return make_maps(side, side, texel, 2, [=](float x, float z) {
    std::vector<Surface> s;
    if (std::abs(x - mid) < half && std::abs(z - mid) < half) s.push_back({0.2f, kUp});
    s.push_back({0.0f, kUp});
    return s;
  });
}

TEST(StabilizeReference, SnowCreepingOffAnEdgeIsDrained) {
  const SnowMaps maps = box_on_plate_maps();
  const std::vector<float> start = snow_on_top(maps, 0.1f);
  const double fell = snow_volume(maps, start);
  std::vector<float> relaxed = start, drained = start;
  StabilizeSettings settings;
  settings.drain_edges = false;
  const StabilizeResult r0 = stabilize_cpu(maps, relaxed, settings);
  settings.drain_edges = true;
  const StabilizeResult r1 = stabilize_cpu(maps, drained, settings);
  std::printf("creeping off an edge: %d passes relaxed, %d with %d drains; %.6f against %.6f m^3\n",
              r0.iterations, r1.iterations, r1.drains, r0.volume, r1.volume);
  EXPECT_TRUE(r0.converged);
  EXPECT_TRUE(r1.converged);
  EXPECT_EQ(r0.drains, 0);
  EXPECT_GE(r1.drains, 1);
  EXPECT_LT(3 * r1.iterations, r0.iterations);  // 426 against 82 when written
  EXPECT_NEAR(r1.volume + r1.lost_volume, fell, 1e-9);
  EXPECT_NEAR(r1.volume, r0.volume, 1e-3 * r0.volume);
  EXPECT_LE(largest_excess(maps, drained, settings, 1e-4f), 2e-4f);
  float difference = 0.0f;
  for (size_t k = 0; k < drained.size(); ++k) {
    difference = std::max(difference, std::abs(drained[k] - relaxed[k]));
  }
  EXPECT_LT(difference, 1e-3f);  // a tenth of a texel
}

TEST(StabilizeReference, TableEdgesRoundOff) {
  // A 1 m table top, 0.75 m high, 0.05 m thick, in a 3.2 m room; 0.3 m of snow
  // on every top surface.
  const float texel = 0.05f;
  const SnowMaps maps = make_maps(64, 64, texel, 4, table(1.6f, 1.6f, 0.5f, 0.75f, 0.05f));
  std::vector<float> depth = snow_on_top(maps, 0.3f);
  StabilizeSettings settings;
  const StabilizeResult r = stabilize_cpu(maps, depth, settings);
  ASSERT_TRUE(r.converged);
  // Along the row through the table's centre.
  const int j = 32;
  auto top_of = [&](int i) { return depth[maps.index(0, i, j)]; };
  const int edge = 22;  // first texel on the table (x = 1.1..1.15)
  ASSERT_TRUE(maps.ground[maps.index(0, edge, j)] > 0.5f);
  ASSERT_FALSE(maps.ground[maps.index(0, edge - 1, j)] > 0.5f);
  // The edge texel keeps little, the middle keeps the full depth, and the
  // profile rises at most at the repose angle (+ jitter) from the edge.
  EXPECT_LT(top_of(edge), 0.06f);
  EXPECT_NEAR(top_of(32), 0.3f, 1e-3f);
  for (int i = edge; i < 32; ++i) {
    EXPECT_LE(top_of(i), (float(i - edge) + 0.5f) * texel * std::tan(48.0f * kDeg) + 2e-4f) << i;
  }
  // Under the table: nothing from the top. The floor snow round the table
  // slumps in at the repose angle from the shadow's edge (0.3 m of snow: at
  // most 0.3 / tan(42 deg) + 1 texel), the rest stays bare.
  const float reach = 0.3f / std::tan(42.0f * kDeg) + texel;
  double under = 0.0;
  for (int jj = 0; jj < 64; ++jj) {
    for (int i = 0; i < 64; ++i) {
      if (!maps.has_surface(2, i, jj)) continue;
      const glm::vec2 c = maps.grid.center(i, jj);
      const float inside = 0.5f - std::max(std::abs(c.x - 1.6f), std::abs(c.y - 1.6f));
      if (inside > reach) under += depth[maps.index(2, i, jj)];
    }
  }
  EXPECT_EQ(under, 0.0);
  EXPECT_GT(depth[maps.index(0, edge - 1, j)], 0.3f);
  EXPECT_NEAR(top_of(edge - 6), 0.3f, 0.02f);  // the floor further out is untouched
}

TEST(StabilizeReference, LowCeilingCapsDepth) {
  // A shelf whose underside is 0.1 m above the floor, with 0.3 m of snow
  // forced under it.
  const SnowMaps maps = shelf_maps();
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ground[k] == 0.0f) depth[k] = 0.3f;
  }
  const double before = snow_volume(maps, depth);
  const StabilizeResult r = stabilize_cpu(maps, depth, StabilizeSettings{});
  ASSERT_TRUE(r.converged);
  float deepest_under = 0.0f;
  for (int j = 0; j < 48; ++j) {
    for (int i = 0; i < 48; ++i) {
      if (maps.has_surface(2, i, j))
        deepest_under = std::max(deepest_under, depth[maps.index(2, i, j)]);
    }
  }
  EXPECT_LE(deepest_under, 0.1f + 1e-4f);
  EXPECT_GT(deepest_under, 0.05f);
  EXPECT_NEAR(snow_volume(maps, depth) + r.lost_volume, before, 1e-5 * before);
}

// A cellar: a 1.6 m square slab 0.1 m over the floor, the gap under it
// filled with 0.12 m of snow (2 cm pressed above its ceiling) and 0.09 m
// around it. The routing sends out only the edge's pressed snow (inside,
// the heights it may keep are level); the relaxation squeezes the rest out
// one texel per pass, a pressure that diffuses across the slab.
SnowMaps cellar_maps() { return slab_maps(0.4f, 2.0f); }

std::vector<float> cellar_snow(const SnowMaps& maps) {
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ground[k] == 0.0f) {
      depth[k] = maps.ceiling[k] < 1.0f ? 0.12f : 0.09f;
    }
  }
  return depth;
}

// Snow pressed above its ceiling is poured out as piles once the relaxation
// creeps: it settles, none stays above its ceiling, and mass is exact.
TEST(StabilizeReference, PressedSnowIsPouredOut) {
  const SnowMaps maps = cellar_maps();
  std::vector<float> depth = cellar_snow(maps);
  const double before = snow_volume(maps, depth);
  StabilizeSettings settings;
  settings.max_iterations = 2000;
  const StabilizeResult r = stabilize_cpu(maps, depth, settings);
  std::printf("cellar: %d passes, %d pours, converged %d\n", r.iterations, r.pours,
              int(r.converged));
  EXPECT_TRUE(r.converged);
  EXPECT_GE(r.pours, 1);
  EXPECT_LT(r.iterations, 1000);  // 480 passes; squeezed out by the passes alone: 1884
  float highest_over = -1.0f;
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ceiling[k] < 1.0f) {
      highest_over = std::max(highest_over, maps.ground[k] + depth[k] - maps.ceiling[k]);
    }
  }
  EXPECT_LE(highest_over, settings.tolerance);
  EXPECT_NEAR(snow_volume(maps, depth) + r.lost_volume, before, 1e-5 * before);
}

TEST(StabilizeReference, BowlFillsFromTheBottom) {
  // A conical bowl with 60 degree walls, 1 m in radius at its rim (1.73 m
  // deep), sunk in a floor; 0.3 m of snow on every top surface.
  const float cx = 1.6f, rim_r = 1.0f, t60 = std::tan(60.0f * kDeg);
  const SnowMaps maps = make_maps(64, 64, 0.05f, 4, [&](float x, float z) {
    const float r = std::hypot(x - cx, z - cx);
    if (r >= rim_r) return std::vector<Surface>{{0.0f, kUp}};
    const glm::vec3 n(-(x - cx) / std::max(r, 1e-6f) * t60, 1.0f,
                      -(z - cx) / std::max(r, 1e-6f) * t60);
    return std::vector<Surface>{{(r - rim_r) * t60, n}};
  });
  std::vector<float> depth = snow_on_top(maps, 0.3f);
  const double before = snow_volume(maps, depth);
  const StabilizeResult r = stabilize_cpu(maps, depth, StabilizeSettings{});
  ASSERT_TRUE(r.converged);
  EXPECT_NEAR(snow_volume(maps, depth) + r.lost_volume, before, 1e-5 * before);
  // The snow that fell into the bowl (pi r^2 0.3 m, 0.94 m^3) collects at
  // the bottom: the deepest snow is there, far deeper than what fell, and
  // the walls above the fill are bare.
  const int c = 32;
  float deepest = 0.0f, fill_top = -10.0f;
  double in_bowl = 0.0;
  for (int j = 0; j < 64; ++j) {
    for (int i = 0; i < 64; ++i) {
      const size_t k = maps.index(0, i, j);
      const float rr = glm::length(maps.grid.center(i, j) - glm::vec2(cx));
      if (rr >= rim_r) continue;
      in_bowl += depth[k];
      if (depth[k] > deepest) deepest = depth[k];
      if (depth[k] > 1e-3f) fill_top = std::max(fill_top, maps.ground[k] + depth[k]);
    }
  }
  in_bowl *= 0.05 * 0.05;
  float bare_above = 0.0f;
  for (int j = 0; j < 64; ++j) {
    for (int i = 0; i < 64; ++i) {
      const size_t k = maps.index(0, i, j);
      const float rr = glm::length(maps.grid.center(i, j) - glm::vec2(cx));
      if (rr < rim_r - 0.15f && maps.ground[k] > fill_top - 0.05f * t60 && rr > 0.0f) {
        bare_above = std::max(bare_above, depth[k]);
      }
    }
  }
  std::printf(
      "bowl: %d passes (+%d routing), %.3f m^3 in the bowl, deepest %.3f m at the "
      "centre %.3f m, fill top %.3f m\n",
      r.iterations, r.route_passes, in_bowl, deepest, depth[maps.index(0, c, c)], fill_top);
  EXPECT_GT(in_bowl, 0.85);
  EXPECT_NEAR(depth[maps.index(0, c, c)], deepest, 0.05f);
  EXPECT_GT(deepest, 0.6f);
  EXPECT_LT(bare_above, 0.01f);
}

TEST(StabilizeReference, LeanToRoofs) {
  // One-sided lean-to roofs (no thickness) over a floor, eave at x = 3 m.
  for (float pitch : {60.0f, 30.0f}) {
    const SnowMaps maps =
        make_maps(96, 48, 0.05f, 4, lean_to_roof(0.5f, 3.0f, 0.6f, 1.8f, 1.5f, pitch));
    std::vector<float> depth = snow_on_top(maps, 0.3f);
    auto on_roof = [&](int l, int i, int j) {
      return l == 0 && maps.ground[maps.index(0, i, j)] > 0.5f;
    };
    const double roof_before = sum_where(maps, depth, on_roof);
    const StabilizeResult r = stabilize_cpu(maps, depth, StabilizeSettings{});
    const double roof_after = sum_where(maps, depth, on_roof);
    std::printf("%.0f deg lean-to: %d passes (+%d routing), roof %.3f -> %.4f m^3\n", pitch,
                r.iterations, r.route_passes, roof_before, roof_after);
    EXPECT_TRUE(r.converged);
    if (pitch > 45.0f) {
      EXPECT_LT(roof_after, 0.01 * roof_before);
    } else {
      EXPECT_GT(roof_after, 0.4 * roof_before);  // a narrow roof: its edges round off
    }
    // No snow passed through the thin roof into the space under it: under the
    // roof, snow only slumps in from the open sides, the back and the eave
    // (each at most about 1 m here).
    const double through = sum_where(maps, depth, [&](int l, int i, int j) {
      const glm::vec2 c = maps.grid.center(i, j);
      return l == 1 && c.x > 1.0f && c.x < 2.0f && c.y > 1.0f && c.y < 1.4f;
    });
    EXPECT_EQ(through, 0.0);
  }
}

// --- GPU against the CPU reference ------------------------------------------

void expect_same(const std::vector<float>& gpu, const std::vector<float>& cpu, float tolerance) {
  ASSERT_EQ(gpu.size(), cpu.size());
  float worst = 0.0f;
  for (size_t k = 0; k < gpu.size(); ++k) worst = std::max(worst, std::abs(gpu[k] - cpu[k]));
  std::printf("GPU vs CPU: largest difference %.3e m\n", worst);
  EXPECT_LE(worst, tolerance);
}

// Bit for bit the same depths.
void expect_identical(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  size_t differ = 0;
  for (size_t k = 0; k < a.size(); ++k) differ += std::memcmp(&a[k], &b[k], sizeof(float)) != 0;
  EXPECT_EQ(differ, 0u);
}

TEST(StabilizeGpu, MatchesReference) {
  REQUIRE_GL();
  const SnowMaps maps = bumpy_maps(64, 4);
  const std::vector<float> start = random_snow(maps, 0.5f, 3);
  StabilizeSettings settings;
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
      EXPECT_EQ(rg.residual, rc.residual);  // the largest move of the last pass, bit for bit
      EXPECT_NEAR(rg.lost_volume, rc.lost_volume, 1e-4);
      EXPECT_NEAR(rg.volume, rc.volume, 1e-4);
      expect_same(gpu, cpu, 1e-4f);
    }
}

// The GPU stabilizer pours the same piles (on the CPU, from its readback):
// a spike on a snowy floor, routing and pouring only, bit for bit.
TEST(StabilizeGpu, PilesMatchReference) {
  REQUIRE_GL();
  const int side = 33, mid = 16;
  const SnowMaps maps = make_maps(side, side, 0.05f, 2, [](float x, float) {
    return std::vector<Surface>{{0.02f * x, kUp}};  // a gentle slope
  });
  std::vector<float> cpu = snow_on_top(maps, 0.2f);
  cpu[maps.index(0, mid, mid)] += 1.5f;
  std::vector<float> gpu = cpu;
  StabilizeSettings settings;
  settings.max_iterations = 0;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GT(rc.routed_volume, 0.0);
  EXPECT_NEAR(rg.routed_volume, rc.routed_volume, 1e-6);
  EXPECT_LT(*std::max_element(cpu.begin(), cpu.end()), 0.2f + 0.3f);  // poured, no spike
  EXPECT_EQ(gpu, cpu);
}

TEST(StabilizeGpu, DrainingMatchesReference) {
  REQUIRE_GL();
  // A plate large enough that much of it rests (tiles the passes skip) when
  // a drain runs: the routing uses the outflow textures as scratch, so the
  // next passes must compute every tile again.
  const SnowMaps maps = box_on_plate_maps(96);
  std::vector<float> cpu = snow_on_top(maps, 0.1f), gpu = cpu;
  const StabilizeSettings settings;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GE(rc.drains, 1);
  EXPECT_EQ(rg.drains, rc.drains);
  EXPECT_EQ(rg.iterations, rc.iterations);
  EXPECT_EQ(gpu, cpu);
}

TEST(StabilizeGpu, PressedSnowPoursMatchReference) {
  REQUIRE_GL();
  const SnowMaps maps = cellar_maps();
  std::vector<float> cpu = cellar_snow(maps), gpu = cpu;
  StabilizeSettings settings;
  settings.max_iterations = 2000;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GE(rc.pours, 1);
  EXPECT_EQ(rg.pours, rc.pours);
  EXPECT_EQ(rg.iterations, rc.iterations);
  EXPECT_EQ(gpu, cpu);
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
  StabilizeSettings settings;
  settings.max_iterations = 0;  // routing only
  std::vector<float> cpu = start, gpu = start;
  stabilize_cpu(maps, cpu, settings);
  stabilize(maps, gpu, settings);
  expect_same(gpu, cpu, 1e-6f);
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
  StabilizeSettings settings;
  settings.max_iterations = 0;  // routing only
  std::vector<float> cpu = start, tiled = start, full = start;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rt = stabilize(maps, tiled, settings);
  settings.active_tiles = false;
  const StabilizeResult rf = stabilize(maps, full, settings);
  EXPECT_GT(rc.routed_volume, 0.0);
  EXPECT_EQ(rt.route_passes, rf.route_passes);
  expect_same(tiled, cpu, 1e-6f);
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
  StabilizeSettings settings;
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
    expect_same(gpu, cpu, 1e-6f);
    bump.expect(gpu, min_move > 0.0f);
  }
}

// The default min_move is automatic: a tenth of the tolerance. On the bump
// above (single steps of 0.45-1 mm), a tolerance of 20 mm makes it 2 mm and
// the bump stays, as with min_move 0.002; a tolerance of 1 mm makes it
// 0.1 mm and the bump moves. An explicit min_move is kept.
TEST(StabilizeCpu, AutomaticMinMoveIsATenthOfTheTolerance) {
  StabilizeSettings settings;
  EXPECT_LT(settings.min_move, 0.0f);
  EXPECT_FLOAT_EQ(min_move_of(settings), 0.1f * settings.tolerance);
  settings.min_move = 0.0f;
  EXPECT_EQ(min_move_of(settings), 0.0f);
  settings.min_move = std::nanf("");
  EXPECT_THROW(check_stabilize_settings(settings), InputError);

  const Bump bump;
  settings = StabilizeSettings{};
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
// the live preview takes the GPU's unless the renderer is software. A
// hardware renderer is stood in for by a context that is never made: an
// OnDemandContext told it is not software answers renderer_is_software()
// without making one.
TEST(StabilizeDevice, AutoIsTheCpuForTheBatchJobAndTheRendererForThePreview) {
  StabilizeSettings settings;
  EXPECT_EQ(settings.device, "auto");
  for (const bool software : {false, true}) {
    SCOPED_TRACE(software);
    gl::OnDemandContext hardware(
        []() -> std::unique_ptr<gl::Context> {
          throw std::logic_error("no pass should need a context here");
        },
        software);
    settings.device = "auto";
    EXPECT_TRUE(stabilizes_on_cpu(settings));
    EXPECT_TRUE(stabilizes_on_cpu(settings, StabilizerUse::Batch));
    EXPECT_EQ(stabilizes_on_cpu(settings, StabilizerUse::Live), software);
    EXPECT_FALSE(hardware.made());
    for (const StabilizerUse use : {StabilizerUse::Batch, StabilizerUse::Live}) {
      settings.device = "gpu";
      EXPECT_FALSE(stabilizes_on_cpu(settings, use));
      settings.device = "cpu";
      EXPECT_TRUE(stabilizes_on_cpu(settings, use));
    }
  }
}

// --- Builder scenes (reference peel, GPU stabilizer) -------------------------

SnowMaps scene_maps(const Scene& scene, int side, int layers = 8) {
  PeelSettings settings;
  settings.max_side = side;
  settings.layers = layers;
  return reference::peel_layers(scene, make_grid(scene.bounds, settings), layers);
}

// Snow top (ground + depth) of the highest layer with snow in column (i, j)
// whose ground is below `below`, or NaN.
float snow_top_below(const SnowMaps& maps, const std::vector<float>& depth, int i, int j,
                     float below) {
  for (int l = 0; l < maps.layers && maps.has_surface(l, i, j); ++l) {
    const size_t k = maps.index(l, i, j);
    if (maps.ground[k] < below) return maps.ground[k] + depth[k];
  }
  return NAN;
}

struct HouseRun {
  SnowMaps maps;
  std::vector<float> before, after;
  StabilizeResult result;
  int roof = -1, floor = -1;
};

HouseRun run_house(const HouseDims& dims, int side) {
  HouseRun run;
  const Scene scene = make_house_scene(dims);
  run.maps = scene_maps(scene, side);
  run.roof = find_object(scene, "HouseRoof");
  run.floor = find_object(scene, "Floor");
  run.before = snow_on_top(run.maps, 0.3f);
  run.after = run.before;
  run.result = stabilize(run.maps, run.after, StabilizeSettings{});
  return run;
}

HouseRun run_house(float pitch, int side) {
  HouseDims dims;
  dims.roof_pitch_deg = pitch;
  return run_house(dims, side);
}

double object_volume(const SnowMaps& maps, const std::vector<float>& depth, int object,
                     const std::function<bool(glm::vec2)>& where = nullptr) {
  return sum_where(maps, depth, [&](int l, int i, int j) {
    const size_t k = maps.index(l, i, j);
    return maps.object[k] == object && (!where || where(maps.grid.center(i, j)));
  });
}

TEST(StabilizeScenes, SteepRoofShedsToTheEaves) {
  REQUIRE_GL();
  const HouseRun run = run_house(60.0f, 128);
  const SnowMaps& maps = run.maps;
  const HouseDims dims;
  const float texel = maps.grid.texel;
  auto outside = [&](glm::vec2 c) {
    return std::abs(c.x) > dims.width / 2 || std::abs(c.y) > dims.depth / 2;
  };
  auto inside = [&](glm::vec2 c) {
    return std::abs(c.x) < dims.width / 2 - dims.wall_thickness &&
           std::abs(c.y) < dims.depth / 2 - dims.wall_thickness;
  };
  const double roof_before = object_volume(maps, run.before, run.roof);
  const double roof_after = object_volume(maps, run.after, run.roof);
  const double ground_gain = object_volume(maps, run.after, run.floor, outside) -
                             object_volume(maps, run.before, run.floor, outside) +
                             run.result.lost_volume;  // only the floor's far edges lose snow
  double in_house = 0.0;
  for (int l = 1; l < maps.layers; ++l) {
    in_house += sum_where(maps, run.after, [&](int ll, int i, int j) {
      return ll == l && inside(maps.grid.center(i, j));
    });
  }
  std::printf(
      "60 deg house: %d passes (+%d routing, %.2f m^3 routed), residual %.1e; roof %.3f -> "
      "%.4f m^3, ground outside +%.3f m^3, inside %.4f m^3\n",
      run.result.iterations, run.result.route_passes, run.result.routed_volume, run.result.residual,
      roof_before, roof_after, ground_gain, in_house);
  EXPECT_TRUE(run.result.converged);
  EXPECT_LT(roof_after, 0.05 * roof_before);
  EXPECT_GE(ground_gain, 0.95 * roof_before);
  EXPECT_EQ(in_house, 0.0);
  // The piles along both eaves crest within 3 texels of the drip line, along
  // the middle third of the house.
  const float drip = dims.depth / 2 + dims.eaves_overhang;
  int worst = 0;
  for (int i = 0; i < maps.grid.width; ++i) {
    const float x = maps.grid.center(i, 0).x;
    if (std::abs(x) > dims.width / 6) continue;
    for (float side : {-1.0f, 1.0f}) {
      float best = -1.0f, best_z = 0.0f;
      for (int j = 0; j < maps.grid.height; ++j) {
        const float z = maps.grid.center(i, j).y;
        if (side * z < dims.depth / 2 || side * z > drip + 2.0f) continue;
        const float top = snow_top_below(maps, run.after, i, j, 0.5f);
        if (top > best + 1e-4f) {
          best = top;
          best_z = z;
        }
      }
      worst = std::max(worst, int(std::lround(std::abs(side * best_z - drip) / texel)));
    }
  }
  std::printf("pile crest: at most %d texels from the drip line\n", worst);
  EXPECT_LE(worst, 3);
}

// Share of a gable roof's snow (depth s, pitch a) that the repose rule
// (angle t) keeps: along each eave the snow rounds off over s / (tan t -
// tan a), along each gable end over s / tan t, each losing a triangle.
double repose_retention(const HouseDims& d, float s, float repose_deg) {
  const double t = std::tan(repose_deg * kDeg), a = std::tan(d.roof_pitch_deg * kDeg);
  const double length = d.width + 2 * d.eaves_overhang, run = d.depth / 2 + d.eaves_overhang;
  const double eaves = 2 * length * 0.5 * s * (s / (t - a));
  const double gables = 4 * run * 0.5 * s * (s / t);
  return 1.0 - (eaves + gables) / (2 * length * run * s);
}

TEST(StabilizeScenes, GentleRoofKeepsItsSnow) {
  REQUIRE_GL();
  // The repose rule rounds the snow off along the eaves and gable ends; the
  // rest of a 30 degree roof (below the 45 degree repose angle) keeps it.
  // On the default house (2.5 m of run) that is 81 % in theory; on a large
  // house (7.5 m of run) 93 %.
  HouseDims large;
  large.roof_pitch_deg = 30.0f;
  large.width = 16.0f;
  large.depth = 14.0f;
  large.floor_size = 24.0f;
  HouseDims small;
  small.roof_pitch_deg = 30.0f;
  for (const HouseDims& dims : {small, large}) {
    const HouseRun run = run_house(dims, dims.width > 10 ? 256 : 128);
    const double roof_before = object_volume(run.maps, run.before, run.roof);
    const double roof_after = object_volume(run.maps, run.after, run.roof);
    const double keeps = roof_after / roof_before, theory = repose_retention(dims, 0.3f, 45.0f);
    std::printf(
        "30 deg house %.0f x %.0f m, texel %.3f m: %d passes (+%d routing), roof keeps "
        "%.1f %% (repose theory %.1f %%)\n",
        dims.width, dims.depth, run.maps.grid.texel, run.result.iterations, run.result.route_passes,
        100.0 * keeps, 100.0 * theory);
    EXPECT_TRUE(run.result.converged);
    // The discrete edge texels lose all their snow: up to a texel more along
    // the eaves and along the gable ends.
    const double texel = run.maps.grid.texel;
    EXPECT_GE(keeps, theory - texel / (dims.depth / 2 + dims.eaves_overhang) -
                         2 * texel / (dims.width + 2 * dims.eaves_overhang));
    EXPECT_LE(keeps, theory + 0.02);
    if (dims.width > 10) {
      EXPECT_GE(keeps, 0.9);
    }
  }
}

TEST(StabilizeScenes, TableSnowRoundsOffOntoTheFloor) {
  REQUIRE_GL();
  const Scene scene = make_table_scene();  // 1 m top at 0.75 m, 4 m floor
  const SnowMaps maps = scene_maps(scene, 128);
  const int top = find_object(scene, "TableTop"), floor = find_object(scene, "Floor");
  std::vector<float> depth = snow_on_top(maps, 0.3f);
  const std::vector<float> before = depth;
  const StabilizeResult r = stabilize(maps, depth, StabilizeSettings{});
  ASSERT_TRUE(r.converged);
  const float texel = maps.grid.texel;
  auto near_table = [&](glm::vec2 c) {  // outside and under its edges
    return std::max(std::abs(c.x), std::abs(c.y)) < 0.5f + 0.6f;
  };
  auto under_table = [&](glm::vec2 c) {  // beyond the slump of the floor snow
    return std::max(std::abs(c.x), std::abs(c.y)) < 0.5f - 0.3f / std::tan(42.0f * kDeg) - texel;
  };
  const double top_lost = object_volume(maps, before, top) - object_volume(maps, depth, top);
  const double floor_gain = object_volume(maps, depth, floor, near_table) -
                            object_volume(maps, before, floor, near_table);
  const double under = object_volume(maps, depth, floor, under_table);
  float deepest_under = 0.0f;
  for (int j = 0; j < maps.grid.height; ++j) {
    for (int i = 0; i < maps.grid.width; ++i) {
      for (int l = 1; l < maps.layers && maps.has_surface(l, i, j); ++l) {
        const size_t k = maps.index(l, i, j);
        if (maps.object[k] == floor && under_table(maps.grid.center(i, j))) {
          deepest_under = std::max(deepest_under, depth[k]);
        }
      }
    }
  }
  std::printf(
      "table: %d passes (+%d routing), top gives %.4f m^3, floor next to it gains %.4f "
      "m^3, under %.5f m^3 (at most %.4f m deep)\n",
      r.iterations, r.route_passes, top_lost, floor_gain, under, deepest_under);
  EXPECT_GT(top_lost, 0.0);
  EXPECT_GT(floor_gain, 0.9 * top_lost);
  // Beyond the slump of the floor snow, the floor under the table stays all
  // but bare: the snow shed by the top piles up at the edge and spreads in
  // at the repose angle too, a few centimetres further at the corners.
  EXPECT_LT(deepest_under, 0.05f);
  EXPECT_LT(under, 0.01 * top_lost);
  // The top keeps its snow in the middle, and the edges are rounded.
  const int ci = maps.grid.width / 2;
  int edge = ci;
  while (maps.object[maps.index(0, edge - 1, ci)] == top) --edge;
  EXPECT_NEAR(depth[maps.index(0, ci, ci)], 0.3f, 1e-3f);
  EXPECT_LT(depth[maps.index(0, edge, ci)], 0.5f * 0.3f);
}

TEST(StabilizeScenes, StairTreadsHoldSnow) {
  REQUIRE_GL();
  const StairsDims dims;  // 6 steps, tread 0.3 m, riser 0.18 m, rising along +z
  const Scene scene = make_stairs_scene(dims);
  const SnowMaps maps = scene_maps(scene, 128);
  const int stairs = find_object(scene, "Stairs");
  std::vector<float> depth = snow_on_top(maps, 0.3f);
  const double before = snow_volume(maps, depth);
  const StabilizeResult r = stabilize(maps, depth, StabilizeSettings{});
  std::printf("stairs: %d passes (+%d routing)\n", r.iterations, r.route_passes);
  ASSERT_TRUE(r.converged);
  EXPECT_NEAR(snow_volume(maps, depth) + r.lost_volume, before, 1e-5 * before);
  // Along the middle of the flight: every tread keeps snow at its back, the
  // snow surface still steps up at every riser, nothing lies inside.
  const int i = maps.grid.width / 2;
  const float z0 = -dims.steps * dims.tread / 2;
  float last_top = -1.0f;
  // The top tread ends in a drop to the floor at its back: its middle.
  for (int step = 0; step < dims.steps; ++step) {
    const float back = z0 + (step + (step + 1 < dims.steps ? 0.8f : 0.5f)) * dims.tread;
    int j = 0;
    while (maps.grid.center(i, j).y < back) ++j;
    const size_t k = maps.index(0, i, j);
    ASSERT_EQ(maps.object[k], stairs);
    const float top = maps.ground[k] + depth[k];
    std::printf("tread %d: ground %.2f m, snow %.3f m\n", step, maps.ground[k], depth[k]);
    EXPECT_GT(depth[k], step + 1 < dims.steps ? 0.2f : 0.05f);
    if (step + 1 < dims.steps) {
      EXPECT_GT(top, last_top + 0.5f * dims.riser);
    }
    last_top = top;
  }
  const double inside = sum_where(maps, depth, [&](int l, int ii, int jj) {
    return l > 0 && maps.object[maps.index(l, ii, jj)] == stairs;
  });
  EXPECT_EQ(inside, 0.0);
}

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
      StabilizeSettings settings;
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
      // and the floor beside it come to rest.
      if (std::string(name) == "house") {
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
  StabilizeSettings settings;
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
}  // namespace snow
