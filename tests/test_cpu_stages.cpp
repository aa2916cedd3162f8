// The CPU parts of the stages (snow_cpu) on their own: this test links
// neither GL nor the stages' GL passes, so it also shows that they build
// without GL. A table on a floor: the CPU peel, the ray-cast coverage and
// the CPU stabilizer keep the snow off the floor under the table and
// conserve its mass.
#include <gtest/gtest.h>

#include <cmath>

#include "scene/builder.h"
#include "snow/coverage.h"
#include "snow/peel.h"
#include "snow/reference/coverage_ref.h"
#include "snow/reference/peel_ref.h"
#include "snow/stabilize_cpu.h"

namespace snow {
namespace {

TEST(CpuStages, TableSnowStaysOffTheFloorUnderItAndMassIsConserved) {
  const Scene scene = make_table_scene(0.75f, 1.0f, 4.0f);
  PeelSettings peel;
  peel.max_side = 64;
  const MapGrid grid = make_grid(scene.bounds, peel);
  const SnowMaps maps = reference::peel_layers(scene, grid, peel.layers);
  CoverageSettings coverage;
  coverage.directions = 16;
  const std::vector<float> p = reference::compute_coverage(scene, maps, fall_directions(coverage));

  // The floor's texel under the table's centre sees no sky; the open floor does.
  const size_t texels = maps.grid.texels();
  const size_t centre =
      size_t(maps.grid.height / 2) * size_t(maps.grid.width) + size_t(maps.grid.width / 2);
  const size_t corner = size_t(2) * size_t(maps.grid.width) + 2;
  ASSERT_GE(maps.layers, 2);
  EXPECT_NEAR(maps.ground[centre], 0.75f, 1e-3f);           // the table top
  EXPECT_NEAR(maps.ground[texels + centre], 0.70f, 1e-3f);  // its underside's floor is lower
  EXPECT_FLOAT_EQ(p[centre], 1.0f);
  EXPECT_FLOAT_EQ(p[corner], 1.0f);
  const size_t under = texels * size_t(maps.layers - 1) + centre;  // the floor, lowest layer
  EXPECT_NEAR(maps.ground[under], 0.0f, 1e-3f);
  EXPECT_FLOAT_EQ(p[under], 0.0f);

  StabilizeSettings stabilize;
  CpuStabilizer stabilizer(maps, stabilize);
  stabilizer.set_depth(std::vector<float>(p.size(), 0.0f));
  stabilizer.add_snow(p, 0.3f);
  const double fallen = snow_volume(maps, [&] {
    std::vector<float> d(p.size());
    for (size_t k = 0; k < p.size(); ++k) d[k] = std::isnan(maps.ground[k]) ? 0.0f : 0.3f * p[k];
    return d;
  }());
  const StabilizeResult r = stabilizer.run();
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.volume + stabilizer.lost_volume(), fallen, 1e-4 * fallen);
  EXPECT_LT(stabilizer.depth()[under], 0.01f);  // at most what slid off the table's edge
}

}  // namespace
}  // namespace snow
