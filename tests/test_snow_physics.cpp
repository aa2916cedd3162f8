// The snow's physics against analytic cases and published measurements, on
// scenes built in code, through the CPU stages (snow_cpu: the CPU peel, the
// ray-cast coverage, the CPU stabilizer; the GPU stabilizer's agreement with
// the CPU one is test_stabilize's): cohesion (snow/cohesion.h) against
// EN 1991-1-3's roof shape coefficient and SnowSlide's holding depths.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <utility>
#include <vector>

#include "mesh/polygonize.h"
#include "scene/builder.h"
#include "snow/bridge.h"
#include "snow/coverage.h"
#include "snow/peel.h"
#include "snow/reference/coverage_ref.h"
#include "snow/reference/peel_ref.h"
#include "snow/stabilize_cpu.h"

namespace snow {
namespace {

struct Snowed {
  SnowMaps maps;
  std::vector<float> depth;  // metres per layer texel, after stabilizing
  double fallen = 0.0;       // m^3 of snow that fell on the maps
  double lying = 0.0;        // m^3 lying after stabilizing
  double lost = 0.0;         // m^3 that left the maps
};

// `fall` metres of snow on `scene` (maps of `max_side` texels along the
// longer side, bridged as the peel bridges them), stabilized on the CPU with
// `settings`.
Snowed snow_on(const Scene& scene, int max_side, float fall, const StabilizeSettings& settings) {
  PeelSettings peel;
  peel.max_side = max_side;
  Snowed out;
  out.maps = reference::peel_layers(scene, make_grid(scene.bounds, peel), peel.layers);
  bridge_gaps(out.maps, peel.bridge_width);
  CoverageSettings coverage;
  coverage.directions = 16;
  std::vector<float> p = reference::compute_coverage(scene, out.maps, fall_directions(coverage));
  mask_coverage(out.maps, {}, p);
  std::vector<float> fell(p.size(), 0.0f);
  for (size_t k = 0; k < p.size(); ++k) {
    if (!std::isnan(out.maps.ground[k])) fell[k] = fall * p[k];
  }
  out.fallen = snow_volume(out.maps, fell);
  CpuStabilizer stabilizer(out.maps, settings);
  stabilizer.set_depth(std::vector<float>(p.size(), 0.0f));
  stabilizer.add_snow(p, fall);
  const StabilizeResult r = stabilizer.run();
  EXPECT_TRUE(r.converged);
  out.depth = stabilizer.depth();
  out.lying = snow_volume(out.maps, out.depth);
  out.lost = stabilizer.lost_volume();
  return out;
}

// Mean snow depth (m) over the up-facing layer texels of `object` whose
// centre satisfies `where(x, z)`.
template <class Where>
double mean_depth(const Snowed& s, int object, Where where) {
  double sum = 0.0;
  size_t count = 0;
  const SnowMaps& m = s.maps;
  for (int l = 0; l < m.layers; ++l) {
    for (int j = 0; j < m.grid.height; ++j) {
      for (int i = 0; i < m.grid.width; ++i) {
        const size_t k = m.index(l, i, j);
        const glm::vec2 c = m.grid.center(i, j);
        if (m.object[k] != object || !(m.normal[k].y > 0.0f) || !where(c.x, c.y)) continue;
        sum += double(s.depth[k]);
        ++count;
      }
    }
  }
  return count > 0 ? sum / double(count) : 0.0;
}

// EN 1991-1-3, table 5.2: roof shape coefficient mu1 for a pitch in degrees.
double en_mu1(double pitch_deg) {
  if (pitch_deg <= 30.0) return 0.8;
  if (pitch_deg >= 60.0) return 0.0;
  return 0.8 * (60.0 - pitch_deg) / 30.0;
}

// Roofs against pitch: a gable-roofed house on open ground, 0.3 m of fresh
// snow. EN 1991-1-3's mu1 is the roof's load over the ground's: 0.8 for
// pitches up to 30 degrees, falling linearly to 0 at 60. Its 0.8 on gentle
// roofs is what wind and heat take off roofs over a winter (the standard's
// exposure and thermal allowances); in still air a flat roof keeps what the
// ground gets. So the shedding against pitch is compared with mu1 / 0.8,
// the share of a flat roof's snow that a pitched roof keeps, within 0.1 of
// mu1 (0.125 of mu1 / 0.8), and gentle roofs keep the ground's depth.
TEST(SnowPhysics, RoofSnowAgainstPitchFollowsEurocodeMu1) {
  StabilizeSettings settings;  // fresh snow, the defaults
  const float fall = 0.3f;
  std::vector<double> mu;
  std::vector<float> pitches;
  for (float pitch : {1.0f, 15.0f, 30.0f, 40.0f, 45.0f, 50.0f, 55.0f, 60.0f, 70.0f}) {
    HouseDims dims;
    dims.roof_pitch_deg = pitch;
    const Scene scene = make_house_scene(dims);
    const Snowed s = snow_on(scene, 256, fall, settings);
    const int roof = find_object(scene, "HouseRoof");
    const int floor = find_object(scene, "Floor");
    const double ground = mean_depth(
        s, floor, [](float x, float z) { return std::abs(x) > 6.0f && std::abs(z) > 5.0f; });
    const double on_roof = mean_depth(s, roof, [](float, float) { return true; });
    mu.push_back(on_roof / ground);
    pitches.push_back(pitch);
    std::printf(
        "pitch %4.1f  roof %.4f m  ground %.4f m  roof/ground %.3f  x 0.8 = %.3f  "
        "(EN mu1 %.3f)\n",
        pitch, on_roof, ground, mu.back(), 0.8 * mu.back(), en_mu1(pitch));
    EXPECT_NEAR(ground, fall, 0.01 * fall) << pitch;
    EXPECT_NEAR(0.8 * mu.back(), en_mu1(pitch), 0.1) << pitch;
    if (pitch <= 30.0f) {
      EXPECT_GT(mu.back(), 0.97) << pitch;
    }
    // Mass: what lies plus what left equals what fell.
    EXPECT_NEAR(s.lying + s.lost, s.fallen, 1e-5 * s.fallen) << pitch;
  }
  for (size_t k = 1; k < mu.size(); ++k) {
    if (pitches[k - 1] >= 30.0f && pitches[k] <= 60.0f) {
      EXPECT_LT(mu[k], mu[k - 1]) << pitches[k];
    }
  }
}

// A 2 x 2 m block, 1 m tall, on open ground, 0.3 m of fresh snow on 1 cm
// texels: the snow keeps its depth to the edge (a pillow), where loose snow
// would bevel at the repose angle.
TEST(SnowPhysics, SnowOnABlockKeepsItsDepthToTheEdge) {
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, glm::vec2(-2.0f), glm::vec2(2.0f));
  const int block = b.add_box("Block", glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 1.0f, 1.0f));
  const Scene scene = b.build();
  for (const bool cohesive : {true, false}) {
    StabilizeSettings settings;
    if (!cohesive) settings.cohesion = loose_snow();
    const Snowed s = snow_on(scene, 400, 0.3f, settings);
    const double centre = mean_depth(
        s, block, [](float x, float z) { return std::abs(x) < 0.2f && std::abs(z) < 0.2f; });
    const double band = mean_depth(
        s, block, [](float x, float z) { return std::max(std::abs(x), std::abs(z)) > 0.9f; });
    std::printf("%s snow: centre %.4f m, outer 10 cm %.4f m (%.2f of the centre)\n",
                cohesive ? "fresh" : "loose", centre, band, band / centre);
    EXPECT_NEAR(centre, 0.3, 0.01);
    if (cohesive) {
      EXPECT_GE(band / centre, 0.6);
    } else {
      EXPECT_LT(band / centre, 0.6);  // the bevel the cohesion does away with
    }
    EXPECT_NEAR(s.lying + s.lost, s.fallen, 1e-5 * s.fallen);
  }
}

// The snow on a 2 x 2 x 1 m block on a 4 m ground, 0.3 m of it on 1 cm
// texels, meshed with the default settings (empty if it has no patch).
TriMesh block_snow_mesh() {
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, glm::vec2(-2.0f), glm::vec2(2.0f));
  const int block = b.add_box("Block", glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 1.0f, 1.0f));
  const Scene scene = b.build();
  const Snowed s = snow_on(scene, 400, 0.3f, StabilizeSettings{});
  const std::vector<SnowPatch> patches = polygonize(s.maps, s.depth, scene, PolygonizeSettings{});
  for (const SnowPatch& p : patches) {
    if (p.object == block) return p.mesh;
  }
  return {};
}

// The block's snow as a mesh (default polygonize settings): the top rounds
// over its shoulder without a crease sharper than 20 degrees between
// neighbouring top faces (tilted less than 60 degrees and off the outline:
// the steeper ring and the feather edge where the top meets the bottom are
// the snow's side).
TEST(SnowPhysics, ThePillowsShoulderIsSmooth) {
  const TriMesh m = block_snow_mesh();
  ASSERT_FALSE(m.indices.empty());
  std::vector<glm::dvec3> normal(m.indices.size() / 3);
  for (size_t f = 0; f < normal.size(); ++f) {
    const glm::dvec3 a = m.positions[m.indices[3 * f]], b1 = m.positions[m.indices[3 * f + 1]],
                     c = m.positions[m.indices[3 * f + 2]];
    normal[f] = glm::normalize(glm::cross(b1 - a, c - a));
  }
  std::map<std::pair<uint32_t, uint32_t>, size_t> first_face;
  double worst = 0.0;
  size_t pairs = 0;
  const auto on_outline = [&](size_t f) {  // where the snow thins out onto the block (y = 1)
    for (int e = 0; e < 3; ++e) {
      if (m.positions[m.indices[3 * f + size_t(e)]].y < 1.01f) return true;
    }
    return false;
  };
  for (size_t f = 0; f < normal.size(); ++f) {
    if (normal[f].y < 0.5 || on_outline(f)) continue;
    for (int e = 0; e < 3; ++e) {
      uint32_t u = m.indices[3 * f + size_t(e)], v = m.indices[3 * f + size_t(e + 1) % 3];
      if (u > v) std::swap(u, v);
      const auto [it, fresh] = first_face.emplace(std::make_pair(u, v), f);
      if (fresh) continue;
      const double cosine = std::clamp(glm::dot(normal[it->second], normal[f]), -1.0, 1.0);
      const double angle = std::acos(cosine) * 180.0 / M_PI;
      worst = std::max(worst, angle);
      ++pairs;
    }
  }
  std::printf("block's snow: %zu neighbouring top faces, sharpest crease %.1f degrees\n", pairs,
              worst);
  EXPECT_GT(pairs, 100u);
  EXPECT_LE(worst, 20.0);
}

// Where cohesion lets it, the snow bulges past a free edge: on the block the
// mesh reaches beyond the block's sides over the air, with faces looking
// down above the block's top (the lip's underside: no longer a height
// field), and stays a closed 2-manifold.
TEST(SnowPhysics, ThePillowBulgesPastTheEdgeAsAClosedSolid) {
  const TriMesh m = block_snow_mesh();
  ASSERT_FALSE(m.indices.empty());
  const TopologyReport topology = check_topology(m.positions, m.indices);
  EXPECT_TRUE(topology.closed()) << topology.boundary_edges << " boundary, "
                                 << topology.nonmanifold_edges << " non-manifold";
  float reach = 0.0f;
  for (const glm::vec3& p : m.positions) {
    if (p.y > 1.005f) reach = std::max(reach, std::max(std::abs(p.x), std::abs(p.z)) - 1.0f);
  }
  size_t under = 0;
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const glm::vec3 a = m.positions[m.indices[t]], b1 = m.positions[m.indices[t + 1]],
                    c = m.positions[m.indices[t + 2]];
    const glm::vec3 n = glm::cross(b1 - a, c - a);
    if (n.y < -0.1f * glm::length(n) && std::min({a.y, b1.y, c.y}) >= 0.999f) ++under;
  }
  std::printf("block's snow: reaches %.3f m past the edge, %zu faces under the lip\n", reach,
              under);
  EXPECT_GT(reach, 0.02f);
  EXPECT_LT(reach, 0.05f);
  EXPECT_GT(under, 100u);
}

// A 60-degree roof: thin snow clings (SnowSlide's field data: the steeper, the
// less holds; a few centimetres on steep faces), a metre of it mostly sheds.
TEST(SnowPhysics, ThinSnowClingsToASteepRoofAndDeepSnowSheds) {
  HouseDims dims;
  dims.roof_pitch_deg = 60.0f;
  const Scene scene = make_house_scene(dims);
  const int roof = find_object(scene, "HouseRoof");
  const StabilizeSettings settings;
  const auto on_roof = [&](const Snowed& s) {
    return mean_depth(s, roof, [](float, float) { return true; });
  };
  const Snowed thin = snow_on(scene, 256, 0.02f, settings);
  const Snowed deep = snow_on(scene, 256, 1.0f, settings);
  std::printf("60-degree roof: 0.02 m fell, %.4f m stays; 1 m fell, %.4f m stays\n", on_roof(thin),
              on_roof(deep));
  EXPECT_GT(on_roof(thin), 0.9 * 0.02);
  EXPECT_GT(on_roof(deep), 0.01);
  EXPECT_LT(on_roof(deep), 0.1 * 1.0);
}

// The kinds of snow and the grip of surfaces: on a 45-degree roof, powder
// keeps less than fresh snow and wet snow more; a slippery (metal) roof
// keeps less than a normal one and a rough (shingled) one more.
TEST(SnowPhysics, SnowKindsAndSurfaceGripChangeWhatARoofHolds) {
  HouseDims dims;
  dims.roof_pitch_deg = 45.0f;
  const Scene scene = make_house_scene(dims);
  const int roof = find_object(scene, "HouseRoof");
  const auto on_roof = [&](SnowKind kind, float grip) {
    StabilizeSettings settings;
    settings.cohesion = cohesion_of(kind);
    settings.grip.assign(scene.objects.size(), kGripNormal);
    settings.grip[size_t(roof)] = grip;
    const Snowed s = snow_on(scene, 128, 0.3f, settings);
    return mean_depth(s, roof, [](float, float) { return true; });
  };
  const double fresh = on_roof(SnowKind::Fresh, kGripNormal);
  const double powder = on_roof(SnowKind::Powder, kGripNormal);
  const double wet = on_roof(SnowKind::Wet, kGripNormal);
  const double metal = on_roof(SnowKind::Fresh, kGripSlippery);
  const double shingles = on_roof(SnowKind::Fresh, kGripRough);
  std::printf("45-degree roof: powder %.3f, fresh %.3f, wet %.3f; slippery %.3f, rough %.3f m\n",
              powder, fresh, wet, metal, shingles);
  EXPECT_LT(powder, 0.8 * fresh);
  EXPECT_GT(wet, 1.2 * fresh);
  EXPECT_NEAR(metal, 0.5 * fresh, 0.1 * fresh);
  EXPECT_GT(shingles, 1.5 * fresh);
}

// Snow shed from a 50-degree roof lands along the drip line (the eaves
// overhang the walls by 0.5 m) as a mound higher than the snow on open
// ground, and fills the sheltered strip under the eaves: no bare trench
// along the wall.
TEST(SnowPhysics, ShedSnowFormsAMoundAlongTheDripLine) {
  HouseDims dims;
  dims.roof_pitch_deg = 50.0f;
  const Scene scene = make_house_scene(dims);
  const Snowed s = snow_on(scene, 256, 0.3f, StabilizeSettings{});
  const int floor = find_object(scene, "Floor");
  const SnowMaps& m = s.maps;
  const int i = m.grid.width / 2;  // x = 0, across the long wall at z = 2
  float at_wall = -1.0f, peak = 0.0f, peak_z = 0.0f;
  for (int j = 0; j < m.grid.height; ++j) {
    for (int l = 0; l < m.layers; ++l) {
      const size_t k = m.index(l, i, j);
      const float z = m.grid.center(i, j).y;
      if (m.object[k] != floor || z < 2.0f || z > 5.0f) continue;
      if (at_wall < 0.0f) at_wall = s.depth[k];
      if (s.depth[k] > peak) {
        peak = s.depth[k];
        peak_z = z;
      }
    }
  }
  std::printf("drip line: %.3f m against the wall, peak %.3f m at z = %.2f m (eaves at 2.5)\n",
              at_wall, peak, peak_z);
  EXPECT_GE(at_wall, 0.3f);
  EXPECT_GT(peak, 0.45f);
  EXPECT_NEAR(peak_z, 2.5f, 0.3f);
}

// A tufted cushion: a 2 m x 1.2 m heightfield at y = 0.8 m with bumps of
// +-`bump` metres every `period` metres (one-sided, facing up).
Scene tufted_cushion(float bump, float period) {
  constexpr int kN = 96;  // quads along x
  const int nz = int(kN * 0.6f);
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  for (int j = 0; j <= nz; ++j) {
    for (int i = 0; i <= kN; ++i) {
      const float x = -1.0f + 2.0f * float(i) / kN, z = -0.6f + 1.2f * float(j) / nz;
      const float w = 2.0f * float(M_PI) / period;
      positions.push_back({x, 0.8f + bump * std::sin(w * x) * std::sin(w * z), z});
    }
  }
  for (int j = 0; j < nz; ++j) {
    for (int i = 0; i < kN; ++i) {
      const uint32_t a = uint32_t(j * (kN + 1) + i), b = a + 1, c = a + kN + 1, d = c + 1;
      indices.insert(indices.end(), {a, c, b, b, c, d});
    }
  }
  SceneBuilder builder;
  builder.add_mesh("Cushion", positions, indices);
  return builder.build();
}

// Snow that slid is loose (Fearing 2000: cohesion holds snow where it fell;
// what avalanches spreads at its angle of repose). A tufted cushion whose
// bumps are steep enough to shed some of 0.3 m of snow into the dips
// between them: the slid snow fills the dips at most at the repose angle
// plus its jitter (48 degrees) over its neighbours, with no column of slid
// snow held up steeper, as cohesion holds the snow that fell.
TEST(SnowPhysics, SnowThatSlidIsLooseAndStandsAtTheReposeAngle) {
  const Scene scene = tufted_cushion(0.06f, 0.3f);
  const StabilizeSettings settings;
  const Snowed s = snow_on(scene, 200, 0.3f, settings);
  const SnowMaps& m = s.maps;
  const float texel = m.grid.texel;
  // Pairs of neighbours whose higher one holds slid snow (more than fell),
  // and those of them whose snow surfaces differ by more than the limit.
  int steep = 0, pairs = 0;
  const float limit = std::tan(glm::radians(settings.repose_deg + settings.repose_jitter_deg));
  for (int j = 2; j + 2 < m.grid.height; ++j) {
    for (int i = 2; i + 2 < m.grid.width; ++i) {
      for (const glm::ivec2 d : {glm::ivec2(1, 0), glm::ivec2(0, 1)}) {
        size_t k = m.index(0, i, j), n = m.index(0, i + d.x, j + d.y);
        if (std::isnan(m.ground[k]) || std::isnan(m.ground[n])) continue;
        if (m.ground[k] + s.depth[k] < m.ground[n] + s.depth[n]) std::swap(k, n);
        if (!(s.depth[k] > 0.31f)) continue;
        ++pairs;
        if ((m.ground[k] + s.depth[k]) - (m.ground[n] + s.depth[n]) > limit * texel + 1e-3f)
          ++steep;
      }
    }
  }
  std::printf("slid snow: %d pairs, %d steeper than tan 48 degrees\n", pairs, steep);
  EXPECT_GT(pairs, 1000);
  EXPECT_LT(steep, pairs / 100);
}

// Bridging (Fearing 2000): two bench seats of 6 cm slats at 0.45 m, 2 cm
// apart on one, 20 cm apart on the other, on 1 cm texels. Snow spans the
// 2 cm gaps (the seat is one snow cover, the ground under it stays bare) and
// falls through the 20 cm ones.
TEST(SnowPhysics, SnowBridgesNarrowGapsOnly) {
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, glm::vec2(-1.0f), glm::vec2(1.0f));
  const auto seat = [&](const std::string& name, float x0, float gap) {
    for (int k = 0; k < 5; ++k) {
      const float z = -0.5f + float(k) * (0.06f + gap);
      b.add_box(name + std::to_string(k), glm::vec3(x0, 0.42f, z),
                glm::vec3(x0 + 0.6f, 0.45f, z + 0.06f));
    }
  };
  seat("Narrow", -0.8f, 0.02f);
  seat("Wide", 0.1f, 0.2f);
  const Scene scene = b.build();
  const Snowed s = snow_on(scene, 200, 0.3f, StabilizeSettings{});
  const SnowMaps& m = s.maps;
  // Per column along z through each seat's middle (x = -0.5, x = 0.4): the
  // snow on the seat's level and on the ground.
  const auto column = [&](float x, float z, bool seat_level) {
    const int i = int((x - m.grid.origin.x) / m.grid.texel);
    const int j = int((z - m.grid.origin.y) / m.grid.texel);
    for (int l = 0; l < m.layers; ++l) {
      const size_t k = m.index(l, i, j);
      if (std::isnan(m.ground[k])) break;
      if ((m.ground[k] > 0.3f) == seat_level) return double(s.depth[k]);
    }
    return -1.0;  // no surface there
  };
  // The narrow seat's gaps: z = -0.5 + 0.06 + 0.01 + k * 0.08.
  for (int k = 0; k < 4; ++k) {
    const float z = -0.43f + float(k) * 0.08f;
    EXPECT_GT(column(-0.5f, z, true), 0.25) << "narrow gap " << k;
    EXPECT_LT(column(-0.5f, z, false), 0.05) << "ground under narrow gap " << k;
  }
  // The wide seat's gaps: z = -0.5 + 0.06 + 0.1 + k * 0.26, in the middle.
  for (int k = 0; k < 4; ++k) {
    const float z = -0.34f + float(k) * 0.26f;
    EXPECT_EQ(column(0.4f, z, true), -1.0) << "wide gap " << k;
    EXPECT_GT(column(0.4f, z, false), 0.15) << "ground under wide gap " << k;
  }
  EXPECT_NEAR(s.lying + s.lost, s.fallen, 1e-5 * s.fallen);
}

// Maps far finer than the bridge width (found by tools/fuzz: a gap of
// width / texel columns overflowed an int): the gap is still bridged, the
// search bounded by kBridgeMaxTexels.
TEST(SnowPhysics, BridgesOnMapsFarFinerThanTheWidth) {
  SnowMaps maps;
  MapGrid grid;
  grid.texel = 1e-30f;
  grid.width = 8;
  grid.height = 1;
  maps.allocate(grid, 2);
  for (int i = 0; i < 8; ++i) {
    const size_t k = maps.index(0, i, 0);
    maps.ground[k] = i == 4 ? 0.0f : 1.0f;  // a one-texel gap at column 4
    maps.normal[k] = glm::vec3(0.0f, 1.0f, 0.0f);
    maps.object[k] = 0;
  }
  EXPECT_EQ(bridge_gaps(maps, 0.05f), 1u);
  EXPECT_EQ(maps.bridge[4], 0);
  EXPECT_FLOAT_EQ(maps.ground[maps.index(0, 4, 0)], 1.0f);
  EXPECT_FLOAT_EQ(maps.ground[maps.index(1, 4, 0)], 0.0f);
}

// Flat stays flat: 0.3 m of snow on a flat 100 m plane, meshed: the top lies
// within 1 cm of 0.3 m everywhere off its rounded edge, and no two
// neighbouring faces of it meet at more than 5 degrees.
TEST(SnowPhysics, SnowOnFlatGroundIsFlat) {
  SceneBuilder b;
  b.add_plane("Ground", 0.0f, glm::vec2(-50.0f), glm::vec2(50.0f));
  // A block of houses in the middle: the open ground beyond 20 m is flat.
  for (int k = 0; k < 4; ++k) {
    const float x = -12.0f + 8.0f * float(k);
    b.add_box("House" + std::to_string(k), glm::vec3(x, 0.0f, -6.0f),
              glm::vec3(x + 6.0f, 6.0f + 2.0f * float(k), 4.0f));
  }
  const Scene scene = b.build();
  const Snowed s = snow_on(scene, 1024, 0.3f, StabilizeSettings{});
  const std::vector<SnowPatch> patches = polygonize(s.maps, s.depth, scene, PolygonizeSettings{});
  const auto ground = std::find_if(patches.begin(), patches.end(),
                                   [&](const SnowPatch& p) { return p.object == 0; });
  ASSERT_NE(ground, patches.end());
  const TriMesh& m = ground->mesh;
  double low = 1e9, high = -1e9, worst = 0.0;
  std::map<std::pair<uint32_t, uint32_t>, size_t> first_face;
  std::vector<glm::dvec3> normal(m.indices.size() / 3);
  for (size_t f = 0; f < normal.size(); ++f) {
    const glm::dvec3 a = m.positions[m.indices[3 * f]], b1 = m.positions[m.indices[3 * f + 1]],
                     c = m.positions[m.indices[3 * f + 2]];
    normal[f] = glm::normalize(glm::cross(b1 - a, c - a));
  }
  const auto inside = [&](const glm::vec3& p) {  // off the rounded edge, away from the houses
    const float r = std::max(std::abs(p.x), std::abs(p.z));
    return r < 49.0f && r > 25.0f;
  };
  for (size_t f = 0; f < normal.size(); ++f) {
    bool in = normal[f].y > 0.0;
    for (int e = 0; e < 3; ++e) in = in && inside(m.positions[m.indices[3 * f + size_t(e)]]);
    if (!in) continue;
    for (int e = 0; e < 3; ++e) {
      const glm::vec3 p = m.positions[m.indices[3 * f + size_t(e)]];
      low = std::min(low, double(p.y));
      high = std::max(high, double(p.y));
      uint32_t u = m.indices[3 * f + size_t(e)], v = m.indices[3 * f + size_t(e + 1) % 3];
      if (u > v) std::swap(u, v);
      const auto [it, fresh] = first_face.emplace(std::make_pair(u, v), f);
      if (fresh) continue;
      const double cosine = std::clamp(glm::dot(normal[it->second], normal[f]), -1.0, 1.0);
      worst = std::max(worst, std::acos(cosine) * 180.0 / M_PI);
    }
  }
  std::printf(
      "flat 100 m plane: top from %.4f to %.4f m, sharpest crease %.2f degrees, %zu faces\n", low,
      high, worst, normal.size());
  EXPECT_GT(low, 0.29);
  EXPECT_LT(high, 0.31);
  EXPECT_LE(worst, 5.0);
}

}  // namespace
}  // namespace snow
