// Where the stabilizer puts the snow (src/snow/stabilize.h,
// src/snow/deposit.h): routed snow poured as piles, snow creeping off an
// edge drained, snow pressed above its ceiling poured out, and the rest the
// snow reaches on analytic shapes (a table, a low shelf, a bowl, lean-to
// roofs) and builder scenes (a house, a table, stairs), on the CPU
// reference and on the GPU.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <tuple>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "scene/builder.h"
#include "snow/deposit.h"
#include "snow/maps.h"
#include "snow/stabilize.h"
#include "snow/stabilize_cpu.h"
#include "support/stabilize_maps.h"

namespace snow::test {
namespace {

// --- Analytic columns --------------------------------------------------------

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

// --- Piles (CPU reference) ---------------------------------------------------

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
  StabilizeSettings settings = loose_settings();
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

// Under a low ceiling, routed snow is poured as a pile that fills the gap up
// to the ceiling around its terminal (snow sliding off a tree's tiers into
// the low gap under them: metres of depth on one texel, squeezed out over a
// thousand passes).
TEST(StabilizeReference, RoutedSnowUnderACeilingFillsTheGap) {
  const SnowMaps maps = shelf_maps();  // 0.1 m gap under the shelf
  const std::vector<glm::vec4> cells = stabilize_cells(maps, loose_settings());
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

// Under a high ceiling (a roof 0.95 m over the floor, 1 cm texels), routed
// snow is poured as a cone, not left on its terminal as a spike that the
// relaxation would take as many passes to spread as it is texels high (snow
// creeping under an eave into a hollow there).
TEST(StabilizeReference, RoutedSnowUnderAHighCeilingIsPouredAsACone) {
  const float texel = 0.01f;
  const SnowMaps maps = make_maps(64, 64, texel, 4, [](float x, float z) {
    std::vector<Surface> s;
    if (x > 0.1f && x < 0.54f && z > 0.1f && z < 0.54f) {
      s.push_back({1.0f, kUp});
      s.push_back({0.95f, kDown});
    }
    s.push_back({0.0f, kUp});
    return s;
  });
  StabilizeSettings settings = loose_settings();
  settings.repose_jitter_deg = 0.0f;  // tan = 1
  const std::vector<glm::vec4> cells = stabilize_cells(maps, settings);
  const size_t under = maps.index(2, 32, 32);  // the floor under the roof's middle
  ASSERT_TRUE(maps.has_surface(2, 32, 32));
  ASSERT_NEAR(maps.ceiling[under], 0.95f, 1e-6f);
  // Cones 0.036 and 0.098 m high (V = pi h^3 / 3 on 1 cm texels).
  for (const auto& [metres, apex] : {std::make_pair(0.5f, 0.036f), std::make_pair(10.0f, 0.098f)}) {
    SCOPED_TRACE(metres);
    std::vector<float> depth(cells.size(), 0.0f), arrive(cells.size(), 0.0f);
    arrive[under] = metres;
    deposit_piles(cells.data(), depth.data(), arrive.data(), DepositGrid{64, 64, 4, texel});
    double sum = 0.0;
    int covered = 0;
    for (size_t k = 0; k < depth.size(); ++k) {
      sum += depth[k];
      covered += depth[k] > 0.0f;
    }
    std::printf("under the roof: %.3f m on the terminal, %d texels covered\n", depth[under],
                covered);
    EXPECT_NEAR(sum, metres, 1e-5 * metres);
    EXPECT_NEAR(depth[under], apex, 2 * texel);
    EXPECT_GT(covered, 3 * int(apex / texel) * int(apex / texel));
    for (int j = 0; j < 64; ++j) {
      for (int i = 0; i + 1 < 64; ++i) {
        const size_t a = maps.index(2, i, j), b = maps.index(2, i + 1, j);
        if (!maps.has_surface(2, i, j) || !maps.has_surface(2, i + 1, j)) continue;
        EXPECT_LE(std::abs(depth[a] - depth[b]), texel + 1e-5f) << i << ", " << j;
      }
    }
  }
}

// Maps of 512 rows and more pour their piles by bands of rows, the bands of
// a phase on several threads: the same bits as on one thread, where the
// bands' piles stay apart (poured in parallel) and where two of them meet
// (the phase undone and poured again serially), and the volume is exact.
// Every terminal is its own pile here (grouped, the two that meet would be
// one pile, in one band).
TEST(StabilizeReference, PilesPouredByBandsAreTheSameOnAnyThreads) {
  const int width = 24, height = 512;  // bands of 64 rows
  const float texel = 0.05f;
  const SnowMaps maps = make_maps(width, height, texel, 2, [](float, float) {
    return std::vector<Surface>{{0.0f, kUp}};
  });
  const std::vector<glm::vec4> cells = stabilize_cells(maps, loose_settings());
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
    EXPECT_EQ(deposit_piles(cells.data(), depth.data(), arrive.data(), terminals, grid, threads,
                            &stats, PileGrouping::Lone),
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

// Terminals whose piles overlap (a line of them, as where snow slides off an
// eave) are poured as one pile, the upper envelope of a cone at each: it
// covers each texel about once, where the piles poured one by one spread
// over each other again and again; the volume is exact, the pile at rest
// (no neighbour above another by more than distance * tan(repose)), as
// high as the piles poured one by one within 4 texels, and as long.
TEST(StabilizeReference, OverlappingPilesArePouredAsOne) {
  const float texel = 0.01f;
  const int width = 160, height = 90;
  const SnowMaps maps = make_maps(width, height, texel, 2, [](float, float) {
    return std::vector<Surface>{{0.0f, kUp}};
  });
  StabilizeSettings settings = loose_settings();
  settings.repose_jitter_deg = 0.0f;  // tan = 1
  const std::vector<glm::vec4> cells = stabilize_cells(maps, settings);
  const std::vector<float> lying = snow_on_top(maps, 0.05f);
  const DepositGrid grid{width, height, 2, texel};
  // 40 terminals 2 texels apart along the middle row, each with a lone cone
  // about 13 texels in radius.
  std::vector<float> arrive(lying.size(), 0.0f);
  std::vector<uint32_t> terminals;
  double poured = 0.0;
  for (int t = 0; t < 40; ++t) {
    const size_t k = maps.index(0, 40 + 2 * t, height / 2);
    arrive[k] = 20.0f;
    terminals.push_back(uint32_t(k));
    poured += arrive[k];
  }
  struct Pile {
    std::vector<float> depth;
    DepositStats stats;
    float peak = 0.0f;             // m over the lying snow
    int first = width, last = -1;  // columns of the middle row the pile reaches
  };
  const auto pour = [&](PileGrouping grouping) {
    Pile p;
    p.depth = lying;
    deposit_piles(cells.data(), p.depth.data(), arrive.data(), terminals, grid, 1, &p.stats,
                  grouping);
    double added = 0.0;
    for (size_t k = 0; k < p.depth.size(); ++k) added += double(p.depth[k]) - double(lying[k]);
    EXPECT_NEAR(added, poured, 1e-5 * poured);
    for (int i = 0; i < width; ++i) {
      const float d = p.depth[maps.index(0, i, height / 2)] - lying[maps.index(0, i, height / 2)];
      p.peak = std::max(p.peak, d);
      if (d > 0.0f) p.first = std::min(p.first, i), p.last = std::max(p.last, i);
    }
    return p;
  };
  const Pile one = pour(PileGrouping::Wide), each = pour(PileGrouping::Lone);
  std::printf(
      "one pile: %zu texels covered, %.3f m high, columns %d-%d; one by one: %zu, %.3f m, "
      "%d-%d\n",
      one.stats.covered, one.peak, one.first, one.last, each.stats.covered, each.peak, each.first,
      each.last);
  EXPECT_EQ(one.stats.groups, 1u);
  EXPECT_EQ(each.stats.groups, 0u);
  EXPECT_LT(one.stats.covered * 5, each.stats.covered);
  EXPECT_NEAR(one.peak, each.peak, 4 * texel);
  // One by one, the later piles spread over the earlier ones and the ridge
  // leans towards the last; as one, it lies even about the line (whose
  // middle is column 79), as long within 15 %.
  EXPECT_NEAR(one.first + one.last, 2 * 79, 2);
  EXPECT_NEAR(one.last - one.first, each.last - each.first, 0.15 * (each.last - each.first));
  for (int j = 0; j < height; ++j) {
    for (int i = 0; i + 1 < width; ++i) {
      const size_t a = maps.index(0, i, j), b = maps.index(0, i + 1, j);
      EXPECT_LE(std::abs(one.depth[a] - one.depth[b]), texel + 1e-5f) << i << ", " << j;
    }
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

// Loose snow creeping off the edges of a box, relaxed alone (`off`) and with
// a shortcut (`on`): both settle, the shortcut in under a third of the
// passes, to the same rest (volume within 0.1 %, every texel within 1 mm,
// no excess over 2e-4 m) with the mass exact. Returns both results.
std::pair<StabilizeResult, StabilizeResult> creep_off_a_box(const StabilizeSettings& off,
                                                            const StabilizeSettings& on) {
  const SnowMaps maps = box_on_plate_maps();
  const std::vector<float> start = snow_on_top(maps, 0.1f);
  const double fell = snow_volume(maps, start);
  std::vector<float> relaxed = start, settled = start;
  const StabilizeResult r0 = stabilize_cpu(maps, relaxed, off);
  const StabilizeResult r1 = stabilize_cpu(maps, settled, on);
  std::printf(
      "creeping off an edge: %d passes relaxed, %d with %d drains, %d creep routings; "
      "%.6f against %.6f m^3\n",
      r0.iterations, r1.iterations, r1.drains, r1.creep_routes, r0.volume, r1.volume);
  EXPECT_TRUE(r0.converged);
  EXPECT_TRUE(r1.converged);
  EXPECT_LT(3 * r1.iterations, r0.iterations);
  EXPECT_NEAR(r1.volume + r1.lost_volume, fell, 1e-9);
  EXPECT_NEAR(r1.volume, r0.volume, 1e-3 * r0.volume);
  EXPECT_LE(largest_excess(maps, settled, on, 1e-4f), 2e-4f);
  float difference = 0.0f;
  for (size_t k = 0; k < settled.size(); ++k) {
    difference = std::max(difference, std::abs(settled[k] - relaxed[k]));
  }
  EXPECT_LT(difference, 1e-3f);  // a tenth of a texel
  return {r0, r1};
}

TEST(StabilizeReference, SnowCreepingOffAnEdgeIsDrained) {
  StabilizeSettings off = loose_settings();
  off.route_creep = false;  // the drains alone
  off.drain_edges = false;
  StabilizeSettings on = off;
  on.drain_edges = true;
  const auto [r0, r1] = creep_off_a_box(off, on);
  EXPECT_EQ(r0.drains, 0);
  EXPECT_GE(r1.drains, 1);
  // The whole excess runs off in one drain, filling the room on its way.
  EXPECT_LE(r1.drains, 2);
}

// A drain's fill and spill (spill_excess) down a channel 1 cm wide: walls
// on both sides and uphill, the ground falling 5 mm per 1 cm texel (a
// slope of 0.5 under a repose slope of 1) to the void past its last texel,
// 10 cm of loose snow on its first texel, none elsewhere. That texel keeps
// 1 cm over its downhill neighbour's ground; the excess runs down, fills
// each texel on its way by 5 mm (up to its downhill neighbour's top plus
// one texel of repose slope), none on the last (snow there slides into the
// void), and the rest is lost there, mass exact. With a wall at the
// channel's end instead of the void, the path ends in a hollow: nothing
// moves (the relaxation spreads that snow).
TEST(StabilizeReference, DrainFillsTheRoomOnItsWayAndSpillsTheRest) {
  const int width = 9, height = 3;  // column 0 and rows 0 and 2 are walls
  const float texel = 0.01f, fall = 0.005f, snow = 0.1f;
  for (const bool open_end : {true, false}) {
    std::vector<glm::vec4> cells(size_t(width * height));
    std::vector<float> depth(cells.size(), 0.0f), lost(cells.size(), 0.0f), stable(cells.size());
    const int last = open_end ? width - 1 : width - 2;  // the channel's last texel
    for (int j = 0; j < height; ++j) {
      for (int i = 0; i < width; ++i) {
        const bool wall = j != 1 || i == 0 || i > last;
        const float ground = wall ? 1.0f : float(width - i) * fall;
        const size_t k = size_t(j * width + i);
        cells[k] = glm::vec4(ground, kCellOpenSky, 1.0f, float(kCellSurface));
        stable[k] = ground;  // bare texels keep their ground
      }
    }
    const size_t source = size_t(width + 1);
    depth[source] = snow;
    stable[source] = cells[source + 1].x + texel;  // the repose slope over its neighbour
    const std::vector<float> before = depth;
    const std::vector<uint32_t> changed =
        spill_excess(cells.data(), stable.data(), depth.data(), lost.data(),
                     DepositGrid{width, height, 1, texel}, 0.0f);
    double total = 0.0, lost_total = 0.0;
    for (size_t k = 0; k < depth.size(); ++k) {
      total += depth[k];
      lost_total += lost[k];
    }
    SCOPED_TRACE(open_end);
    EXPECT_NEAR(total + lost_total, snow, 1e-7);
    if (!open_end) {
      EXPECT_TRUE(changed.empty());
      EXPECT_EQ(depth, before);
      continue;
    }
    EXPECT_EQ(changed.size(), size_t(last - 1));  // the source and the texels it filled
    EXPECT_NEAR(depth[source], stable[source] - cells[source].x, 1e-6);
    for (int i = 2; i < last; ++i) EXPECT_NEAR(depth[size_t(width + i)], fall, 1e-6) << i;
    EXPECT_EQ(depth[size_t(width + last)], 0.0f);
    EXPECT_NEAR(lost[size_t(width + last)], snow - texel + fall - float(last - 2) * fall, 1e-6);
  }
}

// Creeping snow routed again (StabilizeSettings::route_creep) rests as the
// relaxation alone leaves it, in a fraction of the passes (drains off).
TEST(StabilizeReference, CreepingSnowIsRoutedDownItsWholePath) {
  StabilizeSettings off = loose_settings();
  off.drain_edges = false;
  off.route_creep = false;
  StabilizeSettings on = off;
  on.route_creep = true;
  const auto [r0, r1] = creep_off_a_box(off, on);
  EXPECT_EQ(r0.creep_routes, 0);
  EXPECT_GE(r1.creep_routes, 1);
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
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = 2000;
  const StabilizeResult r = stabilize_cpu(maps, depth, settings);
  std::printf("cellar: %d passes, %d pours, converged %d\n", r.iterations, r.pours,
              int(r.converged));
  EXPECT_TRUE(r.converged);
  EXPECT_GE(r.pours, 1);
  EXPECT_LT(r.iterations, 200);  // squeezed out by the passes alone: thousands
  float highest_over = -1.0f;
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ceiling[k] < 1.0f) {
      highest_over = std::max(highest_over, maps.ground[k] + depth[k] - maps.ceiling[k]);
    }
  }
  EXPECT_LE(highest_over, settings.tolerance);
  EXPECT_NEAR(snow_volume(maps, depth) + r.lost_volume, before, 1e-5 * before);
}

// A closed cavity: a slab 0.1 m over the floor, walled in on all sides, its
// gap exactly full (snow up to the ceiling's clearance) and 2 cm more on one
// texel in its middle, with no room anywhere.
SnowMaps closed_cavity_maps(int side, float texel) {
  return make_maps(side, side, texel, 3, [=](float x, float z) {
    const float edge = 1.5f * texel;  // one column of wall around
    if (x < edge || z < edge || x > side * texel - edge || z > side * texel - edge) {
      return std::vector<Surface>{{1.0f, kUp}};
    }
    return std::vector<Surface>{{0.15f, kUp}, {0.1f, kDown}, {0.0f, kUp}};
  });
}

std::vector<float> full_cavity_snow(const SnowMaps& maps, size_t pressed) {
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ground[k] == 0.0f) {
      depth[k] = maps.ceiling[k] - kCeilingClearance;
    }
  }
  depth[pressed] += 0.02f;
  return depth;
}

// Stabilizes `depth` (loose snow, on the CPU, at most `passes` passes):
// expects it to rest in fewer than `within`, nothing lost, the volume kept.
void expect_rests_keeping_mass(const SnowMaps& maps, std::vector<float>& depth, int passes,
                               int within) {
  const double before = snow_volume(maps, depth);
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = passes;
  const StabilizeResult r = stabilize_cpu(maps, depth, settings);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(r.iterations, within);
  EXPECT_EQ(r.lost_volume, 0.0);
  EXPECT_NEAR(snow_volume(maps, depth), before, 1e-6 * before);
}

// The relaxation squeezes the pressed snow into the full gaps around it,
// which press it back: no snow surface changes (every texel stays at its
// ceiling), so the stabilizer rests at its first check. Before, those
// squeezes counted as moves and the snow rocked between full neighbours for
// as many passes as it was given (1000 here; a toy car's underside at forced
// map sides).
TEST(StabilizeReference, PressedSnowInAClosedFullGapComesToRest) {
  const int side = 24;
  const SnowMaps maps = closed_cavity_maps(side, 0.05f);
  const size_t middle = maps.index(2, side / 2, side / 2);  // (layer 2: the floor)
  ASSERT_EQ(maps.ceiling[middle], 0.1f);
  std::vector<float> depth = full_cavity_snow(maps, middle);
  const std::vector<float> start = depth;
  expect_rests_keeping_mass(maps, depth, 1000, 100);
  for (size_t k = 0; k < depth.size(); ++k) {  // every surface as it was
    if (std::isnan(maps.ground[k]) || maps.ground[k] != 0.0f) continue;
    const float top = maps.ceiling[k] - kCeilingClearance;
    EXPECT_FLOAT_EQ(std::min(depth[k], top), std::min(start[k], top)) << k;
  }
}

// The snow of full_cavity_snow with 20 cm pressed over the middle texel of
// the cavity's floor, and a sliver of room (`sliver` m) left on every other.
std::vector<float> sliver_cavity_snow(const SnowMaps& maps, float sliver) {
  const size_t middle = maps.index(2, maps.grid.width / 2, maps.grid.height / 2);
  std::vector<float> depth = full_cavity_snow(maps, middle);
  depth[middle] += 0.18f;
  for (size_t k = 0; k < depth.size(); ++k) {
    if (k != middle && !std::isnan(maps.ground[k]) && maps.ground[k] == 0.0f) depth[k] -= sliver;
  }
  return depth;
}

// sliver_cavity_snow with slivers of twice the tolerance (moves into them
// are seen; half the over in all, so the over cannot all find room): the
// squeeze spreads the pressure until every texel is full, and rests.
// Before, a pressed texel gave its whole over to its neighbours at once, each
// of which gave it back the next pass, for ever (a toy car's underside at a
// forced map side).
TEST(StabilizeReference, PressedSnowBesideSliversOfRoomComesToRest) {
  const SnowMaps maps = closed_cavity_maps(24, 0.05f);
  std::vector<float> depth = sliver_cavity_snow(maps, 2.0f * loose_settings().tolerance);
  expect_rests_keeping_mass(maps, depth, 2000, 500);
}

// A cellar on a toy's scale: a slab 1 mm over the floor, on texels of
// 0.05 mm, so that a step's repose drop (texel * tan) is less than the
// ceiling's clearance. Its gap exactly full (snow up to the clearance), the
// open floor around it under snow whose top lies just under the slab's
// underside: above the gap's snow by more than a step's drop.
SnowMaps fine_cellar_maps() {
  return make_maps(48, 48, 5e-5f, 4, [](float x, float z) {
    std::vector<Surface> s;
    if (x > 0.4e-3f && x < 2e-3f && z > 0.4e-3f && z < 2e-3f) {
      s.push_back({1.5e-3f, kUp});
      s.push_back({1e-3f, kDown});
    }
    s.push_back({0.0f, kUp});
    return s;
  });
}

std::vector<float> full_fine_cellar_snow(const SnowMaps& maps) {
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ground[k] == 0.0f) {
      depth[k] = maps.ceiling[k] < 1.0f ? maps.ceiling[k] - kCeilingClearance
                                        : 1e-3f - 0.1f * kCeilingClearance;
    }
  }
  return depth;
}

// One relaxation pass alone (no routing).
StabilizeSettings one_relaxation_pass() {
  StabilizeSettings settings = loose_settings();
  settings.route_steep = false;
  settings.tolerance = 0.0f;
  settings.max_iterations = 1;
  return settings;
}

// No texel under the slab lies above its ceiling's clearance.
void expect_none_pressed_under_the_slab(const SnowMaps& maps, const std::vector<float>& depth) {
  float highest_over = -1.0f;
  for (size_t k = 0; k < depth.size(); ++k) {
    if (!std::isnan(maps.ground[k]) && maps.ceiling[k] < 1.0f) {
      const float cap = maps.ceiling[k] - kCeilingClearance;
      highest_over = std::max(highest_over, maps.ground[k] + depth[k] - cap);
    }
  }
  EXPECT_LE(highest_over, 1e-9f);
}

// A full gap has no room: snow around it, higher than its snow, slides none
// into it, and none is pressed there. Before, the slope pushed snow in over
// the ceiling, the squeeze and the pours of pressed snow sent it back out,
// and the slope pushed it in again: under a toy car at 2048 texels the passes
// never rested.
TEST(StabilizeReference, SlidingSnowTakesNoRoomAFullGapHasNot) {
  const SnowMaps maps = fine_cellar_maps();
  const std::vector<float> start = full_fine_cellar_snow(maps);
  std::vector<float> depth = start;
  const StabilizeResult r = stabilize_cpu(maps, depth, one_relaxation_pass());
  expect_none_pressed_under_the_slab(maps, depth);
  const double before = snow_volume(maps, start);  // (the map's border sheds into the void)
  EXPECT_NEAR(snow_volume(maps, depth) + r.lost_volume, before, 1e-6 * before);
}

// The snow pressed out of the cellar's full gap (its over, 2 cm on each of
// 1024 texels) poured by pour_pressed_snow's grouping, one pile from the
// whole gap, and one pile per texel: both hold the volume exactly, the one
// pile with none over a ceiling and growing over a fifth of the texels the
// lone piles cover or fewer (each texel's own pile crosses the gap again,
// until the call's budget of growth runs out).
TEST(StabilizeReference, PressedSnowOfOneGapIsPouredAsOnePile) {
  const SnowMaps maps = cellar_maps();
  const std::vector<glm::vec4> cells = stabilize_cells(maps, loose_settings());
  const std::vector<float> snow = cellar_snow(maps);
  std::vector<float> kept = snow, arrive(snow.size(), 0.0f);
  std::vector<uint32_t> pressed;
  double over = 0.0;
  for (size_t k = 0; k < snow.size(); ++k) {
    const float room = cells[k].y - kCeilingClearance - cells[k].x;
    if (std::isnan(maps.ground[k]) || !(snow[k] > room)) continue;
    kept[k] = room;
    arrive[k] = snow[k] - room;
    over += arrive[k];
    pressed.push_back(uint32_t(k));
  }
  ASSERT_EQ(pressed.size(), 32u * 32u);
  const DepositGrid grid{maps.grid.width, maps.grid.height, maps.layers, maps.grid.texel};
  DepositStats stats[2];
  int g = 0;
  for (const PileGrouping grouping : {PileGrouping::Pressed, PileGrouping::Lone}) {
    std::vector<float> depth = kept;
    deposit_piles(cells.data(), depth.data(), arrive.data(), pressed, grid, 1, &stats[g], grouping);
    double added = 0.0;
    float highest_over = -1.0f;
    for (size_t k = 0; k < depth.size(); ++k) {
      if (std::isnan(maps.ground[k])) continue;
      added += double(depth[k]) - double(kept[k]);
      highest_over = std::max(highest_over, maps.ground[k] + depth[k] - maps.ceiling[k]);
    }
    SCOPED_TRACE(g);
    EXPECT_NEAR(added, over, 1e-6 * over);
    // (One pile per texel runs out of the call's budget of growth, and the
    // last texels keep their snow.)
    if (grouping == PileGrouping::Pressed) {
      EXPECT_LE(highest_over, 0.0f);
    }
    ++g;
  }
  std::printf("pressed snow of one gap: one pile covers %zu texels, one per texel %zu\n",
              stats[0].covered, stats[1].covered);
  EXPECT_EQ(stats[0].groups, 1u);
  EXPECT_LT(5 * stats[0].covered, stats[1].covered);
}

// --- Shapes (CPU reference) --------------------------------------------------

TEST(StabilizeReference, TableEdgesRoundOff) {
  // A 1 m table top, 0.75 m high, 0.05 m thick, in a 3.2 m room; 0.3 m of snow
  // on every top surface.
  const float texel = 0.05f;
  const SnowMaps maps = make_maps(64, 64, texel, 4, table(1.6f, 1.6f, 0.5f, 0.75f, 0.05f));
  std::vector<float> depth = snow_on_top(maps, 0.3f);
  StabilizeSettings settings = loose_settings();
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
  // The snow shed by the top piles up on the floor at the table's edge (the
  // texels either side of it), above the 0.3 m that fell there. Under the
  // table, the floor snow slumps in at the repose angle from the pile at the
  // nearest edge (at most its height / tan(42 deg) + 1 texel in); the rest
  // stays bare.
  const int last = 41;  // the table's texels are 22..41 across
  ASSERT_TRUE(maps.ground[maps.index(0, last, j)] > 0.5f);
  ASSERT_FALSE(maps.ground[maps.index(0, last + 1, j)] > 0.5f);
  // The pile at the edge nearest to the floor texel (i, jj) under the table.
  const auto edge_pile = [&](int i, int jj) {
    const bool across = std::abs(i - 31.5f) >= std::abs(jj - 31.5f);
    const int at = across ? i : jj, in = at < 32 ? edge : last, out = at < 32 ? edge - 1 : last + 1;
    return across ? std::max(depth[maps.index(2, in, jj)], depth[maps.index(0, out, jj)])
                  : std::max(depth[maps.index(2, i, in)], depth[maps.index(0, i, out)]);
  };
  EXPECT_GT(edge_pile(edge, j), 0.3f);
  double under = 0.0;
  for (int jj = edge; jj <= last; ++jj) {
    for (int i = edge; i <= last; ++i) {
      ASSERT_TRUE(maps.has_surface(2, i, jj));
      const int in = std::min({i - edge, last - i, jj - edge, last - jj});  // texels
      const float reach = edge_pile(i, jj) / std::tan(42.0f * kDeg) + texel;
      if ((float(in) + 0.5f) * texel > reach) under += depth[maps.index(2, i, jj)];
    }
  }
  EXPECT_EQ(under, 0.0);
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
  const StabilizeResult r = stabilize_cpu(maps, depth, loose_settings());
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
  const StabilizeResult r = stabilize_cpu(maps, depth, loose_settings());
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
    const StabilizeResult r = stabilize_cpu(maps, depth, loose_settings());
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

// --- Piles: GPU against the CPU reference ------------------------------------

// The GPU stabilizer pours the same piles (on the CPU, from its readback):
// a spike on a snowy floor, routing and pouring only, within the backends'
// tolerance (support/stabilize_maps.h).
TEST(StabilizeGpu, PilesMatchReference) {
  REQUIRE_GL();
  const int side = 33, mid = 16;
  const SnowMaps maps = make_maps(side, side, 0.05f, 2, [](float x, float) {
    return std::vector<Surface>{{0.02f * x, kUp}};  // a gentle slope
  });
  std::vector<float> cpu = snow_on_top(maps, 0.2f);
  cpu[maps.index(0, mid, mid)] += 1.5f;
  std::vector<float> gpu = cpu;
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = 0;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GT(rc.routed_volume, 0.0);
  EXPECT_NEAR(rg.routed_volume, rc.routed_volume, 1e-6);
  EXPECT_LT(*std::max_element(cpu.begin(), cpu.end()), 0.2f + 0.3f);  // poured, no spike
  expect_agree(maps, gpu, cpu);
}

TEST(StabilizeGpu, DrainingMatchesReference) {
  REQUIRE_GL();
  // A plate large enough that much of it rests (tiles the passes skip) when
  // a drain runs: the routing uses the outflow textures as scratch, so the
  // next passes must compute every tile again.
  const SnowMaps maps = box_on_plate_maps(96);
  std::vector<float> cpu = snow_on_top(maps, 0.1f), gpu = cpu;
  const StabilizeSettings settings = loose_settings();
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GE(rc.drains, 1);
  EXPECT_EQ(rg.drains, rc.drains);
  EXPECT_EQ(rg.iterations, rc.iterations);
  expect_agree(maps, gpu, cpu);
}

TEST(StabilizeGpu, CreepRoutingMatchesReference) {
  REQUIRE_GL();
  const SnowMaps maps = box_on_plate_maps(96);
  std::vector<float> cpu = snow_on_top(maps, 0.1f), gpu = cpu;
  StabilizeSettings settings = loose_settings();
  settings.drain_edges = false;  // the creep routing alone
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GE(rc.creep_routes, 1);
  EXPECT_EQ(rg.creep_routes, rc.creep_routes);
  EXPECT_EQ(rg.iterations, rc.iterations);
  EXPECT_NEAR(rg.routed_volume, rc.routed_volume, 1e-3 * rc.routed_volume + 1e-9);
  expect_agree(maps, gpu, cpu);
}

// Stabilizes `snow` (loose, at most `passes` passes) on the GPU and the CPU:
// expects the GPU to rest in the CPU's passes, the two in agreement.
void expect_gpu_rests_as_cpu(const SnowMaps& maps, const std::vector<float>& snow, int passes) {
  std::vector<float> cpu = snow, gpu = snow;
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = passes;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_TRUE(rg.converged);
  EXPECT_EQ(rg.iterations, rc.iterations);
  expect_agree(maps, gpu, cpu);
}

TEST(StabilizeGpu, PressedSnowInAClosedFullGapComesToRest) {
  REQUIRE_GL();
  const int side = 24;
  const SnowMaps maps = closed_cavity_maps(side, 0.05f);
  expect_gpu_rests_as_cpu(maps, full_cavity_snow(maps, maps.index(2, side / 2, side / 2)), 1000);
}

TEST(StabilizeGpu, PressedSnowBesideSliversOfRoomComesToRest) {
  REQUIRE_GL();
  const SnowMaps maps = closed_cavity_maps(24, 0.05f);
  expect_gpu_rests_as_cpu(maps, sliver_cavity_snow(maps, 2.0f * loose_settings().tolerance), 2000);
}

TEST(StabilizeGpu, SlidingSnowTakesNoRoomAFullGapHasNot) {
  REQUIRE_GL();
  const SnowMaps maps = fine_cellar_maps();
  std::vector<float> gpu = full_fine_cellar_snow(maps), cpu = gpu;
  stabilize(maps, gpu, one_relaxation_pass());
  stabilize_cpu(maps, cpu, one_relaxation_pass());
  expect_none_pressed_under_the_slab(maps, gpu);
  expect_agree(maps, gpu, cpu);
}

TEST(StabilizeGpu, PressedSnowPoursMatchReference) {
  REQUIRE_GL();
  const SnowMaps maps = cellar_maps();
  std::vector<float> cpu = cellar_snow(maps), gpu = cpu;
  StabilizeSettings settings = loose_settings();
  settings.max_iterations = 2000;
  const StabilizeResult rc = stabilize_cpu(maps, cpu, settings);
  const StabilizeResult rg = stabilize(maps, gpu, settings);
  EXPECT_GE(rc.pours, 1);
  EXPECT_EQ(rg.pours, rc.pours);
  EXPECT_EQ(rg.iterations, rc.iterations);
  expect_agree(maps, gpu, cpu);
}

// --- Builder scenes (reference peel, GPU stabilizer) -------------------------

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
  run.result = stabilize(run.maps, run.after, loose_settings());
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
  const StabilizeResult r = stabilize(maps, depth, loose_settings());
  ASSERT_TRUE(r.converged);
  const float texel = maps.grid.texel;
  auto near_table = [&](glm::vec2 c) {  // outside and under its edges
    return std::max(std::abs(c.x), std::abs(c.y)) < 0.5f + 0.6f;
  };
  // The snow shed by the top piles up on the floor along its edges: per row
  // of texels, the deepest floor snow within a texel of the edges x = -0.5
  // and x = 0.5 m, and per column those of z = -0.5 and 0.5 m.
  const int w = maps.grid.width, h = maps.grid.height;
  std::vector<float> row_pile(2 * size_t(h), 0.0f), column_pile(2 * size_t(w), 0.0f);
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      const glm::vec2 c = maps.grid.center(i, j);
      for (int l = 0; l < maps.layers && maps.has_surface(l, i, j); ++l) {
        const float d = depth[maps.index(l, i, j)];
        if (maps.object[maps.index(l, i, j)] != floor) continue;
        if (std::abs(std::abs(c.x) - 0.5f) < texel && std::abs(c.y) < 0.5f) {
          float& pile = row_pile[2 * size_t(j) + (c.x > 0.0f)];
          pile = std::max(pile, d);
        }
        if (std::abs(std::abs(c.y) - 0.5f) < texel && std::abs(c.x) < 0.5f) {
          float& pile = column_pile[2 * size_t(i) + (c.y > 0.0f)];
          pile = std::max(pile, d);
        }
      }
    }
  }
  // Under the table, beyond the slump of the floor snow at the repose angle
  // from the pile at the nearest edge (its height / tan(42 deg) + 1 texel).
  auto under_table = [&](glm::vec2 c) {
    const int i = std::clamp(int((c.x - maps.grid.origin.x) / texel), 0, w - 1);
    const int j = std::clamp(int((c.y - maps.grid.origin.y) / texel), 0, h - 1);
    const float pile = std::abs(c.x) >= std::abs(c.y) ? row_pile[2 * size_t(j) + (c.x > 0.0f)]
                                                      : column_pile[2 * size_t(i) + (c.y > 0.0f)];
    return std::max(std::abs(c.x), std::abs(c.y)) < 0.5f - pile / std::tan(42.0f * kDeg) - texel;
  };
  const double top_lost = object_volume(maps, before, top) - object_volume(maps, depth, top);
  const double floor_gain = object_volume(maps, depth, floor, near_table) -
                            object_volume(maps, before, floor, near_table);
  const double under = object_volume(maps, depth, floor, under_table);
  float deepest_under = 0.0f;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      for (int l = 1; l < maps.layers && maps.has_surface(l, i, j); ++l) {
        const size_t k = maps.index(l, i, j);
        if (maps.object[k] == floor && under_table(maps.grid.center(i, j))) {
          deepest_under = std::max(deepest_under, depth[k]);
        }
      }
    }
  }
  const float highest_pile = std::max(*std::max_element(row_pile.begin(), row_pile.end()),
                                      *std::max_element(column_pile.begin(), column_pile.end()));
  std::printf(
      "table: %d passes (+%d routing), top gives %.4f m^3, floor next to it gains %.4f "
      "m^3, under %.5f m^3 (at most %.4f m deep); edge piles up to %.3f m\n",
      r.iterations, r.route_passes, top_lost, floor_gain, under, deepest_under, highest_pile);
  EXPECT_GT(top_lost, 0.0);
  EXPECT_GT(floor_gain, 0.9 * top_lost);
  EXPECT_GT(highest_pile, 0.3f);
  // Beyond the slump, the floor under the table stays all but bare.
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
  const StabilizeResult r = stabilize(maps, depth, loose_settings());
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

}  // namespace
}  // namespace snow::test
