// Tests for snow::polygonize: synthetic snow maps built in code (flat plane,
// slab with a bump, table over a floor, two patches, roofs); every mesh must
// be a closed, consistently oriented 2-manifold without NaN whose volume
// matches the snow it was made from.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/log.h"
#include "mesh/polygonize.h"
#include "mesh/polygonize/steps.h"
#include "scene/builder.h"

namespace snow {
namespace {

// ---------------------------------------------------------------------------
// Synthetic maps

struct Layer {
  float ground = kNoSurface;
  float ceiling = kOpenSky;
  glm::vec3 normal{0, 1, 0};
  int object = -1;
};

SnowMaps make_maps(int width, int height, float texel, int layers) {
  SnowMaps maps;
  MapGrid grid;
  grid.origin = glm::vec2(-0.5f * float(width) * texel, -0.5f * float(height) * texel);
  grid.texel = texel;
  grid.width = width;
  grid.height = height;
  maps.allocate(grid, layers);
  return maps;
}

void set_layer(SnowMaps& maps, int l, int i, int j, const Layer& layer) {
  const size_t k = maps.index(l, i, j);
  maps.ground[k] = layer.ground;
  maps.ceiling[k] = layer.ceiling;
  maps.normal[k] = layer.normal;
  maps.object[k] = layer.object;
}

Scene names_scene(std::initializer_list<const char*> names) {
  Scene scene;
  for (const char* name : names) {
    SceneObject object;
    object.name = name;
    scene.objects.push_back(object);
  }
  return scene;
}

/// A flat floor (object 0, y = 0) over the whole map.
SnowMaps flat_floor(int size, float texel) {
  SnowMaps maps = make_maps(size, size, texel, 1);
  for (int j = 0; j < size; ++j) {
    for (int i = 0; i < size; ++i) set_layer(maps, 0, i, j, {0.0f, kOpenSky, {0, 1, 0}, 0});
  }
  return maps;
}

double texel_sum(const SnowMaps& maps, const std::vector<float>& depth) {
  double sum = 0.0;
  for (float d : depth) sum += d > 0.005f ? double(d) : 0.0;
  return sum * double(maps.grid.texel) * double(maps.grid.texel);
}

// ---------------------------------------------------------------------------
// Mesh checks

struct MeshReport {
  size_t boundary_edges = 0;     // edges with one face
  size_t nonmanifold_edges = 0;  // edges with more than two faces
  size_t misoriented_edges = 0;  // two faces running the same way along the edge
  size_t nonmanifold_vertices = 0;
  size_t non_finite = 0;  // NaN or inf in positions, normals, uvs
  size_t unit_normal_failures = 0;
};

MeshReport check(const TriMesh& m) {
  MeshReport r;
  std::map<std::pair<uint32_t, uint32_t>, std::vector<bool>> edges;  // forward?
  std::vector<std::map<uint32_t, std::vector<uint32_t>>> link(m.positions.size());
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const uint32_t u = m.indices[t + e], v = m.indices[t + (e + 1) % 3];
      const uint32_t w = m.indices[t + (e + 2) % 3];
      edges[{std::min(u, v), std::max(u, v)}].push_back(u < v);
      link[u][v].push_back(w);  // face (u, v, w): link edge v -> w around u
    }
  }
  for (const auto& [edge, dirs] : edges) {
    if (dirs.size() == 1) ++r.boundary_edges;
    if (dirs.size() > 2) ++r.nonmanifold_edges;
    if (dirs.size() == 2 && dirs[0] == dirs[1]) ++r.misoriented_edges;
  }
  // A vertex is manifold when its link edges form one chain or cycle.
  for (size_t v = 0; v < link.size(); ++v) {
    const auto& l = link[v];
    if (l.empty()) continue;
    size_t link_edges = 0;
    bool branching = false;
    std::map<uint32_t, int> in_degree;
    for (const auto& [a, bs] : l) {
      link_edges += bs.size();
      branching |= bs.size() > 1;
      for (uint32_t b : bs) ++in_degree[b];
    }
    for (const auto& [b, count] : in_degree) branching |= count > 1;
    if (branching) {
      ++r.nonmanifold_vertices;
      continue;
    }
    // Start at a chain's head if there is one, else anywhere; walk.
    uint32_t start = l.begin()->first;
    for (const auto& [a, bs] : l) {
      if (!in_degree.count(a)) start = a;
    }
    size_t walked = 0;
    uint32_t at = start;
    while (walked < link_edges) {
      auto it = l.find(at);
      if (it == l.end()) break;
      at = it->second[0];
      ++walked;
      if (at == start) break;
    }
    if (walked != link_edges) ++r.nonmanifold_vertices;
  }
  auto finite = [](const auto& v) {
    for (int c = 0; c < v.length(); ++c) {
      if (!std::isfinite(v[c])) return false;
    }
    return true;
  };
  for (const auto& p : m.positions) r.non_finite += !finite(p);
  for (const auto& n : m.normals) {
    r.non_finite += !finite(n);
    r.unit_normal_failures += std::abs(glm::length(n) - 1.0f) > 1e-3f;
  }
  for (const auto& uv : m.uvs) r.non_finite += !finite(uv);
  return r;
}

void expect_closed(const SnowPatch& patch) {
  SCOPED_TRACE(patch.mesh.name);
  const MeshReport r = check(patch.mesh);
  EXPECT_GT(patch.mesh.indices.size(), 0u);
  EXPECT_EQ(patch.mesh.indices.size() % 3, 0u);
  EXPECT_EQ(r.boundary_edges, 0u);
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.misoriented_edges, 0u);
  EXPECT_EQ(r.nonmanifold_vertices, 0u);
  EXPECT_EQ(r.non_finite, 0u);
  EXPECT_EQ(r.unit_normal_failures, 0u);
  EXPECT_EQ(patch.mesh.normals.size(), patch.mesh.positions.size());
  ASSERT_EQ(patch.mesh.uvs.size(), patch.mesh.positions.size());
  for (size_t v = 0; v < patch.mesh.positions.size(); ++v) {
    ASSERT_EQ(patch.mesh.uvs[v].x, patch.mesh.positions[v].x);
    ASSERT_EQ(patch.mesh.uvs[v].y, patch.mesh.positions[v].z);
  }
  EXPECT_GT(patch.volume, 0.0);
}

double mesh_volume(const TriMesh& m) {
  double v6 = 0.0;
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const glm::dvec3 a = m.positions[m.indices[t]];
    const glm::dvec3 b = m.positions[m.indices[t + 1]];
    const glm::dvec3 c = m.positions[m.indices[t + 2]];
    v6 += glm::dot(a, glm::cross(b, c));
  }
  return v6 / 6.0;
}

/// Highest point of the mesh's up-facing triangles above plan point (x, z);
/// NaN when none covers it.
double top_height(const TriMesh& m, double x, double z) {
  double best = std::numeric_limits<double>::quiet_NaN();
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    const glm::dvec3 a = m.positions[m.indices[t]];
    const glm::dvec3 b = m.positions[m.indices[t + 1]];
    const glm::dvec3 c = m.positions[m.indices[t + 2]];
    const glm::dvec3 n = glm::cross(b - a, c - a);
    if (n.y <= 0.0) continue;
    // Barycentric coordinates in the (x, z) plane.
    const double det = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
    if (std::abs(det) < 1e-15) continue;
    const double u = ((x - a.x) * (c.z - a.z) - (c.x - a.x) * (z - a.z)) / det;
    const double v = ((b.x - a.x) * (z - a.z) - (x - a.x) * (b.z - a.z)) / det;
    if (u < -1e-9 || v < -1e-9 || u + v > 1.0 + 1e-9) continue;
    const double y = a.y + u * (b.y - a.y) + v * (c.y - a.y);
    if (std::isnan(best) || y > best) best = y;
  }
  return best;
}

size_t triangles(const std::vector<SnowPatch>& patches) {
  size_t n = 0;
  for (const auto& p : patches) n += p.mesh.indices.size() / 3;
  return n;
}

// ---------------------------------------------------------------------------

// Square edges (no shoulders): the tests of the height field's meshing
// (exact tops, volumes, the bottom's coarseness) measure it alone;
// SnowPhysics.ThePillowsShoulderIsSmooth and Polygonize.ShouldersKeepTheVolume
// test the shoulders.
PolygonizeSettings square_edges() {
  PolygonizeSettings settings;
  settings.shoulder_radius = 0.0f;
  return settings;
}

TEST(Polygonize, FlatPlaneEvenSnowIsClosedAndKeepsVolume) {
  const SnowMaps maps = flat_floor(64, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 8; j < 56; ++j) {
    for (int i = 8; i < 56; ++i) depth[maps.index(0, i, j)] = 0.3f;
  }
  const auto patches = polygonize(maps, depth, names_scene({"Floor"}), square_edges());
  ASSERT_EQ(patches.size(), 1u);
  const SnowPatch& p = patches[0];
  expect_closed(p);
  EXPECT_EQ(p.mesh.name, "snow/Floor");
  EXPECT_EQ(p.object, 0);
  EXPECT_EQ(p.texels, 48u * 48u);
  const double expected = texel_sum(maps, depth);
  EXPECT_NEAR(p.depth_volume, expected, 1e-6 * expected);
  EXPECT_NEAR(mesh_volume(p.mesh), p.volume, 1e-9 + 1e-6 * p.volume);
  EXPECT_NEAR(p.volume, expected, 0.05 * expected) << "expected " << expected;
  // Plan area: the 4.8 m square plus the tapered rim, about one texel wide.
  EXPECT_GT(p.area, 4.8 * 4.8 * 0.98);
  EXPECT_LT(p.area, 5.0 * 5.0);
  // Bounds: the top at 0.3, the bottom a hair under the floor.
  float ymin = 1e9f, ymax = -1e9f;
  for (const auto& q : p.mesh.positions) {
    ymin = std::min(ymin, q.y);
    ymax = std::max(ymax, q.y);
  }
  EXPECT_NEAR(ymax, 0.3f, 1e-5f);
  EXPECT_NEAR(ymin, -0.001f, 1e-5f);
  std::printf("flat plane: volume %.4f m^3 vs %.4f m^3 of snow (%+.2f%%), %zu triangles\n",
              p.volume, expected, 100.0 * (p.volume / expected - 1.0), p.mesh.indices.size() / 3);
}

// Rounded shoulders and lips (the default) move snow at the edges and the
// patch keeps it: the even 0.3 m slab, 4.8 m square with free edges all
// round, as a mesh holds the snow of the maps within 1 %, its top within
// 1 cm of 0.3 m.
TEST(Polygonize, ShouldersKeepTheVolume) {
  const SnowMaps maps = flat_floor(64, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 8; j < 56; ++j) {
    for (int i = 8; i < 56; ++i) depth[maps.index(0, i, j)] = 0.3f;
  }
  const auto patches = polygonize(maps, depth, names_scene({"Floor"}), {});
  ASSERT_EQ(patches.size(), 1u);
  const SnowPatch& p = patches[0];
  float ymax = 0.0f;
  for (const glm::vec3& v : p.mesh.positions) ymax = std::max(ymax, v.y);
  std::printf("shoulders: volume %.4f m^3 vs %.4f m^3 of snow, top at %.4f m\n", p.volume,
              p.depth_volume, ymax);
  EXPECT_NEAR(p.volume, p.depth_volume, 0.01 * p.depth_volume);
  EXPECT_NEAR(ymax, 0.3f, 0.01f);
}

// Maps of absurdly fine texels (found by tools/fuzz: the shoulder's width in
// texels overflowed an int; the sanitized build catches a relapse).
TEST(Polygonize, ShouldersOnAbsurdlyFineMaps) {
  const SnowMaps maps = flat_floor(16, 1e-30f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 4; j < 12; ++j) {
    for (int i = 4; i < 12; ++i) depth[maps.index(0, i, j)] = 0.3f;
  }
  PolygonizeSettings settings;
  settings.min_patch_area = 0.0f;
  EXPECT_NO_THROW(polygonize(maps, depth, names_scene({"Floor"}), settings));
}

// Shoulders on thin snow and on narrow strips (a parapet's cap, a sill):
// 5 cm of snow keeps its depth a shoulder's width from the edge, and a strip
// narrower than two shoulders rounds over its width instead of vanishing.
TEST(Polygonize, ShouldersKeepThinSnowAndNarrowStrips) {
  const SnowMaps maps = flat_floor(64, 0.02f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 8; j < 56; ++j) {
    for (int i = 8; i < 30; ++i) depth[maps.index(0, i, j)] = 0.05f;  // thin snow, 44 cm wide
    for (int i = 40; i < 45; ++i) depth[maps.index(0, i, j)] = 0.3f;  // a strip 10 cm wide
  }
  const auto patches = polygonize(maps, depth, names_scene({"Floor"}), {});
  ASSERT_EQ(patches.size(), 2u);
  for (const SnowPatch& p : patches) {
    float top = 0.0f;
    for (const glm::vec3& v : p.mesh.positions) top = std::max(top, v.y);
    std::printf("%s: top %.4f m, volume %.4f m^3 vs %.4f m^3 of snow\n",
                p.texels > 600 ? "thin snow" : "narrow strip", top, p.volume, p.depth_volume);
    EXPECT_NEAR(p.volume, p.depth_volume, 0.05 * p.depth_volume);
    if (p.texels > 600) {
      EXPECT_NEAR(top, 0.05f, 0.01f);  // raised by what the shoulders give up
    } else {
      EXPECT_GT(top, 0.25f);
    }
  }
}

TEST(Polygonize, FlatPlaneDecimatesEightfoldWithinTheErrorBound) {
  const SnowMaps maps = flat_floor(64, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 8; j < 56; ++j) {
    for (int i = 8; i < 56; ++i) depth[maps.index(0, i, j)] = 0.3f;
  }
  const Scene scene = names_scene({"Floor"});
  PolygonizeSettings full;
  full.decimate_error = 0.0f;
  const auto dense = polygonize(maps, depth, scene, full);
  PolygonizeSettings settings;  // error: half a texel = 0.05 m
  const auto coarse = polygonize(maps, depth, scene, settings);
  ASSERT_EQ(dense.size(), 1u);
  ASSERT_EQ(coarse.size(), 1u);
  expect_closed(dense[0]);
  expect_closed(coarse[0]);
  const double ratio = double(triangles(dense)) / double(triangles(coarse));
  std::printf("flat plane decimation: %zu -> %zu triangles (%.1fx)\n", triangles(dense),
              triangles(coarse), ratio);
  EXPECT_GE(ratio, 8.0);
  // The decimated top stays within the bound of the full-resolution top at
  // every texel centre of the patch and on a finer grid in between.
  const double bound = 0.5 * 0.1 + 1e-4;
  double worst = 0.0;
  for (int j = 8; j < 56; ++j) {
    for (int i = 8; i < 56; ++i) {
      for (double fj : {0.0, 0.5}) {
        for (double fi : {0.0, 0.5}) {
          if ((i == 55 && fi > 0) || (j == 55 && fj > 0)) continue;
          const glm::vec2 c = maps.grid.center(i, j) + glm::vec2(fi, fj) * 0.1f;
          const double a = top_height(dense[0].mesh, c.x, c.y);
          const double b = top_height(coarse[0].mesh, c.x, c.y);
          ASSERT_FALSE(std::isnan(a));
          ASSERT_FALSE(std::isnan(b));
          worst = std::max(worst, std::abs(a - b));
        }
      }
    }
  }
  std::printf("flat plane decimation: worst top height change %.5f m (bound %.3f m)\n", worst,
              bound);
  EXPECT_LE(worst, bound);
  EXPECT_NEAR(coarse[0].volume, dense[0].volume, 0.02 * dense[0].volume);
}

TEST(Polygonize, SlabWithBumpKeepsVolumeAndPeak) {
  const SnowMaps maps = flat_floor(64, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 6; j < 58; ++j) {
    for (int i = 6; i < 58; ++i) {
      const glm::vec2 c = maps.grid.center(i, j) - glm::vec2(0.5f, -0.3f);
      depth[maps.index(0, i, j)] = 0.2f + 0.4f * std::exp(-glm::dot(c, c) / (0.8f * 0.8f));
    }
  }
  const auto patches = polygonize(maps, depth, names_scene({"Ground"}), {});
  ASSERT_EQ(patches.size(), 1u);
  expect_closed(patches[0]);
  const double expected = texel_sum(maps, depth);
  EXPECT_NEAR(patches[0].volume, expected, 0.05 * expected);
  // Smoothing and decimation may lower the peak a little, not much.
  const double peak = top_height(patches[0].mesh, 0.5, -0.3);
  EXPECT_GT(peak, 0.6 - 0.05 - 0.03);
  EXPECT_LT(peak, 0.6 + 0.05);
  // Decimation keeps the top within its bound (half a texel) of the full
  // resolution top at every texel centre.
  PolygonizeSettings full;
  full.decimate_error = 0.0f;
  const auto dense = polygonize(maps, depth, names_scene({"Ground"}), full);
  ASSERT_EQ(dense.size(), 1u);
  double worst = 0.0;
  for (int j = 6; j < 58; ++j) {
    for (int i = 6; i < 58; ++i) {
      const glm::vec2 c = maps.grid.center(i, j);
      worst = std::max(worst, std::abs(top_height(dense[0].mesh, c.x, c.y) -
                                       top_height(patches[0].mesh, c.x, c.y)));
    }
  }
  EXPECT_LE(worst, 0.05);
  std::printf("bump: %zu -> %zu triangles (%.1fx), worst top height change %.4f m\n",
              triangles(dense), triangles(patches),
              double(triangles(dense)) / double(triangles(patches)), worst);
  std::printf("bump: volume %.4f m^3 vs %.4f m^3 (%+.2f%%), peak %.3f m, %zu triangles\n",
              patches[0].volume, expected, 100.0 * (patches[0].volume / expected - 1.0), peak,
              patches[0].mesh.indices.size() / 3);
}

/// Floor (object 0) under a table top (object 1) over columns [20, 44)^2:
/// layer 0 table top y = 0.75, layer 1 its underside y = 0.7 (ceiling 0.75),
/// layer 2 the floor (ceiling 0.7); elsewhere layer 0 is the floor.
SnowMaps table_maps(int size) {
  SnowMaps maps = make_maps(size, size, 0.1f, 3);
  for (int j = 0; j < size; ++j) {
    for (int i = 0; i < size; ++i) {
      const bool under = i >= 20 && i < 44 && j >= 20 && j < 44;
      if (under) {
        set_layer(maps, 0, i, j, {0.75f, kOpenSky, {0, 1, 0}, 1});
        set_layer(maps, 1, i, j, {0.70f, 0.75f, {0, -1, 0}, 1});
        set_layer(maps, 2, i, j, {0.0f, 0.70f, {0, 1, 0}, 0});
      } else {
        set_layer(maps, 0, i, j, {0.0f, kOpenSky, {0, 1, 0}, 0});
      }
    }
  }
  return maps;
}

TEST(Polygonize, TableAndFloorAreTwoPatchesAcrossLayers) {
  const SnowMaps maps = table_maps(64);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  double table_snow = 0.0, floor_snow = 0.0;
  for (int j = 0; j < 64; ++j) {
    for (int i = 0; i < 64; ++i) {
      const bool under = i >= 20 && i < 44 && j >= 20 && j < 44;
      const bool deep_under = i >= 23 && i < 41 && j >= 23 && j < 41;
      if (under) {
        depth[maps.index(0, i, j)] = 0.2f;  // table top
        table_snow += 0.2 * 0.01;
        // Snow blown three texels under the table edge, on layer 2.
        if (!deep_under) {
          depth[maps.index(2, i, j)] = 0.25f;
          floor_snow += 0.25 * 0.01;
        }
      } else if (i >= 4 && i < 60 && j >= 4 && j < 60) {
        depth[maps.index(0, i, j)] = 0.25f;
        floor_snow += 0.25 * 0.01;
      }
    }
  }
  const auto patches = polygonize(maps, depth, names_scene({"Floor", "TableTop"}), {});
  ASSERT_EQ(patches.size(), 2u);
  std::map<std::string, const SnowPatch*> by_name;
  for (const auto& p : patches) {
    expect_closed(p);
    by_name[p.mesh.name] = &p;
  }
  ASSERT_TRUE(by_name.count("snow/Floor"));
  ASSERT_TRUE(by_name.count("snow/TableTop"));
  const SnowPatch& floor = *by_name["snow/Floor"];
  const SnowPatch& table = *by_name["snow/TableTop"];
  EXPECT_EQ(floor.object, 0);
  EXPECT_EQ(table.object, 1);
  // The band under the table is part of the floor patch.
  EXPECT_NEAR(floor.depth_volume, floor_snow, 1e-4);
  EXPECT_NEAR(table.depth_volume, table_snow, 1e-4);
  EXPECT_NEAR(floor.volume, floor_snow, 0.05 * floor_snow);
  EXPECT_NEAR(table.volume, table_snow, 0.05 * table_snow);
  // Floor snow stays under the table top, table snow on it.
  for (const auto& q : floor.mesh.positions) EXPECT_LT(q.y, 0.26f);
  for (const auto& q : table.mesh.positions) EXPECT_GT(q.y, 0.74f);
  std::printf("table: floor %.4f m^3 vs %.4f (%+.2f%%), table %.4f vs %.4f (%+.2f%%)\n",
              floor.volume, floor_snow, 100.0 * (floor.volume / floor_snow - 1.0), table.volume,
              table_snow, 100.0 * (table.volume / table_snow - 1.0));
}

// Floor under the open sky on both sides of a bridge that spans the map:
// the two open parts meet only through the columns under the bridge (two
// surfaces each), so the patch walks through them. With the north part
// raised beyond the connecting step, the floor falls into two patches, even
// where the bridge is not (the step runs the full width).
TEST(Polygonize, OpenFloorJoinsThroughColumnsUnderABridge) {
  const int size = 48;
  for (const float raise : {0.0f, 0.5f}) {
    SCOPED_TRACE(raise);
    SnowMaps maps = make_maps(size, size, 0.1f, 3);
    std::vector<float> depth(maps.ground.size(), 0.0f);
    for (int j = 0; j < size; ++j) {
      for (int i = 0; i < size; ++i) {
        const float floor = j >= 24 ? raise : 0.0f;
        if (j >= 20 && j < 28) {  // under the bridge deck (2.0-2.2 m)
          set_layer(maps, 0, i, j, {2.2f, kOpenSky, {0, 1, 0}, 1});
          set_layer(maps, 1, i, j, {2.0f, 2.2f, {0, -1, 0}, 1});
          set_layer(maps, 2, i, j, {floor, 2.0f, {0, 1, 0}, 0});
          depth[maps.index(2, i, j)] = 0.2f;
        } else {
          set_layer(maps, 0, i, j, {floor, kOpenSky, {0, 1, 0}, 0});
          depth[maps.index(0, i, j)] = 0.2f;
        }
      }
    }
    const auto patches = polygonize(maps, depth, names_scene({"Floor", "Bridge"}), {});
    const double texel_area = 0.1 * 0.1;
    if (raise == 0.0f) {
      ASSERT_EQ(patches.size(), 1u);
      EXPECT_EQ(patches[0].mesh.name, "snow/Floor");
      EXPECT_EQ(patches[0].texels, size_t(size * size));
      EXPECT_NEAR(patches[0].depth_volume, size * size * 0.2 * texel_area, 1e-6);
    } else {
      ASSERT_EQ(patches.size(), 2u);
      for (const SnowPatch& p : patches) {
        EXPECT_EQ(p.object, 0);
        EXPECT_EQ(p.texels, size_t(size * size / 2));
        expect_closed(p);
      }
      // In seed order: the south part (rows 0-23) first.
      for (const auto& q : patches[0].mesh.positions) EXPECT_LT(q.y, 0.21f);
      for (const auto& q : patches[1].mesh.positions) EXPECT_GT(q.y, 0.49f);
    }
  }
}

// A floor that is the top of a slab (its underside a second layer, as a
// closed ground gives) meshes as the same floor alone: snow on the slab's
// top joins as on a one-surface floor, also across a step too high to join.
TEST(Polygonize, SlabUndersideChangesNothing) {
  const int size = 48;
  std::vector<std::vector<SnowPatch>> results;
  for (const int layers : {1, 2}) {
    SnowMaps maps = make_maps(size, size, 0.1f, layers);
    std::vector<float> depth(maps.ground.size(), 0.0f);
    for (int j = 0; j < size; ++j) {
      for (int i = 0; i < size; ++i) {
        const float floor = i >= 30 ? 0.5f : 0.0f;
        set_layer(maps, 0, i, j, {floor, kOpenSky, {0, 1, 0}, 0});
        if (layers == 2) set_layer(maps, 1, i, j, {-0.3f, floor, {0, -1, 0}, 0});
        depth[maps.index(0, i, j)] = 0.2f + 0.05f * std::sin(0.7f * float(i)) * float(j % 3);
      }
    }
    results.push_back(polygonize(maps, depth, names_scene({"Slab"}), {}));
  }
  ASSERT_EQ(results[0].size(), 2u);  // the step splits the floor
  ASSERT_EQ(results[1].size(), results[0].size());
  for (size_t p = 0; p < results[0].size(); ++p) {
    expect_closed(results[1][p]);
    EXPECT_EQ(results[1][p].texels, results[0][p].texels);
    EXPECT_EQ(results[1][p].mesh.positions, results[0][p].mesh.positions);
    EXPECT_EQ(results[1][p].mesh.indices, results[0][p].mesh.indices);
  }
}

TEST(Polygonize, TwoSeparatePatchesGetUniqueNames) {
  const SnowMaps maps = flat_floor(48, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 10; j < 30; ++j) {
    for (int i = 4; i < 20; ++i) depth[maps.index(0, i, j)] = 0.15f;
    for (int i = 26; i < 44; ++i) depth[maps.index(0, i, j)] = 0.10f;
  }
  const auto patches = polygonize(maps, depth, names_scene({"Floor"}), square_edges());
  ASSERT_EQ(patches.size(), 2u);
  EXPECT_EQ(patches[0].mesh.name, "snow/Floor");
  EXPECT_EQ(patches[1].mesh.name, "snow/Floor_2");
  const double expected[2] = {16 * 20 * 0.01 * 0.15, 18 * 20 * 0.01 * 0.10};
  for (int p = 0; p < 2; ++p) {
    expect_closed(patches[size_t(p)]);
    EXPECT_NEAR(patches[size_t(p)].volume, expected[p], 0.05 * expected[p]);
  }
  // The patches do not touch: their x ranges are apart.
  float max0 = -1e9f, min1 = 1e9f;
  for (const auto& q : patches[0].mesh.positions) max0 = std::max(max0, q.x);
  for (const auto& q : patches[1].mesh.positions) min1 = std::min(min1, q.x);
  EXPECT_LT(max0, min1);
}

/// A gable roof (object 0 "Roof.002") over columns i in [8, 56), ridge along
/// z at the map centre, pitch 30 degrees, eaves at y = 3; the floor
/// (object 1) lies under it on layer 1 and around it on layer 0.
SnowMaps roof_maps(int size, float pitch_deg, bool gable) {
  SnowMaps maps = make_maps(size, size, 0.1f, 3);
  const float slope = std::tan(glm::radians(pitch_deg));
  const float ridge_x = 0.0f, x0 = maps.grid.center(8, 0).x;
  for (int j = 0; j < size; ++j) {
    for (int i = 0; i < size; ++i) {
      const glm::vec2 c = maps.grid.center(i, j);
      if (i >= 8 && i < size - 8 && j >= 4 && j < size - 4) {
        const float run = gable ? (ridge_x - std::abs(c.x - ridge_x)) - x0 : c.x - x0;
        const float y = 3.0f + slope * run;
        const float sx = gable ? (c.x < ridge_x ? slope : -slope) : slope;
        const glm::vec3 n = glm::normalize(glm::vec3(-sx, 1.0f, 0.0f));
        set_layer(maps, 0, i, j, {y, kOpenSky, n, 0});
        set_layer(maps, 1, i, j, {y - 0.2f, y, -n, 0});
        set_layer(maps, 2, i, j, {0.0f, y - 0.2f, {0, 1, 0}, 1});
      } else {
        set_layer(maps, 0, i, j, {0.0f, kOpenSky, {0, 1, 0}, 1});
      }
    }
  }
  return maps;
}

TEST(Polygonize, SlopedRoofIsOnePatchNamedAfterTheRoof) {
  for (bool gable : {false, true}) {
    SCOPED_TRACE(gable ? "gable" : "shed");
    const SnowMaps maps = roof_maps(64, 30.0f, gable);
    std::vector<float> depth(maps.ground.size(), 0.0f);
    for (int j = 4; j < 60; ++j) {
      for (int i = 8; i < 56; ++i) depth[maps.index(0, i, j)] = 0.15f;
    }
    const auto patches = polygonize(maps, depth, names_scene({"Roof.002", "Floor"}), {});
    ASSERT_EQ(patches.size(), 1u);
    expect_closed(patches[0]);
    EXPECT_EQ(patches[0].mesh.name, "snow/Roof.002");
    const double expected = texel_sum(maps, depth);
    EXPECT_NEAR(patches[0].volume, expected, 0.05 * expected);
    // The snow follows the roof: 0.15 m above it in the middle of a slope.
    const glm::vec2 c = maps.grid.center(16, 32);
    const float ground = maps.ground[maps.index(0, 16, 32)];
    EXPECT_NEAR(top_height(patches[0].mesh, c.x, c.y), ground + 0.15, 0.03);
    std::printf("%s roof: volume %.4f m^3 vs %.4f (%+.2f%%), %zu triangles\n",
                gable ? "gable" : "shed", patches[0].volume, expected,
                100.0 * (patches[0].volume / expected - 1.0), patches[0].mesh.indices.size() / 3);
  }
}

TEST(Polygonize, RoofAndGroundSnowStaySeparate) {
  const SnowMaps maps = roof_maps(64, 20.0f, false);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 0; j < 64; ++j) {
    for (int i = 0; i < 64; ++i) {
      depth[maps.index(0, i, j)] = 0.2f;  // roof, and floor around it
    }
  }
  const auto patches = polygonize(maps, depth, names_scene({"Roof", "Floor"}), {});
  ASSERT_EQ(patches.size(), 2u);
  std::set<std::string> names;
  for (const auto& p : patches) {
    expect_closed(p);
    names.insert(p.mesh.name);
  }
  EXPECT_EQ(names, (std::set<std::string>{"snow/Roof", "snow/Floor"}));
}

TEST(Polygonize, OpenTopSurfacesOnly) {
  const SnowMaps maps = flat_floor(32, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  for (int j = 4; j < 28; ++j) {
    for (int i = 4; i < 28; ++i) depth[maps.index(0, i, j)] = 0.2f;
  }
  PolygonizeSettings settings;
  settings.closed = false;
  const auto open = polygonize(maps, depth, names_scene({"Floor"}), settings);
  const auto closed = polygonize(maps, depth, names_scene({"Floor"}), {});
  ASSERT_EQ(open.size(), 1u);
  ASSERT_EQ(closed.size(), 1u);
  const MeshReport r = check(open[0].mesh);
  EXPECT_GT(r.boundary_edges, 0u);
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.misoriented_edges, 0u);
  EXPECT_EQ(r.non_finite, 0u);
  EXPECT_LT(open[0].mesh.indices.size(), closed[0].mesh.indices.size());
  for (size_t t = 0; t < open[0].mesh.indices.size(); t += 3) {
    const glm::vec3 a = open[0].mesh.positions[open[0].mesh.indices[t]];
    const glm::vec3 b = open[0].mesh.positions[open[0].mesh.indices[t + 1]];
    const glm::vec3 c = open[0].mesh.positions[open[0].mesh.indices[t + 2]];
    ASSERT_GT(glm::cross(b - a, c - a).y, 0.0f) << "triangle " << t / 3;
  }
  // The open boundary lies on the floor.
  for (const auto& q : open[0].mesh.positions) EXPECT_GE(q.y, -1e-6f);
  EXPECT_NEAR(open[0].volume, closed[0].volume, 1e-9);
}

TEST(Polygonize, SmallPatchesAreDroppedAndBadInputRejected) {
  const SnowMaps maps = flat_floor(32, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  depth[maps.index(0, 5, 5)] = 0.1f;  // one texel: about 0.02 m^2 with its taper
  for (int j = 12; j < 28; ++j) {
    for (int i = 12; i < 28; ++i) depth[maps.index(0, i, j)] = 0.1f;
  }
  depth[maps.index(0, 2, 20)] = std::numeric_limits<float>::quiet_NaN();
  depth[maps.index(0, 3, 20)] = -1.0f;
  depth[maps.index(0, 5, 9)] = 0.1f;  // and two more single texels
  depth[maps.index(0, 9, 5)] = 0.1f;
  PolygonizeSettings settings;
  settings.min_patch_area = 0.1f;
  // The small patches dropped are reported in one line, not one each.
  const LogLevel level = log_level();
  set_log_level(LogLevel::Debug);
  testing::internal::CaptureStderr();
  const auto patches = polygonize(maps, depth, names_scene({"Floor"}), settings);
  const std::string log = testing::internal::GetCapturedStderr();
  set_log_level(level);
  EXPECT_NE(log.find("dropped 3 snow patches under the smallest area kept, 0.1 m^2"),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find("dropped", log.find("dropped") + 1), std::string::npos) << log;
  ASSERT_EQ(patches.size(), 1u);
  EXPECT_EQ(patches[0].texels, 16u * 16u);
  settings.min_patch_area = 0.0f;
  const auto all = polygonize(maps, depth, names_scene({"Floor"}), settings);
  ASSERT_EQ(all.size(), 4u);
  for (const auto& p : all) expect_closed(p);

  std::vector<float> short_depth(10, 0.1f);
  EXPECT_THROW(polygonize(maps, short_depth, Scene{}, {}), InputError);
  // Unknown object indices still give a name.
  const auto unnamed = polygonize(maps, depth, Scene{}, {});
  ASSERT_EQ(unnamed.size(), 1u);
  EXPECT_EQ(unnamed[0].mesh.name, "snow/patch");
}

TEST(Polygonize, NoSnowGivesNoPatches) {
  const SnowMaps maps = flat_floor(16, 0.1f);
  std::vector<float> depth(maps.ground.size(), 0.001f);  // under min_thickness
  EXPECT_TRUE(polygonize(maps, depth, names_scene({"Floor"}), {}).empty());
  SnowMaps empty;
  EXPECT_TRUE(polygonize(empty, {}, Scene{}, {}).empty());
}

/// Noisy snow (what the stabilizer's jitter leaves) over a wavy ground: the
/// meshes must still be closed.
/// Noisy snow on wavy ground: a hill of deeper snow and scattered specks,
/// on a map of size x size texels.
void wavy_noisy(SnowMaps& maps, std::vector<float>& depth, int size = 64, float texel = 0.05f) {
  maps = make_maps(size, size, texel, 1);
  uint32_t state = 12345u;
  auto noise = [&]() {
    state = state * 1664525u + 1013904223u;
    return float(state >> 8) / float(1u << 24);
  };
  for (int j = 0; j < size; ++j) {
    for (int i = 0; i < size; ++i) {
      const glm::vec2 c = maps.grid.center(i, j);
      const float y = 0.2f * std::sin(2.0f * c.x) * std::cos(1.5f * c.y);
      const float sx = 0.4f * std::cos(2.0f * c.x) * std::cos(1.5f * c.y);
      const float sz = -0.3f * std::sin(2.0f * c.x) * std::sin(1.5f * c.y);
      set_layer(maps, 0, i, j, {y, kOpenSky, glm::normalize(glm::vec3(-sx, 1, -sz)), 0});
    }
  }
  depth.assign(maps.ground.size(), 0.0f);
  for (int j = 0; j < size; ++j) {
    for (int i = 0; i < size; ++i) {
      const glm::vec2 c = maps.grid.center(i, j);
      const float r = glm::length(c) + 0.3f * noise();
      depth[maps.index(0, i, j)] =
          r < 1.2f ? 0.1f + 2.0f * texel * noise() : (noise() < 0.1f ? 0.05f : 0.0f);
    }
  }
}

TEST(Polygonize, NoisySnowOnWavyGroundStaysClosed) {
  SnowMaps maps;
  std::vector<float> depth;
  wavy_noisy(maps, depth);
  const auto patches = polygonize(maps, depth, names_scene({"Hill"}), {});
  ASSERT_GE(patches.size(), 1u);
  double volume = 0.0, depth_volume = 0.0;
  for (const auto& p : patches) {
    expect_closed(p);
    volume += p.volume;
    depth_volume += p.depth_volume;
  }
  EXPECT_NEAR(patches[0].volume, patches[0].depth_volume, 0.05 * patches[0].depth_volume);
  std::printf("noisy: %zu patches, volume %.4f m^3 vs %.4f m^3 of snow in them\n", patches.size(),
              volume, depth_volume);
}

/// The patches decimated whole and in pieces of 20000 top triangles; these
/// really are decimated in pieces (no note of a fall back to one piece).
std::pair<std::vector<SnowPatch>, std::vector<SnowPatch>> whole_and_in_pieces(
    const SnowMaps& maps, const std::vector<float>& depth, const Scene& scene) {
  PolygonizeSettings whole = square_edges();
  whole.piece_triangles = 0;
  PolygonizeSettings split = square_edges();
  split.piece_triangles = 20000;
  auto a = polygonize(maps, depth, scene, whole);
  const LogLevel level = log_level();
  set_log_level(LogLevel::Debug);
  testing::internal::CaptureStderr();
  auto b = polygonize(maps, depth, scene, split);
  const std::string log = testing::internal::GetCapturedStderr();
  set_log_level(level);
  EXPECT_EQ(log.find("decimating it whole"), std::string::npos) << log;
  return {std::move(a), std::move(b)};
}

TEST(Polygonize, LargePatchDecimatedInPiecesJoinsClosed) {
  // The hill is about 280 texels wide, so its top is cut into strips of 16.
  SnowMaps maps;
  std::vector<float> depth;
  wavy_noisy(maps, depth, 400, 0.008f);
  // The hill's top has a few ten thousand triangles: a few pieces.
  const auto [a, b] = whole_and_in_pieces(maps, depth, names_scene({"Hill"}));
  ASSERT_GE(a.size(), 1u);
  ASSERT_EQ(a.size(), b.size());
  for (const auto& p : b) expect_closed(p);
  // The hill is the largest patch; its seams keep their full-grid vertices,
  // so it has more triangles than when decimated whole, and the same volume.
  const auto largest = [](const std::vector<SnowPatch>& patches) {
    return *std::max_element(
        patches.begin(), patches.end(),
        [](const SnowPatch& p, const SnowPatch& q) { return p.volume < q.volume; });
  };
  const SnowPatch& ha = largest(a);
  const SnowPatch& hb = largest(b);
  std::printf("hill decimated whole: %zu triangles, %.5f m^3; in pieces: %zu, %.5f m^3\n",
              ha.mesh.indices.size() / 3, ha.volume, hb.mesh.indices.size() / 3, hb.volume);
  EXPECT_GT(hb.mesh.indices.size(), ha.mesh.indices.size());
  EXPECT_LE(hb.mesh.indices.size(), ha.mesh.indices.size() * 5 / 4);
  EXPECT_NEAR(hb.volume, ha.volume, 0.01 * ha.volume);
  EXPECT_NEAR(hb.area, ha.area, 1e-9);
}

TEST(Polygonize, BottomOverFlatGroundIsCoarseAlsoInPieces) {
  // Rough snow on a flat floor: a top of many triangles, a bottom that needs
  // few, whole or in pieces.
  const SnowMaps maps = flat_floor(400, 0.008f);
  std::vector<float> depth(maps.ground.size(), 0.0f);
  uint32_t state = 777u;
  for (int j = 20; j < 380; ++j) {
    for (int i = 20; i < 380; ++i) {
      state = state * 1664525u + 1013904223u;
      depth[maps.index(0, i, j)] = 0.05f + 0.03f * float(state >> 8) / float(1u << 24);
    }
  }
  const auto [a, b] = whole_and_in_pieces(maps, depth, names_scene({"Floor"}));
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  // Faces facing up (the top's) or down (the bottom's).
  const auto faces = [](const TriMesh& m, bool up) {
    size_t count = 0;
    for (size_t t = 0; t < m.indices.size(); t += 3) {
      const glm::dvec3 p0 = m.positions[m.indices[t]], p1 = m.positions[m.indices[t + 1]],
                       p2 = m.positions[m.indices[t + 2]];
      count += size_t((glm::cross(p1 - p0, p2 - p0).y > 0.0) == up);
    }
    return count;
  };
  for (const auto* patch : {&a[0], &b[0]}) {
    expect_closed(*patch);
    const size_t top = faces(patch->mesh, true), bottom = faces(patch->mesh, false);
    std::printf("rough snow on a flat floor (%s): %zu top faces, %zu bottom faces\n",
                patch == &a[0] ? "whole" : "in pieces", top, bottom);
    // The bottom over flat ground needs an order of magnitude fewer faces
    // than the rough top (a bottom on the top's triangles, decimated, would
    // keep far more).
    EXPECT_LT(bottom * 10, top);
  }
  // In pieces, the seams keep their vertices: more top faces.
  EXPECT_GT(faces(b[0].mesh, true), faces(a[0].mesh, true));
  EXPECT_NEAR(b[0].volume, a[0].volume, 1e-3 * a[0].volume);
}

// A sliver (three corners on a line) in a closed solid: a glTF reader drops
// it and the solid opens. flip_degenerate_faces flips it away: a
// tetrahedron whose edge p0-p1 carries its midpoint m on one side (faces
// (p0, m, p2), (m, p1, p2) and the sliver (p0, p1, m)) stays closed, keeps
// its volume and holds no degenerate face after.
TEST(Polygonize, SliversAreFlippedAway) {
  poly::Solid solid;
  solid.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.5, 0, 0}};
  solid.tris = {0, 4, 2, 4, 1, 2, 0, 1, 4, 1, 0, 3, 0, 2, 3, 1, 3, 2};
  solid.top.assign(solid.tris.size() / 3, 0);
  std::vector<glm::vec3> positions(solid.positions.begin(), solid.positions.end());
  ASSERT_TRUE(check_topology(positions, solid.tris).closed());
  ASSERT_TRUE(poly::degenerate_face(solid.positions[0], solid.positions[1], solid.positions[4]));
  const double before = signed_volume(positions, solid.tris);
  EXPECT_EQ(poly::flip_degenerate_faces(solid), 0u);
  for (size_t f = 0; f < solid.tris.size() / 3; ++f) {
    EXPECT_FALSE(poly::degenerate_face(solid.positions[solid.tris[3 * f]],
                                       solid.positions[solid.tris[3 * f + 1]],
                                       solid.positions[solid.tris[3 * f + 2]]))
        << f;
  }
  EXPECT_TRUE(check_topology(positions, solid.tris).closed());
  EXPECT_NEAR(signed_volume(positions, solid.tris), before, 1e-12);
  EXPECT_NEAR(std::abs(before), 1.0 / 6.0, 1e-12);
}

}  // namespace
}  // namespace snow
