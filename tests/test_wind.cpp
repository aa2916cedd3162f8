// Wind (issue 51): the horizons the transport reads the scene with
// (snow/exposure.h), and the transport (snow/drift.h) against drifts
// measured around a cube (Tominaga et al. 2011) and EN 1991-1-3's drift at
// a step, on scenes built in code, through the CPU stages.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "core/error.h"
#include "mesh/polygonize.h"
#include "scene/builder.h"
#include "snow/coverage.h"
#include "snow/drift.h"
#include "snow/exposure.h"
#include "snow/reference/coverage_ref.h"
#include "snow/stabilize_cpu.h"
#include "support/maps.h"

namespace snow {
namespace {

using test::maps_of;

// The column (j * width + i) under world (x, z).
size_t column_at(const MapGrid& g, float x, float z) {
  const int i = std::clamp(int((x - g.origin.x) / g.texel), 0, g.width - 1);
  const int j = std::clamp(int((z - g.origin.y) / g.texel), 0, g.height - 1);
  return size_t(j) * size_t(g.width) + size_t(i);
}

// A box "Cube" from `low` to `high` on a level "Field" over [field_low,
// field_high] (x, z), metres.
Scene box_in_a_field(const glm::vec2& field_low, const glm::vec2& field_high, const glm::vec3& low,
                     const glm::vec3& high) {
  SceneBuilder b;
  b.add_plane("Field", 0.0f, field_low, field_high);
  b.add_box("Cube", low, high);
  return b.build();
}

Scene cube_in_a_field() {
  return box_in_a_field({-20.0f, -20.0f}, {40.0f, 20.0f}, {-1.0f, 0.0f, -1.0f}, {1.0f, 2.0f, 1.0f});
}

// A 2 m cube in a field, wind along +x, slope 0.5: the lee is sheltered
// 2 / 0.5 = 4 m downwind (rise = 2 - 0.5 d above the field at distance d),
// the open field not at all, and looking downwind the cube's windward face
// shelters 4 m in front of it.
TEST(Wind, HorizonsShelterTheLeeAndTheWindwardFace) {
  const SnowMaps maps = maps_of(cube_in_a_field(), 0.1f);
  const std::vector<float> top = top_surface(maps, std::vector<float>(maps.ground.size(), 0.0f));
  const Horizon lee = horizon_along(maps.grid, top, glm::vec2(-1.0f, 0.0f), 0.5f);
  const Horizon front = horizon_along(maps.grid, top, glm::vec2(1.0f, 0.0f), 0.5f);
  const auto at = [&](const std::vector<float>& v, float x, float z) {
    return v[column_at(maps.grid, x, z)];
  };
  // Texel centres: the lee point at x = 2.05 lies 1.1 m from the cube's last
  // column centre (0.95).
  EXPECT_NEAR(at(lee.rise, 2.05f, 0.05f), 2.0f - 0.5f * 1.1f, 1e-4f);
  EXPECT_NEAR(at(lee.height, 2.05f, 0.05f), 2.0f, 1e-4f);
  EXPECT_LT(at(lee.rise, 5.55f, 0.05f), 0.0f);  // 4.6 m behind: out of the shelter
  EXPECT_LT(at(lee.rise, -8.05f, 0.05f), 0.0f);
  EXPECT_LT(at(lee.rise, 0.05f, 3.05f), 0.0f);  // beside the cube
  EXPECT_NEAR(at(front.rise, -2.05f, 0.05f), 2.0f - 0.5f * 1.1f, 1e-4f);
  EXPECT_LT(at(front.rise, 2.05f, 0.05f), 0.0f);
  // Diagonal: exact along the diagonal too.
  const Horizon diagonal = horizon_along(maps.grid, top, glm::vec2(-1.0f, -1.0f), 0.5f);
  const float d = std::sqrt(2.0f) * 0.2f;  // two diagonal steps from the corner column
  EXPECT_NEAR(at(diagonal.rise, 1.15f, 1.15f), 2.0f - 0.5f * d, 1e-4f);
  EXPECT_THROW(horizon_along(maps.grid, top, glm::vec2(0.0f), 0.5f), InputError);
}

struct Windy {
  SnowMaps maps;
  std::vector<float> depth;  // metres per layer texel, after drifting and stabilizing
  double fallen = 0.0;       // m^3 that fell on the maps, plus what drifted in
  double lying = 0.0;        // m^3 lying at the end
  double left = 0.0;         // m^3 that left the maps (drifting off, sliding off)
  DriftResult drift;
  float depth_at(float x, float z) const { return depth[column_at(maps.grid, x, z)]; }
};

// `fall` metres of fresh snow on `scene` in a wind of `wind` m/s (x, z):
// the tilted fall's coverage, the transport the planner gives for that
// wind, the stabilizer, as the batch job runs them.
Windy windy_snow(const Scene& scene, float texel, float fall, const glm::vec2& wind) {
  Windy out;
  out.maps = maps_of(scene, texel);
  CoverageSettings coverage;
  coverage.directions = 16;
  coverage.wind = wind;
  const std::vector<float> p =
      reference::compute_coverage(scene, out.maps, fall_directions(coverage));
  std::vector<float> depth(p.size(), 0.0f);
  for (size_t k = 0; k < p.size(); ++k) {
    if (!std::isnan(out.maps.ground[k])) depth[k] = fall * p[k];
  }
  out.fallen = snow_volume(out.maps, depth);
  out.drift = drift_snow(out.maps, depth, fall, drift_for_wind(wind, SnowKind::Fresh, fall));
  out.fallen += out.drift.entered;
  CpuStabilizer stabilizer(out.maps, StabilizeSettings{});
  stabilizer.set_depth(depth);
  const StabilizeResult r = stabilizer.run();
  EXPECT_TRUE(r.converged);
  out.depth = stabilizer.depth();
  out.lying = snow_volume(out.maps, out.depth);
  out.left = stabilizer.lost_volume() + out.drift.left;
  return out;
}

void print_profile(const Windy& s, float z, float x0, float x1, float dx) {
  for (float x = x0; x <= x1 + 1e-3f; x += dx) std::printf(" %5.2f", double(s.depth_at(x, z)));
  std::printf("\n");
}

// Mean depth (m) of layer 0 over the columns whose centres lie in the
// rectangle [x0, x1] x [z0, z1].
double mean_in(const Windy& s, float x0, float x1, float z0, float z1) {
  double sum = 0.0;
  size_t n = 0;
  const MapGrid& g = s.maps.grid;
  for (int j = 0; j < g.height; ++j) {
    for (int i = 0; i < g.width; ++i) {
      const glm::vec2 c = g.center(i, j);
      if (c.x < x0 || c.x > x1 || c.y < z0 || c.y > z1) continue;
      sum += double(s.depth[size_t(j) * size_t(g.width) + size_t(i)]);
      ++n;
    }
  }
  return n > 0 ? sum / double(n) : 0.0;
}

// Tominaga et al. (2011) measured the snow around a cube in a field in
// Sapporo: drifts in its lee, scour at its windward corners and along its
// sides. A 2 m cube, 0.3 m of fresh snow in a 5 m/s wind along +x: 1 to
// 10 m downwind, behind it, the snow reaches 1.3 times the open field's depth; beside the
// windward corners (the first half of each side, 0.5 m out) it lies below
// it; the open field away from the cube keeps its depth within 10 %.
TEST(Wind, CubeGetsALeeDriftAndScouredWindwardCorners) {
  const Scene scene = cube_in_a_field();
  const float fall = 0.3f;
  const Windy s = windy_snow(scene, 0.1f, fall, glm::vec2(5.0f, 0.0f));
  for (float z : {0.05f, 1.25f, 2.05f, 4.05f}) {
    std::printf("z %.2f:", double(z));
    print_profile(s, z, -6.0f, 14.0f, 0.5f);
  }
  float lee = 0.0f;
  for (float x = 2.05f; x < 11.0f; x += 0.1f) {
    for (float z = -0.95f; z < 1.0f; z += 0.1f) lee = std::max(lee, s.depth_at(x, z));
  }
  const double corners =
      0.5 * (mean_in(s, -1.0f, 0.0f, 1.0f, 1.5f) + mean_in(s, -1.0f, 0.0f, -1.5f, -1.0f));
  const double upwind = mean_in(s, -19.0f, -12.0f, -19.0f, 19.0f);
  const double beside =
      0.5 * (mean_in(s, -19.0f, 39.0f, 12.0f, 19.0f) + mean_in(s, -19.0f, 39.0f, -19.0f, -12.0f));
  std::printf("lee peak %.3f m (%.2f x), corners %.3f m, open field upwind %.3f, beside %.3f\n",
              double(lee), double(lee / fall), corners, upwind, beside);
  EXPECT_GE(lee, 1.3f * fall);
  EXPECT_LT(corners, 0.95 * fall);
  EXPECT_NEAR(upwind, fall, 0.1 * fall);
  EXPECT_NEAR(beside, fall, 0.1 * fall);
  EXPECT_NEAR(s.lying + s.left, s.fallen, 1e-5 * s.fallen);
}

// EN 1991-1-3, section 5.3.6: on a roof abutting a building h metres
// higher, the drift is a triangle of length ls = 2h against the step, its
// peak mu_w = (b1 + b2) / 2h times the ground's snow (b1, b2 the widths of
// the higher and the lower roof; mu_w within 0.8..4). A lower roof 3 m high
// and b2 = 8 m wide against a building 6 m high, b1 = 8 m wide; 0.3 m of
// fresh snow, a 6 m/s wind towards the step. The drift: the depth along the
// lower roof's middle, from the step to where it falls back to the roof's
// depth far from the step; its length within 30 % of 2h and its peak
// within 30 % of mu_w times the open field's depth.
void expect_step_drift(float wind_x) {
  SceneBuilder b;
  b.add_plane("Field", 0.0f, glm::vec2(-30.0f, -15.0f), glm::vec2(30.0f, 15.0f));
  b.add_box("Lower", glm::vec3(-8.0f, 0.0f, -6.0f), glm::vec3(0.0f, 3.0f, 6.0f));
  b.add_box("Higher", glm::vec3(0.0f, 0.0f, -6.0f), glm::vec3(8.0f, 6.0f, 6.0f));
  const Scene scene = b.build();
  const float fall = 0.3f, h = 3.0f, b1 = 8.0f, b2 = 8.0f;
  const Windy s = windy_snow(scene, 0.1f, fall, glm::vec2(wind_x, 0.0f));
  std::printf("wind %.0f m/s along x:", double(wind_x));
  print_profile(s, 0.05f, -8.0f, 0.0f, 0.25f);
  // The roof's depth away from the step: its far quarter, inside the edges.
  float peak = 0.0f;
  for (float x = -0.05f; x > -1.0f; x -= 0.1f) peak = std::max(peak, s.depth_at(x, 0.05f));
  const double far = mean_in(s, -7.0f, -6.0f, -2.0f, 2.0f);
  float length = 0.0f;
  for (float x = -0.05f; x > -7.9f; x -= 0.1f) {
    if (s.depth_at(x, 0.05f) <= float(far) + 0.01f) break;
    length = -x;
  }
  const double mu_w = std::clamp((b1 + b2) / (2.0 * h), 0.8, 4.0);
  const double open = mean_in(s, -28.0f, 28.0f, 10.0f, 14.0f);
  std::printf("drift: peak %.3f m (EN %.3f), length %.2f m (EN %.1f), roof far %.3f, open %.3f\n",
              double(peak), mu_w * open, double(length), 2.0 * h, far, open);
  EXPECT_NEAR(peak, mu_w * open, 0.3 * mu_w * open);
  EXPECT_NEAR(length, 2.0 * h, 0.3 * 2.0 * h);
  EXPECT_NEAR(s.lying + s.left, s.fallen, 1e-5 * s.fallen);
}

TEST(Wind, DriftAgainstAStepFollowsEurocode) { expect_step_drift(8.0f); }
// The same with the wind off the higher roof: the lee drift.
TEST(Wind, DriftBehindAStepFollowsEurocode) { expect_step_drift(-8.0f); }

// A wall 1.5 m high and 0.2 m thick across a 6 m/s wind, as a snow fence:
// the snow within 2h behind it reaches 1.3 times the open field's depth,
// and more lies there than fell.
TEST(Wind, FenceAcrossTheWindHasADriftInItsLee) {
  const float fall = 0.3f;
  const Windy s = windy_snow(
      box_in_a_field({-20.0f, -15.0f}, {30.0f, 15.0f}, {-0.1f, 0.0f, -8.0f}, {0.1f, 1.5f, 8.0f}),
      0.1f, fall, glm::vec2(6.0f, 0.0f));
  print_profile(s, 0.05f, -5.0f, 10.0f, 0.5f);
  float lee = 0.0f;
  for (float x = 0.15f; x < 3.1f; x += 0.1f) lee = std::max(lee, s.depth_at(x, 0.05f));
  const double behind = mean_in(s, 0.1f, 3.1f, -6.0f, 6.0f);
  const double before = mean_in(s, -3.1f, -0.1f, -6.0f, 6.0f);
  std::printf("fence: lee peak %.3f m, lee mean %.3f m, windward mean %.3f m\n", double(lee),
              behind, before);
  EXPECT_GE(lee, 1.3f * fall);
  EXPECT_GT(behind, fall);
  EXPECT_NEAR(s.lying + s.left, s.fallen, 1e-5 * s.fallen);
}

// A post 4 m high but 0.2 m across leaves no drift tail behind it (the flow
// closes behind it): 1 to 8 m downwind no snow lies 15 % deeper than on the
// open field (the tilted fall's thin shadow may leave less).
TEST(Wind, APostCastsNoDriftTail) {
  const float fall = 0.3f;
  const Windy s = windy_snow(
      box_in_a_field({-10.0f, -6.0f}, {20.0f, 6.0f}, {-0.1f, 0.0f, -0.1f}, {0.1f, 4.0f, 0.1f}),
      0.05f, fall, glm::vec2(8.0f, 0.0f));
  float high = 0.0f;
  for (float x = 1.1f; x < 8.1f; x += 0.05f) {
    for (float z = -0.475f; z < 0.5f; z += 0.05f) high = std::max(high, s.depth_at(x, z));
  }
  std::printf("behind the post: at most %.3f m\n", double(high));
  EXPECT_LT(high, 1.15f * fall);
}

// Mass: what lies plus what left equals what fell plus what drifted in, to
// 1e-5, at every wind speed; below the threshold nothing moves (the depth
// keeps its bytes); the same storm twice gives the same bytes.
TEST(Wind, TransportConservesMassAndRepeatsItself) {
  const SnowMaps maps = maps_of(cube_in_a_field(), 0.1f);
  const float fall = 0.3f;
  std::vector<float> fallen(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < fallen.size(); ++k) {
    // An uneven snowfall, so that columns differ.
    if (!std::isnan(maps.ground[k]))
      fallen[k] = fall * (0.5f + 0.5f * float((k * 2654435761u) % 1000) / 1000.0f);
  }
  const double before = snow_volume(maps, fallen);
  for (float speed : {0.0f, 3.9f, 5.0f, 10.0f, 25.0f}) {
    const DriftSettings settings =
        drift_for_wind(glm::vec2(0.6f, 0.8f) * speed, SnowKind::Fresh, fall);
    std::vector<float> depth = fallen;
    const DriftResult r = drift_snow(maps, depth, fall, settings);
    const double after = snow_volume(maps, depth);
    std::printf("%4.1f m/s: transport %.1f m, moved %.1f m^3, in %.1f, out %.1f, balance %.3g\n",
                double(speed), double(settings.transport), r.moved, r.entered, r.left,
                after + r.left - before - r.entered);
    EXPECT_NEAR(after + r.left, before + r.entered, 1e-5 * (before + r.entered));
    for (float d : depth) ASSERT_GE(d, 0.0f);
    if (speed < 4.0f) {
      EXPECT_EQ(settings.transport, 0.0f);
      EXPECT_EQ(depth, fallen);
    } else {
      EXPECT_GT(r.moved, 0.0);
      std::vector<float> again = fallen;
      drift_snow(maps, again, fall, settings);
      EXPECT_EQ(std::memcmp(again.data(), depth.data(), depth.size() * sizeof(float)), 0);
    }
  }
}

// On texels of a tenth of an attometre (a scene of that size, as tools/fuzz
// made one) the lateral mixing's spread per slab overflowed an int (UB, which
// the sanitized build stops at); the passes are capped first, and the storm
// still conserves the snow.
TEST(Wind, TinyTexelsMixWithinTheCap) {
  SceneBuilder b;
  b.add_plane("Field", 0.0f, {-1e-18f, -1e-18f}, {1e-18f, 1e-18f});
  const SnowMaps maps = maps_of(b.build(), 1e-19f);
  ASSERT_GT(maps.grid.width, 4);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (size_t k = 0; k < depth.size(); ++k) depth[k] = std::isnan(maps.ground[k]) ? 0.0f : 0.3f;
  const double before = snow_volume(maps, depth);
  const DriftResult r =
      drift_snow(maps, depth, 0.3f, drift_for_wind({8.0f, 3.0f}, SnowKind::Fresh, 0.3f));
  for (float d : depth) ASSERT_TRUE(std::isfinite(d) && d >= 0.0f);
  EXPECT_NEAR(snow_volume(maps, depth) + r.left, before + r.entered, 1e-5 * (before + r.entered));
}

// A snowfall in 8 steps, each drifted as it falls (the live preview, the
// batch job's --steps), is scoured as one: no column of the field ends with
// less than 1 - max_scour of what fell on it, as in one step.
TEST(Wind, ASnowfallInStepsIsScouredAsOne) {
  const SnowMaps maps = maps_of(cube_in_a_field(), 0.1f);
  const float fall = 0.3f;
  const DriftSettings settings = drift_for_wind(glm::vec2(10.0f, 0.0f), SnowKind::Fresh, fall);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int step = 0; step < 8; ++step) {
    for (size_t c = 0; c < maps.grid.texels(); ++c) depth[c] += fall / 8.0f;
    drift_snow(maps, depth, fall / 8.0f, settings);
  }
  const float least =
      *std::min_element(depth.begin(), depth.begin() + ptrdiff_t(maps.grid.texels()));
  std::printf("8 steps at 10 m/s: the most scoured column keeps %.3f m of %.2f\n", double(least),
              double(fall));
  EXPECT_GE(least, (1.0f - settings.max_scour) * fall - 1e-4f);
}

// Cornices: snow blown over a roof's lee edge grows out over the air. The
// cube's snow in an 8 m/s wind along +x, meshed with the planner's cornice
// for that wind: past the lee edge (x = 1) the snow reaches out further than
// the still-air lip (PolygonizeSettings::overhang) and than at the windward
// edge, with faces looking down under it, and the solid stays a closed
// 2-manifold.
TEST(Wind, CorniceGrowsOverTheLeeEdgeAsAClosedSolid) {
  const Scene scene = cube_in_a_field();
  const glm::vec2 wind(8.0f, 0.0f);
  const Windy s = windy_snow(scene, 0.05f, 0.3f, wind);
  const DriftSettings drift = drift_for_wind(wind, SnowKind::Fresh, 0.3f);
  PolygonizeSettings settings;
  settings.cornice.direction = glm::normalize(drift.direction);
  settings.cornice.length = float(plan::cornice_length(double(drift.transport)));
  const std::vector<SnowPatch> patches = polygonize(s.maps, s.depth, scene, settings);
  const int cube = find_object(scene, "Cube");
  const SnowPatch* roof = nullptr;
  for (const SnowPatch& p : patches) {
    if (p.object == cube) roof = &p;
  }
  ASSERT_NE(roof, nullptr);
  const TriMesh& m = roof->mesh;
  const TopologyReport topology = check_topology(m.positions, m.indices);
  EXPECT_TRUE(topology.closed()) << topology.boundary_edges << " boundary, "
                                 << topology.nonmanifold_edges << " non-manifold";
  float lee = 0.0f, windward = 0.0f;
  for (const glm::vec3& p : m.positions) {
    if (p.y < 2.0f || std::abs(p.z) > 0.8f) continue;  // the roof's snow, off its corners
    lee = std::max(lee, p.x - 1.0f);
    windward = std::max(windward, -1.0f - p.x);
  }
  size_t under = 0;
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const glm::vec3 a = m.positions[m.indices[t]], b = m.positions[m.indices[t + 1]],
                    c = m.positions[m.indices[t + 2]];
    const glm::vec3 n = glm::cross(b - a, c - a);
    if (n.y < -0.1f * glm::length(n) && std::min({a.x, b.x, c.x}) > 1.0f) ++under;
  }
  std::printf(
      "cornice %.2f m asked; reaches %.3f m past the lee edge, %.3f m past the windward "
      "edge; %zu faces under it\n",
      double(settings.cornice.length), double(lee), double(windward), under);
  EXPECT_GT(lee, 2.0f * settings.overhang);
  EXPECT_GT(lee, 2.0f * windward);
  EXPECT_GT(under, 4u);
}

}  // namespace
}  // namespace snow
