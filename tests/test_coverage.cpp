// Tests of stage 2 (src/snow/coverage.h): fall directions, GPU coverage on
// canned scenes (soft table edges, closed box, wind), against the CPU
// ray-cast reference (src/snow/reference/coverage_ref.h).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <random>
#include <string>

#include "core/error.h"
#include "gl/context.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "snow/bvh.h"
#include "snow/coverage.h"
#include "snow/peel.h"
#include "snow/reference/coverage_ref.h"
#include "support/gl_context.h"

namespace snow {
namespace {

constexpr double kPi = 3.14159265358979323846;

SnowMaps peel(const Scene& scene, int side, int layers = 6) {
  PeelSettings s;
  s.max_side = side;
  s.layers = layers;
  return peel_layers(scene, s, plan::current_gl());
}

glm::ivec2 texel_at(const MapGrid& g, float x, float z) {
  return glm::ivec2(int(std::floor((x - g.origin.x) / g.texel)),
                    int(std::floor((z - g.origin.y) / g.texel)));
}

// Coverage of the lowest surface of column (i, j) lying within 1 cm of
// height y (the floor under a table is layer 2, elsewhere layer 0).
float coverage_at_height(const SnowMaps& maps, const std::vector<float>& cov, int i, int j,
                         float y) {
  for (int l = 0; l < maps.layers; ++l) {
    const size_t k = maps.index(l, i, j);
    if (!std::isnan(maps.ground[k]) && std::abs(maps.ground[k] - y) < 0.01f) return cov[k];
  }
  ADD_FAILURE() << "no surface at y = " << y << " in column " << i << ", " << j;
  return -1.0f;
}

struct Difference {
  double mean = 0;
  float max = 0;
  size_t count = 0;
};

Difference compare(const SnowMaps& maps, const std::vector<float>& a, const std::vector<float>& b) {
  Difference d;
  for (size_t k = 0; k < a.size(); ++k) {
    if (std::isnan(maps.ground[k])) {
      EXPECT_EQ(a[k], 0.0f);
      EXPECT_EQ(b[k], 0.0f);
      continue;
    }
    const float e = std::abs(a[k] - b[k]);
    d.mean += e;
    d.max = std::max(d.max, e);
    ++d.count;
  }
  if (d.count) d.mean /= double(d.count);
  return d;
}

// Coverage by `method` (the renderer must take it), and how it differs from
// the reference's.
std::pair<std::vector<float>, Difference> coverage_by(CoverageRenderer& renderer,
                                                      const SnowMaps& maps, CoverageSettings s,
                                                      const char* method, CoverageMethod expected,
                                                      const std::vector<float>& reference,
                                                      const char* scene) {
  s.method = method;
  std::vector<float> coverage = renderer.compute(maps, s);
  EXPECT_EQ(renderer.timings().method, expected) << method;
  const Difference d = compare(maps, coverage, reference);
  std::printf("%-14s %-15s mean |coverage - reference| %.5f, max %.3f over %zu layer texels\n",
              scene, method, d.mean, d.max, d.count);
  return {std::move(coverage), d};
}

// --- Directions ---------------------------------------------------------------

TEST(FallDirections, UnitDownwardInsideTheCone) {
  CoverageSettings s;
  const std::vector<glm::vec3> dirs = fall_directions(s);
  ASSERT_EQ(dirs.size(), 64u);
  const double cos_max = std::cos(15.0 * kPi / 180.0);
  int inner = 0;
  for (const glm::vec3& d : dirs) {
    EXPECT_NEAR(glm::length(d), 1.0f, 1e-6);
    EXPECT_LT(d.y, 0.0f);
    EXPECT_GE(-d.y, cos_max - 1e-6);  // no wind: the cone is around -Y
    inner += -d.y > std::cos(7.5 * kPi / 180.0);
  }
  // Uniform in solid angle: the inner half-angle cone holds about
  // (1 - cos 7.5) / (1 - cos 15) = 25.1 % of the directions (stratified: exactly +-1).
  EXPECT_NEAR(inner, 16, 1);
  // Azimuths spread all around: the mean direction is close to -Y.
  glm::dvec3 mean(0);
  for (const glm::vec3& d : dirs) mean += glm::dvec3(d);
  mean = glm::normalize(mean);
  EXPECT_GT(-mean.y, std::cos(1.0 * kPi / 180.0));
}

TEST(FallDirections, WindTiltsTheMeanDownwind) {
  CoverageSettings s;
  s.wind = glm::vec2(0.5f, 0.0f);  // 0.5 m/s along +x, fall 1 m/s: tilt atan(0.5) = 26.57 deg
  const glm::vec3 m = mean_fall_direction(s);
  EXPECT_NEAR(std::atan2(m.x, -m.y), std::atan(0.5), 1e-6);
  EXPECT_NEAR(m.z, 0.0f, 1e-7);
  const std::vector<glm::vec3> dirs = fall_directions(s);
  glm::dvec3 mean(0);
  for (const glm::vec3& d : dirs) {
    EXPECT_GE(glm::dot(d, m), std::cos(15.0 * kPi / 180.0) - 1e-6);
    EXPECT_GT(d.x, 0.0f);  // every flake drifts downwind (tilt > flutter)
    mean += glm::dvec3(d);
  }
  mean = glm::normalize(mean);
  EXPECT_NEAR(std::atan2(mean.x, -mean.y), std::atan(0.5), 0.01);
}

// A storm's wind (10 m/s against a 1 m/s fall: atan 10 = 84 degrees) is
// taken, its tilt capped at kMaxFallAngleDeg - flutter (75 - 15 = 60
// degrees), along the wind; a light one keeps its atan tilt.
TEST(FallDirections, StrongWindIsTakenWithItsTiltCapped) {
  CoverageSettings s;
  s.wind = glm::vec2(0.0f, 10.0f);
  const glm::vec3 m = mean_fall_direction(s);
  EXPECT_NEAR(std::atan2(m.z, -m.y), 60.0 * kPi / 180.0, 1e-6);
  EXPECT_NEAR(m.x, 0.0f, 1e-7);
  for (const glm::vec3& d : fall_directions(s)) {
    EXPECT_GE(-d.y,
              std::cos(kMaxFallAngleDeg * kPi / 180.0) - 1e-6);  // 15 degrees above the horizon
  }
  s.wind = glm::vec2(0.0f, 1.0f);
  EXPECT_NEAR(std::atan2(mean_fall_direction(s).z, -mean_fall_direction(s).y), kPi / 4.0, 1e-6);
}

TEST(FallDirections, SameSeedSameBitsDifferentSeedDifferentJitter) {
  CoverageSettings a;
  CoverageSettings b;
  const auto da = fall_directions(a), db = fall_directions(b);
  ASSERT_EQ(da.size(), db.size());
  EXPECT_EQ(std::memcmp(da.data(), db.data(), da.size() * sizeof(glm::vec3)), 0);
  const auto ja = shadow_origin_jitter(a), jb = shadow_origin_jitter(b);
  EXPECT_EQ(std::memcmp(ja.data(), jb.data(), ja.size() * sizeof(glm::vec2)), 0);
  b.seed = 2;
  const auto dc = fall_directions(b);
  const auto jc = shadow_origin_jitter(b);
  int differ = 0;
  for (size_t k = 0; k < da.size(); ++k) differ += da[k] != dc[k];
  EXPECT_EQ(differ, int(da.size()));
  differ = 0;
  for (size_t k = 0; k < ja.size(); ++k) {
    differ += ja[k] != jc[k];
    EXPECT_GE(jc[k].x, 0.0f);
    EXPECT_LT(jc[k].x, 1.0f);
    EXPECT_GE(jc[k].y, 0.0f);
    EXPECT_LT(jc[k].y, 1.0f);
  }
  EXPECT_EQ(differ, int(ja.size()));
}

TEST(FallDirections, RejectsBadSettings) {
  CoverageSettings s;
  s.directions = 0;
  EXPECT_THROW(fall_directions(s), InputError);
  s = {};
  s.flutter_deg = 70;
  EXPECT_THROW(fall_directions(s), InputError);
  s = {};
  s.fall_speed = 0;
  EXPECT_THROW(fall_directions(s), InputError);
  s = {};
  s.wind = glm::vec2(26.0f, 0.0f);  // over a storm's 25 m/s
  try {
    fall_directions(s);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("wind of 26 m/s is over the 25 m/s"), std::string::npos)
        << e.what();
  }
  s = {};
  s.wind = glm::vec2(std::nanf(""), 0.0f);
  EXPECT_THROW(fall_directions(s), InputError);
}

// --- Coverage on canned scenes ------------------------------------------------

TEST(Coverage, OpenPlaneIsFullyCovered) {
  REQUIRE_GL();
  const Scene scene = make_open_plane(10.0f);
  const SnowMaps maps = peel(scene, 128);
  const std::vector<float> cov = compute_coverage(scene, maps, {}, plan::current_gl());
  ASSERT_EQ(cov.size(), maps.ground.size());
  size_t plane = 0;
  float lowest = 1.0f;
  for (int j = 0; j < maps.grid.height; ++j) {
    for (int i = 0; i < maps.grid.width; ++i) {
      const size_t k = maps.index(0, i, j);
      if (std::isnan(maps.ground[k])) {
        EXPECT_EQ(cov[k], 0.0f);
        continue;
      }
      const glm::vec2 c = maps.grid.center(i, j);
      if (std::max(std::abs(c.x), std::abs(c.y)) > 5.0f - 2 * maps.grid.texel) continue;
      lowest = std::min(lowest, cov[k]);
      ++plane;
    }
  }
  EXPECT_GT(plane, 10000u);
  EXPECT_GT(lowest, 0.99f);
}

TEST(Coverage, TableShadowsTheFloorWithSoftEdges) {
  REQUIRE_GL();
  const float h = 0.75f;  // top of the table
  const Scene scene = make_table_scene(h, 1.0f, 4.0f);
  const SnowMaps maps = peel(scene, 160);
  CoverageSettings s;
  const std::vector<float> cov = compute_coverage(scene, maps, s, plan::current_gl());
  const MapGrid& g = maps.grid;
  // Under the middle of the table.
  const glm::ivec2 mid = texel_at(g, 0.0f, 0.0f);
  EXPECT_LT(coverage_at_height(maps, cov, mid.x, mid.y, 0.0f), 0.05f);
  // The table top itself is in full sky.
  EXPECT_GT(cov[maps.index(0, mid.x, mid.y)], 0.99f);
  // Across the edge x = 0.5 along z = 0 (between the legs): dark more than
  // H tan(flutter) inside, bright more than that outside, within 2 texels.
  const float reach = h * std::tan(15.0f * float(kPi) / 180.0f) + 2 * g.texel;
  const glm::ivec2 row = texel_at(g, 0.0f, 0.0f);
  int inside = 0, outside = 0;
  for (int i = 0; i < g.width; ++i) {
    const float x = g.center(i, row.y).x;
    if (x > 0.0f && x < 0.5f - reach) {
      EXPECT_LT(coverage_at_height(maps, cov, i, row.y, 0.0f), 0.1f) << "x = " << x;
      ++inside;
    }
    if (x > 0.5f + reach && x < 1.9f) {
      EXPECT_GT(coverage_at_height(maps, cov, i, row.y, 0.0f), 0.9f) << "x = " << x;
      ++outside;
    }
  }
  EXPECT_GT(inside, 5);
  EXPECT_GT(outside, 20);
  // The penumbra is really soft: some floor texel at the edge is partly lit.
  const glm::ivec2 edge = texel_at(g, 0.5f, 0.0f);
  const float p = coverage_at_height(maps, cov, edge.x, edge.y, 0.0f);
  EXPECT_GT(p, 0.2f);
  EXPECT_LT(p, 0.8f);
}

TEST(Coverage, ClosedBoxFloorGetsNoSnow) {
  REQUIRE_GL();
  ClosedBoxDims dims;  // 1 m cube, 10 cm walls
  const Scene scene = make_closed_box_scene(dims);
  const SnowMaps maps = peel(scene, 128);
  CoverageSettings s;
  s.wind = glm::vec2(0.3f, 0.2f);
  const std::vector<float> cov = compute_coverage(scene, maps, s, plan::current_gl());
  const MapGrid& g = maps.grid;
  size_t interior = 0;
  for (int j = 0; j < g.height; ++j) {
    for (int i = 0; i < g.width; ++i) {
      const glm::vec2 c = g.center(i, j);
      if (std::max(std::abs(c.x), std::abs(c.y)) >= 0.5f) continue;
      for (int l = 0; l < maps.layers; ++l) {
        const size_t k = maps.index(l, i, j);
        if (std::isnan(maps.ground[k])) break;
        if (l == 0) {
          EXPECT_GT(cov[k], 0.99f);  // the lid's top
        } else {
          EXPECT_EQ(cov[k], 0.0f) << "layer " << l << " y " << maps.ground[k];
          ++interior;
        }
      }
    }
  }
  EXPECT_GT(interior, 1000u);
}

// A surface modelled as two sheets (a cloth's two sides, a cushion's cover
// over its filling, a bridge laid just under a fold) takes the snow once:
// the sheet under another, whether millimetres under it (sealed: thinner
// than the shadow maps' bias, which would light it) or within the peel's
// rounding of it (a second sheet, reference::second_sheet), gets none, as
// the reference's rays find. Before, the lower sheet got the full fall too,
// pressed out of its gap onto the top sheet: twice the snow.
TEST(Coverage, DoubleSheetedSurfaceTakesTheSnowOnce) {
  REQUIRE_GL();
  const float top = 0.5f, gap = 2e-3f;  // metres
  SceneBuilder b;
  b.add_plane("Floor", 0.0f, {-1.5f, -1.5f}, {1.5f, 1.5f});
  b.add_plane("Cover", top, {-0.5f, -0.5f}, {0.5f, 0.5f});
  b.add_plane("Filling", top - gap, {-0.5f, -0.5f}, {0.5f, 0.5f});
  const Scene scene = b.build();
  SnowMaps sealed = peel(scene, 160);
  // The same maps with the lower sheet within the peel's rounding of the
  // cover (the peel itself merges sheets closer than its merge distance).
  SnowMaps second = sealed;
  const MapGrid& g = sealed.grid;
  std::vector<glm::ivec2> inside;  // the columns 2 texels or more inside the sheets
  for (int j = 0; j < g.height; ++j) {
    for (int i = 0; i < g.width; ++i) {
      const glm::vec2 c = g.center(i, j);
      if (std::max(std::abs(c.x), std::abs(c.y)) > 0.5f - 2 * g.texel) continue;
      inside.push_back({i, j});
      ASSERT_NEAR(sealed.ground[sealed.index(1, i, j)], top - gap, 1e-5f);  // two sheets
      second.ground[sealed.index(1, i, j)] = top - 5e-5f;
      second.ceiling[sealed.index(2, i, j)] = top - 5e-5f;
    }
  }
  ASSERT_GT(inside.size(), 1000u);
  for (const SnowMaps* maps : {&sealed, &second}) {
    SCOPED_TRACE(maps == &sealed ? "sealed" : "second sheet");
    const std::vector<float> cov = compute_coverage(scene, *maps, {}, plan::current_gl());
    const std::vector<float> rays =
        reference::compute_coverage(scene, *maps, fall_directions(CoverageSettings{}));
    for (const glm::ivec2& c : inside) {
      EXPECT_GT(cov[maps->index(0, c.x, c.y)], 0.99f);
      EXPECT_EQ(cov[maps->index(1, c.x, c.y)], 0.0f) << "column " << c.x << ", " << c.y;
      EXPECT_EQ(rays[maps->index(1, c.x, c.y)], 0.0f) << "column " << c.x << ", " << c.y;
    }
  }
}

// Where coverage along z (at x = 0, floor layer 0, z from the wall's face
// outwards) first rises to 0.5, interpolated; metres from the wall's centre.
float half_coverage_distance(const SnowMaps& maps, const std::vector<float>& cov, float start) {
  const MapGrid& g = maps.grid;
  const int i = texel_at(g, 0.0f, 0.0f).x;
  float prev_z = 0, prev_p = 0;
  bool have_prev = false;
  for (int j = 0; j < g.height; ++j) {
    const float z = g.center(i, j).y;
    if (z < start) continue;
    const size_t k = maps.index(0, i, j);
    if (std::isnan(maps.ground[k]) || maps.ground[k] > 0.01f) continue;
    const float p = cov[k];
    if (p >= 0.5f) {
      if (!have_prev) return z;
      return prev_z + (z - prev_z) * (0.5f - prev_p) / (p - prev_p);
    }
    prev_z = z;
    prev_p = p;
    have_prev = true;
  }
  return NAN;
}

TEST(Coverage, WindMovesTheWallsShadowDownwind) {
  REQUIRE_GL();
  WallDims dims;  // 2 m high, 6 m long along x, 0.2 m thick, on a 10 m floor
  const Scene scene = make_wall_scene(dims);
  const SnowMaps maps = peel(scene, 256);
  const float face = 0.5f * dims.wall_thickness;
  CoverageSettings calm;
  const std::vector<float> cov_calm = compute_coverage(scene, maps, calm, plan::current_gl());
  CoverageSettings windy;
  windy.wind = glm::vec2(0.0f, 0.5f);  // along +z: tilt atan(0.5)
  const std::vector<float> cov_wind = compute_coverage(scene, maps, windy, plan::current_gl());
  const float z_calm = half_coverage_distance(maps, cov_calm, face);
  const float z_wind = half_coverage_distance(maps, cov_wind, face);
  const float expected = dims.wall_height * 0.5f;  // H tan(tilt) = 2 * 0.5
  EXPECT_NEAR(z_wind - z_calm, expected, 2 * maps.grid.texel)
      << "calm " << z_calm << " windy " << z_wind;
  EXPECT_NEAR(z_wind - face, expected, 2 * maps.grid.texel);
  // Upwind (-z) every direction comes from away from the wall: fully covered
  // two texels from its face.
  const MapGrid& g = maps.grid;
  const glm::ivec2 up = texel_at(g, 0.0f, -face - 2.5f * g.texel);
  EXPECT_GT(cov_wind[maps.index(0, up.x, up.y)], 0.99f);
}

// Canned scenes with a wind each, for the comparisons with the reference.
struct Case {
  const char* name;
  Scene scene;
  glm::vec2 wind;
};

std::vector<Case> canned_cases() {
  std::vector<Case> cases;
  cases.push_back({"open plane", make_open_plane(10.0f), {0.0f, 0.0f}});
  cases.push_back({"table", make_table_scene(0.75f, 1.0f, 4.0f), {0.0f, 0.0f}});
  cases.push_back({"table in wind", make_table_scene(0.75f, 1.0f, 4.0f), {0.4f, -0.3f}});
  cases.push_back({"closed box", make_closed_box_scene(1.0f), {0.0f, 0.0f}});
  cases.push_back({"wall in wind", make_wall_scene(2.0f, 6.0f, 10.0f), {0.0f, 0.5f}});
  cases.push_back({"house", make_house_scene(45.0f, 0.5f), {0.3f, 0.0f}});
  cases.push_back({"stairs", make_stairs_scene(), {0.0f, 0.2f}});
  return cases;
}

// The shadow-map method, drawn and counted by GL or on the CPU cores, agrees
// with the reference; the two differ only where a shadow texel's centre
// lies on a triangle's edge (GL's fill rule against the CPU's inclusive
// one) or a height on the bias's edge.
TEST(Coverage, ShadowMapsMatchRayCastReference) {
  REQUIRE_GL();
  for (const Case& c : canned_cases()) {
    SCOPED_TRACE(c.name);
    const SnowMaps maps = peel(c.scene, 128);
    CoverageSettings s;
    s.wind = c.wind;
    const std::vector<float> cpu = reference::compute_coverage(c.scene, maps, fall_directions(s));
    CoverageRenderer renderer(c.scene, plan::current_gl());
    std::vector<float> by_gl;
    for (const auto& [method, expected] :
         {std::make_pair("shadow-maps", CoverageMethod::ShadowMaps),
          std::make_pair("cpu-shadow-maps", CoverageMethod::CpuShadowMaps)}) {
      const auto [maps_coverage, d] = coverage_by(renderer, maps, s, method, expected, cpu, c.name);
      EXPECT_GT(d.count, 1000u);
      EXPECT_LT(d.mean, 0.02);
      EXPECT_LT(d.max, 0.1f);
      if (by_gl.empty()) {
        by_gl = maps_coverage;
      } else {
        const Difference between = compare(maps, maps_coverage, by_gl);
        std::printf("%-14s mean |CPU maps - GL maps| %.5f, max %.3f\n", c.name, between.mean,
                    between.max);
        EXPECT_LT(between.mean, 0.002);
      }
    }
  }
}

// Casting every line as a ray (no shadow maps), on the GPU or the CPU, is
// the reference's method, and its sky cull then ignores only what the
// reference ignores (surfaces within 0.1 mm above the receiver, not the
// shadow maps' quarter texel): not one ray differs. With the maps' bias in
// the cull, one stairs texel differed by a ray.
TEST(Coverage, RaysMatchTheRayCastReference) {
  REQUIRE_GL();
  for (const Case& c : canned_cases()) {
    SCOPED_TRACE(c.name);
    const SnowMaps maps = peel(c.scene, 64);
    CoverageSettings s;
    s.wind = c.wind;
    const std::vector<float> cpu = reference::compute_coverage(c.scene, maps, fall_directions(s));
    CoverageRenderer renderer(c.scene, plan::current_gl());
    for (const auto& [method, expected] : {std::make_pair("rays", CoverageMethod::GpuRays),
                                           std::make_pair("cpu-rays", CoverageMethod::CpuRays)}) {
      const Difference d = coverage_by(renderer, maps, s, method, expected, cpu, c.name).second;
      EXPECT_GT(d.count, 1000u);
      EXPECT_LT(d.max, 0.5f / 64.0f);
    }
  }
}

// Thin shells (a toy car's body panels, a fraction of a millimetre apart)
// put surfaces just above a receiver: the sky cull must judge them as the
// reference's rays do. A cone bound of y + eps + cot d (rather than y +
// max(eps, cot d)) let grazing lines hit triangles it called harmless:
// texels then differed by up to 0.2.
TEST(Coverage, CpuRaysMatchTheReferenceOnAToyCar) {
  const std::filesystem::path car =
      std::filesystem::path(SNOW_SHARED_SCENES) / "khronos/ToyCar/ToyCar.gltf";
  if (!std::filesystem::exists(car)) GTEST_SKIP() << "../shared/scenes is absent";
  REQUIRE_GL();
  const Scene scene = load_scene(car);
  const SnowMaps maps = peel(scene, 256, 8);
  CoverageSettings s;
  s.method = "cpu-rays";
  const std::vector<float> rays = compute_coverage(scene, maps, s, plan::current_gl());
  const std::vector<float> ref = reference::compute_coverage(scene, maps, fall_directions(s));
  const Difference d = compare(maps, rays, ref);
  std::printf("ToyCar at 256: max |rays - reference| %.3f over %zu layer texels\n", d.max, d.count);
  EXPECT_GT(d.count, 10000u);
  EXPECT_LT(d.max, 0.5f / 64.0f);
}

// The automatic method casts rays where the receivers are few against the
// triangles drawn per shadow map, on the CPU where GL runs in software.
TEST(Coverage, AutomaticMethodCastsRaysWhereReceiversAreFew) {
  CoverageSettings s;  // auto
  CoverageWork car;    // ToyCar at 16 texels
  car.triangles = 108936;
  car.shadow_texels = 15 * 16;
  car.receivers = 84;
  CoverageWork building;  // building-small-a at 110 texels
  building.triangles = 440;
  building.shadow_texels = 133 * 134;
  building.receivers = 35106;
  EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::GpuRays);
  EXPECT_EQ(choose_coverage_method(s, building), CoverageMethod::ShadowMaps);
  // In software, the CPU cores draw and count the building's small maps
  // (llvmpipe spends about 1 ms per direction on its passes).
  car.software = building.software = true;
  EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::CpuRays);
  EXPECT_EQ(choose_coverage_method(s, building), CoverageMethod::CpuShadowMaps);
  // Also where the receivers are many: the CPU counts them faster than
  // llvmpipe's passes (the courtyard at 1024, SheenChair at 1024).
  CoverageWork courtyard;
  courtyard.triangles = 956;
  courtyard.shadow_texels = 968256;
  courtyard.receivers = 1367856;
  CoverageWork chair;
  chair.triangles = 39936;
  chair.shadow_texels = 668136;
  chair.receivers = 989833;
  courtyard.software = chair.software = true;
  EXPECT_EQ(choose_coverage_method(s, courtyard), CoverageMethod::CpuShadowMaps);
  EXPECT_EQ(choose_coverage_method(s, chair), CoverageMethod::CpuShadowMaps);
  courtyard.software = chair.software = false;
  EXPECT_EQ(choose_coverage_method(s, courtyard), CoverageMethod::ShadowMaps);
  EXPECT_EQ(choose_coverage_method(s, chair), CoverageMethod::ShadowMaps);
  // On a GPU whose driver has not started, the CPU takes what it does in
  // under kCpuSecondsBeforeGl: the car and the building (0.04 s estimated on
  // 2 cores), not the courtyard or the chair at 1024 (1.7 and 1.3 s on 2
  // cores, 0.2 s on 16).
  for (const unsigned threads : {2u, 16u}) {
    for (CoverageWork* w : {&car, &building, &courtyard, &chair}) {
      w->software = false;
      w->gl_cold = true;
      w->threads = threads;
    }
    EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::CpuRays);
    EXPECT_EQ(choose_coverage_method(s, building), CoverageMethod::CpuShadowMaps);
    EXPECT_EQ(choose_coverage_method(s, courtyard), CoverageMethod::ShadowMaps);
    EXPECT_EQ(choose_coverage_method(s, chair), CoverageMethod::ShadowMaps);
  }
  // A terrain of many small triangles with few receivers left (the 1M one
  // at 2048): every map drawing every triangle costs more than the rays,
  // but a CPU map draws only the few near the receivers.
  CoverageWork terrain;
  terrain.triangles = 999890;
  terrain.shadow_texels = 1700 * 534;
  terrain.receivers = 125797;
  terrain.software = true;
  EXPECT_EQ(choose_coverage_method(s, terrain), CoverageMethod::CpuRays);
  terrain.drawn = 40000;
  EXPECT_EQ(choose_coverage_method(s, terrain), CoverageMethod::CpuShadowMaps);
  // A few triangles under 1M-texel maps (Kenney grass and road-corner at
  // 0.05 m): a CPU map's texels cost what llvmpipe's do, and its counting
  // less, so grass's 105k receivers take the CPU maps (0.24 s against
  // llvmpipe's 0.42 s); its rays walk a shallow BVH, so road-corner's 17k
  // receivers take rays (0.11 against 0.16 s on the CPU maps).
  CoverageWork grass;
  grass.triangles = grass.drawn = 30;
  grass.shadow_texels = 999 * 1000;
  grass.receivers = 104704;
  grass.software = true;
  EXPECT_EQ(choose_coverage_method(s, grass), CoverageMethod::CpuShadowMaps);
  CoverageWork corner = grass;
  corner.triangles = corner.drawn = 126;
  corner.receivers = 16984;
  EXPECT_EQ(choose_coverage_method(s, corner), CoverageMethod::CpuRays);
  car.gl_cold = building.gl_cold = false;  // its driver started: the GPU
  EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::GpuRays);
  EXPECT_EQ(choose_coverage_method(s, building), CoverageMethod::ShadowMaps);
  car.software = building.software = true;
  CoverageWork huge = building;  // a map per core would not fit in 256 MiB
  huge.shadow_texels = 16384.0 * 16384.0;
  huge.receivers = 20000000;
  EXPECT_EQ(choose_coverage_method(s, huge), CoverageMethod::ShadowMaps);
  car.snow = building.snow = true;  // no BVH of the snow surface's triangles
  EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::GpuRays);
  EXPECT_EQ(choose_coverage_method(s, building), CoverageMethod::ShadowMaps);
  s.method = "shadow-maps";
  EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::ShadowMaps);
  s.method = "cpu-rays";
  EXPECT_EQ(choose_coverage_method(s, building), CoverageMethod::CpuRays);
  s.method = "cpu-shadow-maps";
  EXPECT_EQ(choose_coverage_method(s, car), CoverageMethod::CpuShadowMaps);
  s.method = "raytrace";
  EXPECT_THROW(fall_directions(s), InputError);
}

// A finely tessellated table top (80k triangles) on maps of 24 texels: the
// automatic method casts rays, and every BVH build and method agrees.
TEST(Coverage, DenseTableTopCastsRaysAndEveryBvhAgrees) {
  REQUIRE_GL();
  SceneBuilder b;
  b.add_plane("Floor", 0.0f, glm::vec2(-2.0f), glm::vec2(2.0f));
  constexpr int kCells = 200;  // 200 x 200 quads at y = 0.75
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  for (int j = 0; j <= kCells; ++j) {
    for (int i = 0; i <= kCells; ++i) {
      positions.emplace_back(-0.5f + float(i) / kCells, 0.75f, -0.5f + float(j) / kCells);
    }
  }
  for (int j = 0; j < kCells; ++j) {
    for (int i = 0; i < kCells; ++i) {
      const uint32_t v = uint32_t(j * (kCells + 1) + i);
      for (uint32_t corner : {v, v + kCells + 1, v + 1, v + 1, v + kCells + 1, v + kCells + 2}) {
        indices.push_back(corner);
      }
    }
  }
  b.add_mesh("TableTop", positions, indices);
  const Scene scene = b.build();
  const SnowMaps maps = peel(scene, 24);
  CoverageRenderer renderer(scene, plan::current_gl());
  const std::vector<float> a = renderer.compute(maps, CoverageSettings{});
  EXPECT_EQ(renderer.timings().method,
            gl::renderer_is_software() ? CoverageMethod::CpuRays : CoverageMethod::GpuRays);
  // Told the maps, the renderer builds its BVH in Morton order for the few
  // rays (80k triangles, 24 x 24 texels x 2 layers): the same coverage.
  EXPECT_EQ(renderer.bvh_build(), Bvh::Build::Sah);
  CoverageRenderer morton(scene, plan::current_gl(), &maps);
  EXPECT_EQ(morton.bvh_build(), Bvh::Build::Morton);
  const std::vector<float> am = morton.compute(maps, CoverageSettings{});
  EXPECT_EQ(std::memcmp(a.data(), am.data(), a.size() * sizeof(float)), 0);
  EXPECT_EQ(
      CoverageRenderer(make_table_scene(0.75f, 1.0f, 4.0f), plan::current_gl(), &maps).bvh_build(),
      Bvh::Build::Sah);
  // Built ahead from the grid alone (the batch job on a GPU, beside the
  // peel): 80k triangles over 576 texels, Morton order; the same coverage.
  EXPECT_EQ(coverage_bvh_build(80000, 576), Bvh::Build::Morton);
  EXPECT_EQ(coverage_bvh_build(9000, 576), Bvh::Build::Sah);
  CoverageRenderer ahead(
      scene,
      build_coverage_bvh(scene, coverage_bvh_build(scene.triangle_count(), maps.grid.texels())),
      plan::current_gl());
  EXPECT_EQ(ahead.bvh_build(), Bvh::Build::Morton);
  const std::vector<float> aa = ahead.compute(maps, CoverageSettings{});
  EXPECT_EQ(std::memcmp(a.data(), aa.data(), a.size() * sizeof(float)), 0);
  CoverageSettings rays;
  rays.method = "rays";
  const std::vector<float> r = renderer.compute(maps, rays);
  EXPECT_EQ(std::memcmp(a.data(), r.data(), a.size() * sizeof(float)), 0);
  // The floor under the top is shaded; the shadow-map method agrees on average.
  const glm::ivec2 under = texel_at(maps.grid, 0.0f, 0.0f);
  EXPECT_LT(coverage_at_height(maps, a, under.x, under.y, 0.0f), 0.01f);
  CoverageSettings maps_method;
  maps_method.method = "shadow-maps";
  const std::vector<float> m = renderer.compute(maps, maps_method);
  EXPECT_EQ(renderer.timings().method, CoverageMethod::ShadowMaps);
  EXPECT_LT(compare(maps, a, m).mean, 0.02);
}

// The CPU sky cull (receivers open along every direction get coverage 1
// without GPU work, found per tile of receivers) skips only texels the
// reference's rays find open, and nearly all of them: like the reference,
// it ignores surfaces only within 0.1 mm above a receiver. Counts for the
// table, house and stairs: 14396 / 13992 / 14750 of 14519 / 14111 / 14778.
// The triangle test is exact (the whole triangle under the cone); with the
// bound it replaced (its highest corner at its footprint's distance) the
// house's roof ridges kept 12516. With the shadow maps' bias (a quarter
// texel) the cull took 5 texels of the table's floor that the reference
// finds shaded.
// CPU shadow maps settle runs of neighbouring receivers at once where the
// texels they read bound every receiver's plane (classify_run_on_cpu),
// clear and draw only the tiles of texels that the receivers read, and where
// triangles outnumber the runs draw only the triangles near those: the
// counts are those of classifying each receiver alone on whole maps, bit for
// bit, in calm and wind, with the snow surface drawn too, on a terrain of
// many triangles and on the bundled courtyard.
TEST(Coverage, ReceiverRunsCountAsEachReceiverAlone) {
  REQUIRE_GL();  // for the peel
  struct Run {
    std::string name;
    Scene scene;
    int side;
    glm::vec2 wind;
    bool snow;
  };
  std::vector<Run> runs;
  for (Case& c : canned_cases()) runs.push_back({c.name, std::move(c.scene), 96, c.wind, false});
  runs.push_back(
      {"table, snow on snow", make_table_scene(0.75f, 1.0f, 4.0f), 96, {0.3f, 0.0f}, true});
  // Many small triangles, few receivers left: each map draws only the
  // triangles near those.
  runs.push_back({"terrain", make_terrain(20000).build(), 256, {0.2f, 0.1f}, false});
  runs.push_back(
      {"courtyard",
       load_scene(std::filesystem::path(SNOW_SOURCE_DIR) / "assets/scenes/courtyard.glb"),
       256,
       {0.0f, 0.0f},
       false});
  for (const Run& run : runs) {
    SCOPED_TRACE(run.name);
    const SnowMaps maps = peel(run.scene, run.side);
    std::vector<float> depth(maps.ground.size(), 0.0f);
    for (size_t k = 0; k < depth.size(); ++k) {
      if (!std::isnan(maps.ground[k])) depth[k] = 0.1f;
    }
    CoverageSettings s;
    s.wind = run.wind;
    s.method = "cpu-shadow-maps";
    CoverageRenderer renderer(run.scene, plan::current_gl());
    const std::vector<float> by_runs = renderer.compute(maps, s, run.snow ? &depth : nullptr);
    const CoverageRenderer::Timings t = renderer.timings();
    ASSERT_EQ(t.method, CoverageMethod::CpuShadowMaps);
    renderer.set_run_bounds(false);
    const std::vector<float> alone = renderer.compute(maps, s, run.snow ? &depth : nullptr);
    EXPECT_EQ(renderer.timings().settled, 0u);
    EXPECT_EQ(renderer.timings().left_out, 0u);
    ASSERT_EQ(by_runs.size(), alone.size());
    EXPECT_EQ(std::memcmp(by_runs.data(), alone.data(), alone.size() * sizeof(float)), 0);
    std::printf("%-20s %llu of %llu pairs settled by runs, %llu triangles left out of maps\n",
                run.name.c_str(), (unsigned long long)t.settled, (unsigned long long)t.pairs,
                (unsigned long long)t.left_out);
    if (run.name == "terrain") {
      // Most of its triangles lie far from the receivers left.
      EXPECT_GT(t.left_out, uint64_t(run.scene.triangle_count()) * 64 / 2);
    } else if (t.pairs > 0) {
      EXPECT_GT(t.settled, t.pairs / 2);  // the runs do most of the work
    }
  }
}

// "auto" judges the CPU shadow maps by the triangles they draw near the
// receivers left: on a terrain of 200k small triangles, whose receivers
// left lie by its tables and walls, it takes them over the rays, and the
// maps leave most triangles out. (On a GPU whose driver has started it
// draws the shadow maps there.)
TEST(Coverage, AutomaticMethodCountsOnlyTrianglesNearTheReceivers) {
  REQUIRE_GL();  // for the peel
  if (!gl::renderer_is_software()) GTEST_SKIP() << "auto draws the shadow maps on this GPU";
  const Scene scene = make_terrain(200000).build();
  const SnowMaps maps = peel(scene, 512, 3);
  CoverageRenderer renderer(scene, plan::current_gl());
  renderer.compute(maps, CoverageSettings{});
  const CoverageRenderer::Timings& t = renderer.timings();
  ASSERT_EQ(t.method, CoverageMethod::CpuShadowMaps);
  std::printf("%llu of %zu triangles x 64 maps left out\n", (unsigned long long)t.left_out,
              scene.triangle_count());
  EXPECT_GT(t.left_out, uint64_t(scene.triangle_count()) * 64 * 3 / 4);
}

TEST(Coverage, SkyCullSkipsOnlyOpenReceivers) {
  REQUIRE_GL();
  const Scene scenes[] = {make_table_scene(0.75f, 1.0f, 4.0f), make_house_scene(45.0f, 0.5f),
                          make_stairs_scene()};
  for (const Scene& scene : scenes) {
    const SnowMaps maps = peel(scene, 128);
    CoverageSettings s;
    CoverageRenderer renderer(scene, plan::current_gl());
    const std::vector<float> gpu = renderer.compute(maps, s);
    const std::vector<float> cpu = reference::compute_coverage(scene, maps, fall_directions(s));
    size_t open = 0;
    for (size_t k = 0; k < cpu.size(); ++k) {
      open += size_t(!std::isnan(maps.ground[k]) && cpu[k] == 1.0f);
    }
    const uint64_t culled = renderer.timings().culled - renderer.timings().shaded;
    std::printf("culled %llu of %zu open layer texels\n", (unsigned long long)culled, open);
    EXPECT_LE(culled, open);
    EXPECT_GT(culled, open * 95 / 100);
  }
}

// Receivers under a solid's top (a table top's and a box lid's undersides,
// the box's cavity floor) are shaded along every direction without any
// ray: only ones the reference's rays find shaded, and the rays' result is
// still the reference's, also at the table top's rim, where lines of fall
// leave through its sides.
TEST(Coverage, UnderSolidCullSkipsOnlyShadedReceivers) {
  REQUIRE_GL();
  const Case cases[] = {{"table in wind", make_table_scene(0.75f, 1.0f, 4.0f), {0.4f, -0.3f}},
                        {"closed box", make_closed_box_scene(1.0f), {0.0f, 0.0f}}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const SnowMaps maps = peel(c.scene, 128);
    CoverageSettings s;
    s.wind = c.wind;
    const std::vector<float> cpu = reference::compute_coverage(c.scene, maps, fall_directions(s));
    size_t shaded_below = 0;  // on layers under another, shaded along every direction
    for (size_t k = maps.grid.texels(); k < cpu.size(); ++k) {
      shaded_below += size_t(!std::isnan(maps.ground[k]) && cpu[k] == 0.0f);
    }
    CoverageRenderer renderer(c.scene, plan::current_gl());
    const Difference d =
        coverage_by(renderer, maps, s, "cpu-rays", CoverageMethod::CpuRays, cpu, c.name).second;
    EXPECT_LT(d.max, 0.5f / 64.0f);
    const uint64_t shaded = renderer.timings().shaded;
    std::printf("%s: %llu of %zu layer texels shaded below another found without rays\n", c.name,
                (unsigned long long)shaded, shaded_below);
    EXPECT_LE(shaded, shaded_below);
    EXPECT_GT(shaded * 3, shaded_below);  // 60 % and 47 % here
  }
}

TEST(Coverage, SameSeedSameOutputDifferentSeedDifferentJitter) {
  REQUIRE_GL();
  const Scene scene = make_table_scene(0.75f, 1.0f, 4.0f);
  const SnowMaps maps = peel(scene, 96);
  CoverageSettings s;
  const std::vector<float> a = compute_coverage(scene, maps, s, plan::current_gl());
  CoverageRenderer renderer(scene, plan::current_gl());  // a second renderer, called twice
  const std::vector<float> b = renderer.compute(maps, s);
  const std::vector<float> b2 = renderer.compute(maps, s);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
  EXPECT_EQ(std::memcmp(b.data(), b2.data(), b.size() * sizeof(float)), 0);
  s.seed = 7;
  const std::vector<float> c = renderer.compute(maps, s);
  size_t differ = 0;
  for (size_t k = 0; k < a.size(); ++k) differ += a[k] != c[k];
  EXPECT_GT(differ, 10u);  // the penumbra moves with the jitter
  // ... but only in the penumbra: the mean barely changes.
  EXPECT_LT(compare(maps, a, c).mean, 0.02);
}

TEST(Coverage, BatchSizeDoesNotChangeTheResult) {
  REQUIRE_GL();
  const Scene scene = make_table_scene(0.75f, 1.0f, 4.0f);
  const SnowMaps maps = peel(scene, 64);
  CoverageSettings s;
  s.directions = 20;
  s.batch = 8;  // 8 + 8 + 4
  const std::vector<float> a = compute_coverage(scene, maps, s, plan::current_gl());
  s.batch = 1;
  const std::vector<float> b = compute_coverage(scene, maps, s, plan::current_gl());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
  s.batch = 0;  // automatic: all 20 in one batch on these small maps
  const std::vector<float> c = compute_coverage(scene, maps, s, plan::current_gl());
  EXPECT_EQ(std::memcmp(a.data(), c.data(), a.size() * sizeof(float)), 0);
}

TEST(Coverage, SnowOnSnowOccludesAndRaisesPoints) {
  REQUIRE_GL();
  const Scene scene = make_open_plane(6.0f);
  const SnowMaps maps = peel(scene, 96, 2);
  // A 1 m high ridge of snow along x, crest |z| < 0.236, flanks at 70
  // degrees down to |z| = 0.6, on the open plane.
  std::vector<float> depth(maps.ground.size(), 0.0f);
  const MapGrid& g = maps.grid;
  for (int j = 0; j < g.height; ++j) {
    for (int i = 0; i < g.width; ++i) {
      const glm::vec2 c = g.center(i, j);
      if (std::abs(c.x) > 2.5f) continue;
      depth[maps.index(0, i, j)] = std::clamp(2.75f * (0.6f - std::abs(c.y)), 0.0f, 1.0f);
    }
  }
  CoverageSettings s;
  s.wind = glm::vec2(0.0f, 0.8f);  // blowing across the ridge: tilt 38.7 degrees
  const std::vector<float> cpu =
      reference::compute_coverage(scene, maps, fall_directions(s), &depth);
  for (const char* method : {"rays", "cpu-rays"}) {  // the snow surface in every ray's way
    s.method = method;
    const Difference rays =
        compare(maps, compute_coverage(scene, maps, s, plan::current_gl(), &depth), cpu);
    std::printf("snow on snow, %s: mean |rays - reference| %.5f, max %.3f\n", method, rays.mean,
                rays.max);
    EXPECT_LT(rays.max, 0.5f / 64.0f);
  }
  s.method = "cpu-shadow-maps";  // the snow surface's triangles drawn and cast on the CPU
  const Difference on_cpu =
      compare(maps, compute_coverage(scene, maps, s, plan::current_gl(), &depth), cpu);
  std::printf("snow on snow, CPU shadow maps: mean |maps - reference| %.4f, max %.3f\n",
              on_cpu.mean, on_cpu.max);
  EXPECT_LT(on_cpu.mean, 0.02);
  s.method = "shadow-maps";
  const std::vector<float> gpu = compute_coverage(scene, maps, s, plan::current_gl(), &depth);
  const Difference d = compare(maps, gpu, cpu);
  std::printf("snow on snow: mean |gpu - cpu| %.4f, max %.3f\n", d.mean, d.max);
  EXPECT_LT(d.mean, 0.02);
  // The ridge's crest sees the sky; the bare plane in its lee is shadowed.
  const glm::ivec2 crest = texel_at(g, 0.0f, 0.0f);
  EXPECT_GT(gpu[maps.index(0, crest.x, crest.y)], 0.99f);
  const glm::ivec2 lee = texel_at(g, 0.0f, 0.75f);  // 0.15 m past the ridge's foot
  EXPECT_LT(gpu[maps.index(0, lee.x, lee.y)], 0.5f);
  // Without the snow surface the plane is open sky everywhere.
  const std::vector<float> bare = compute_coverage(scene, maps, s, plan::current_gl());
  EXPECT_GT(bare[maps.index(0, lee.x, lee.y)], 0.99f);
}

TEST(Coverage, RejectsMismatchedSnowDepth) {
  REQUIRE_GL();
  const Scene scene = make_open_plane(2.0f);
  const SnowMaps maps = peel(scene, 32, 2);
  std::vector<float> depth(3, 0.0f);
  EXPECT_THROW(compute_coverage(scene, maps, {}, plan::current_gl(), &depth), InputError);
  CoverageSettings bad;
  bad.batch = 33;
  EXPECT_THROW(compute_coverage(scene, maps, bad, plan::current_gl()), InputError);
}

// Moller-Trumbore in double precision: does the ray from `o` along `d` hit
// triangle (a, b, c) for some t > 0?
bool ray_hits(glm::dvec3 o, glm::dvec3 d, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  const glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
  const double det = glm::dot(e1, p);
  if (det == 0.0) return false;
  const glm::dvec3 s = o - a, q = glm::cross(s, e1);
  const double u = glm::dot(s, p) / det, v = glm::dot(d, q) / det;
  return u >= 0.0 && v >= 0.0 && u + v <= 1.0 && glm::dot(e2, q) / det > 0.0;
}

}  // namespace

// Each test of the BVH runs on both builds (named in test output; found by
// argument-dependent lookup, so in Bvh's namespace).
void PrintTo(Bvh::Build build, std::ostream* os) {
  *os << (build == Bvh::Build::Sah ? "Sah" : "Morton");
}

namespace {

class BvhBuilds : public ::testing::TestWithParam<Bvh::Build> {};
INSTANTIATE_TEST_SUITE_P(Bvh, BvhBuilds, ::testing::Values(Bvh::Build::Sah, Bvh::Build::Morton),
                         [](const ::testing::TestParamInfo<Bvh::Build>& info) {
                           return info.param == Bvh::Build::Sah ? "Sah" : "Morton";
                         });

// A BVH large enough to be built on several threads (the SAH build's top
// splits build their halves beside each other, spliced into one pre-order
// array, and its nodes of 128k triangles or more bin and partition them on
// all cores; the Morton build's loops run on all cores, its tree on one):
// the spliced skip links and boxes hold for every node, the leaves cover
// every triangle once in order, and rays find what a walk over all
// triangles finds.
TEST_P(BvhBuilds, ParallelBuildIsOneValidTree) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> where(-50.0f, 50.0f), size(-0.3f, 0.3f);
  const size_t n = 300000;  // two halves built apart
  std::vector<glm::vec3> corners;
  corners.reserve(3 * n);
  for (size_t t = 0; t < n; ++t) {
    const glm::vec3 c(where(rng), 0.2f * where(rng), where(rng));
    for (int k = 0; k < 3; ++k) corners.push_back(c + glm::vec3(size(rng), size(rng), size(rng)));
  }
  const Bvh bvh(corners, GetParam());
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  ASSERT_FALSE(nodes.empty());
  uint32_t next_triangle = 0;
  size_t bad = 0;
  // Checks the subtree at node i inside box (lo, hi); returns the node after it.
  std::function<uint32_t(uint32_t, glm::vec3, glm::vec3)> walk = [&](uint32_t i, glm::vec3 lo,
                                                                     glm::vec3 hi) -> uint32_t {
    const Bvh::Node& node = nodes.at(i);
    bad += glm::any(glm::lessThan(node.min, lo)) || glm::any(glm::greaterThan(node.max, hi));
    if (node.count > 0) {
      bad += node.first != next_triangle;
      for (uint32_t t = node.first; t < node.first + node.count; ++t) {
        for (int k = 0; k < 3; ++k) {
          const glm::vec3 p = bvh.corners()[3 * size_t(t) + size_t(k)];
          bad += glm::any(glm::lessThan(p, node.min)) || glm::any(glm::greaterThan(p, node.max));
        }
      }
      next_triangle = node.first + node.count;
      return i + 1;
    }
    const uint32_t right = walk(i + 1, node.min, node.max);
    const uint32_t end = walk(right, node.min, node.max);
    bad += node.first != end;  // the skip link
    return end;
  };
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(walk(0, glm::vec3(-inf), glm::vec3(inf)), nodes.size());
  EXPECT_EQ(next_triangle, n);
  ASSERT_EQ(bad, 0u);  // (a bad skip link can send the walk below in circles)
  // order() is a permutation, and the triangles in leaf order are the input's.
  ASSERT_EQ(bvh.order().size(), n);
  std::vector<uint8_t> seen(n, 0);
  for (size_t k = 0; k < n; ++k) {
    const uint32_t t = bvh.order()[k];
    ASSERT_LT(t, n);
    bad += seen[t]++;
    for (size_t c = 0; c < 3; ++c) bad += bvh.corners()[3 * k + c] != corners[3 * size_t(t) + c];
  }
  EXPECT_EQ(bad, 0u);
  // Vertical rays through random points, against every triangle.
  size_t hits = 0, differ = 0;
  for (int r = 0; r < 100; ++r) {
    const glm::vec3 origin(where(rng), 20.0f, where(rng));
    const glm::vec3 down(0.01f * size(rng), -1.0f, 0.01f * size(rng));
    bool any = false;
    for (size_t t = 0; t < n && !any; ++t) {
      any = ray_hits(origin, down, corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]);
    }
    hits += any;
    differ += any != bvh.occluded(origin, down, 0.0f, 1e9f);
  }
  EXPECT_GT(hits, 5u);
  EXPECT_EQ(differ, 0u);
}

// The Morton build's radix sort runs on all cores in ranges of 16k
// triangles and must stay stable: triangles of one code (here, of one of
// four centroids, interleaved over 5 ranges) keep their input order, in one
// run per code.
TEST(Bvh, MortonOrderKeepsEqualCodesInInputOrder) {
  const size_t n = 70000;
  const glm::vec3 at[4] = {{0, 0, 0}, {3, 1, 0}, {0, 2, 3}, {3, 0, 3}};
  std::vector<glm::vec3> corners;
  for (size_t t = 0; t < n; ++t) {
    const glm::vec3 c = at[t % 4];
    corners.insert(corners.end(), {c + glm::vec3(0.1f, 0, 0), c + glm::vec3(0, 0, 0.1f),
                                   c - glm::vec3(0.1f, 0, 0.1f)});
  }
  const Bvh bvh(corners, Bvh::Build::Morton);
  const std::vector<uint32_t>& order = bvh.order();
  ASSERT_EQ(order.size(), n);
  size_t runs = 1, out_of_order = 0;
  for (size_t k = 1; k < n; ++k) {
    if (order[k] % 4 != order[k - 1] % 4) {
      ++runs;
    } else {
      out_of_order += order[k] < order[k - 1];
    }
  }
  EXPECT_EQ(runs, 4u);
  EXPECT_EQ(out_of_order, 0u);
}

// Triangles the split cannot part (one shared centroid, or NaN corners):
// the build ends in leaves that still hold every triangle once, in order,
// and rays still find the shared ones.
TEST_P(BvhBuilds, UnsplittableTrianglesStillBuild) {
  std::vector<glm::vec3> corners;
  for (int t = 0; t < 40; ++t) {  // 40 triangles about the origin, turned
    const float a = 0.15f * float(t);
    const glm::vec3 u(std::cos(a), 0.0f, std::sin(a));
    corners.insert(corners.end(),
                   {u, -0.5f * u + glm::vec3(0, 0.1f, 0), -0.5f * u - glm::vec3(0, 0.1f, 0)});
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int t = 0; t < 5; ++t) {
    corners.insert(corners.end(),
                   {glm::vec3(nan), glm::vec3(float(t)), glm::vec3(1.0f, nan, 0.0f)});
  }
  const Bvh bvh(corners, GetParam());
  uint32_t next = 0;
  for (const Bvh::Node& node : bvh.nodes()) {
    if (node.count == 0) continue;
    EXPECT_EQ(node.first, next);
    next = node.first + node.count;
  }
  EXPECT_EQ(next, 45u);
  // Through the origin, where every turned triangle lies.
  EXPECT_TRUE(bvh.occluded(glm::vec3(0.0f, 0.0f, -1.0f), glm::vec3(0.0f, 0.0f, 1.0f), 0.0f, 2.0f));
  EXPECT_FALSE(bvh.occluded(glm::vec3(0.0f, 5.0f, -1.0f), glm::vec3(0.0f, 0.0f, 1.0f), 0.0f, 2.0f));
}

// Bvh::reaches, the exact casts' shortcut on the CPU: true for some
// triangle exactly when the walk finds the ray occluded, and never where it
// does not (rays with zero components too: slabs of 0 * inf).
// n small random triangles in a flat box 10 m wide (corners 3 per triangle).
std::vector<glm::vec3> random_triangles(std::mt19937& rng, size_t n) {
  std::uniform_real_distribution<float> where(-5.0f, 5.0f), size(-0.8f, 0.8f);
  std::vector<glm::vec3> corners;
  for (size_t t = 0; t < n; ++t) {
    const glm::vec3 c(where(rng), 0.3f * where(rng), where(rng));
    for (int k = 0; k < 3; ++k) corners.push_back(c + glm::vec3(size(rng), size(rng), size(rng)));
  }
  return corners;
}

TEST_P(BvhBuilds, ReachesAgreesWithTheWalk) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> where(-5.0f, 5.0f), unit(-1.0f, 1.0f);
  const size_t n = 2000;
  const Bvh bvh(random_triangles(rng, n), GetParam());
  size_t occluded = 0, differ = 0, false_hits = 0;
  for (int r = 0; r < 400; ++r) {
    const glm::vec3 origin(where(rng), 0.5f * where(rng), where(rng));
    glm::vec3 dir(unit(rng), 0.2f + std::abs(unit(rng)), unit(rng));
    if (r % 4 == 0) dir.x = 0.0f;
    if (r % 8 == 0) dir = glm::vec3(0.0f, 1.0f, 0.0f);
    const float t_min = r % 3 == 0 ? 0.0f : 0.01f;
    const bool walk = bvh.occluded(origin, dir, t_min, std::numeric_limits<float>::infinity());
    bool any = false;
    for (uint32_t t = 0; t < n; ++t) {
      const bool reached =
          bvh.reaches(t, origin, dir, t_min, std::numeric_limits<float>::infinity());
      any = any || reached;
      false_hits += reached && !walk;
    }
    occluded += walk;
    differ += any != walk;
  }
  EXPECT_GT(occluded, 50u);
  EXPECT_EQ(differ, 0u);
  EXPECT_EQ(false_hits, 0u);
  EXPECT_FALSE(bvh.reaches(uint32_t(n), glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f), 0.0f, 1e9f));
}

// Bvh::first_hit names a triangle that the ray hits (one that reaches()
// confirms, the CPU casts' cache) exactly where occluded() is true, and
// kNone elsewhere.
TEST_P(BvhBuilds, FirstHitNamesAnOccluder) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> where(-5.0f, 5.0f), unit(-1.0f, 1.0f);
  const size_t n = 2000;
  const Bvh bvh(random_triangles(rng, n), GetParam());
  const float far = std::numeric_limits<float>::infinity();
  size_t hits = 0, misses = 0, wrong = 0;
  for (int r = 0; r < 2000; ++r) {
    const glm::vec3 origin(where(rng), 0.5f * where(rng), where(rng));
    glm::vec3 dir(unit(rng), 0.2f + std::abs(unit(rng)), unit(rng));
    if (r % 4 == 0) dir.x = 0.0f;
    const float t_min = r % 3 == 0 ? 0.0f : 0.01f;
    const uint32_t t = bvh.first_hit(origin, dir, t_min, far);
    if (t == Bvh::kNone) {
      ++misses;
      wrong += bvh.occluded(origin, dir, t_min, far);
    } else {
      ++hits;
      wrong += t >= n || !bvh.occluded(origin, dir, t_min, far) ||
               !bvh.reaches(t, origin, dir, t_min, far);
    }
  }
  EXPECT_GT(hits, 200u);
  EXPECT_GT(misses, 200u);
  EXPECT_EQ(wrong, 0u);
}

}  // namespace
}  // namespace snow
