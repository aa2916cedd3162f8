// Tests of stage 1 (src/snow/peel.h): map grid, memory guard, GPU depth
// peeling against the CPU reference (src/snow/reference/peel_ref.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "scene/builder.h"
#include "snow/gpu_scene.h"
#include "snow/peel.h"
#include "snow/reference/peel_ref.h"
#include "support/gl_context.h"

namespace snow {
namespace {

// The GPU passes unless `device` says otherwise ("auto" would peel these
// maps on the CPU under llvmpipe).
PeelSettings settings_with_side(int side, int layers = 8, const char* device = "gpu") {
  PeelSettings s;
  s.max_side = side;
  s.layers = layers;
  s.device = device;
  return s;
}

// Index of the texel whose centre is nearest to world (x, z).
glm::ivec2 texel_at(const MapGrid& g, float x, float z) {
  return glm::ivec2(int(std::floor((x - g.origin.x) / g.texel)),
                    int(std::floor((z - g.origin.y) / g.texel)));
}

struct Agreement {
  size_t compared = 0;
  size_t mismatched = 0;
  float max_height_error = 0;
};

// Compares every layer texel of two map sets; texels where only one has a
// surface (ties on triangle edges), or where objects differ, count as
// mismatches; heights of matching texels are compared exactly otherwise.
Agreement compare_maps(const SnowMaps& a, const SnowMaps& b) {
  Agreement r;
  EXPECT_EQ(a.grid.width, b.grid.width);
  EXPECT_EQ(a.layers, b.layers);
  for (size_t k = 0; k < a.ground.size(); ++k) {
    const bool ha = !std::isnan(a.ground[k]), hb = !std::isnan(b.ground[k]);
    if (!ha && !hb) continue;
    ++r.compared;
    if (ha != hb || a.object[k] != b.object[k] || glm::dot(a.normal[k], b.normal[k]) < 0.999f ||
        (std::isinf(a.ceiling[k]) != std::isinf(b.ceiling[k]))) {
      ++r.mismatched;
      continue;
    }
    r.max_height_error = std::max(r.max_height_error, std::abs(a.ground[k] - b.ground[k]));
    if (!std::isinf(a.ceiling[k])) {
      r.max_height_error = std::max(r.max_height_error, std::abs(a.ceiling[k] - b.ceiling[k]));
    }
  }
  return r;
}

TEST(WeldVertices, EqualCornersBecomeOneVertex) {
  // Two triangles sharing an edge, a third apart, and a corner at -0 beside
  // one at +0 (equal as floats: one vertex).
  const std::vector<glm::vec3> corners = {
      {0, 0, 0}, {1, 0, 0}, {0, 0, 1},       // t0
      {1, 0, 0}, {1, 0, 1}, {0, 0, 1},       // t1 shares the edge (1,0,0)-(0,0,1)
      {5, 5, 5}, {6, 5, 5}, {-0.0f, 0, 0}};  // t2, its last corner equal to t0's first
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
  weld_vertices(corners, vertices, indices);
  ASSERT_EQ(indices.size(), corners.size());
  EXPECT_EQ(vertices.size(), 6u);
  for (size_t c = 0; c < corners.size(); ++c) {
    ASSERT_LT(indices[c], vertices.size());
    EXPECT_EQ(vertices[indices[c]], corners[c]) << "corner " << c;
  }
  EXPECT_EQ(indices[1], indices[3]);
  EXPECT_EQ(indices[2], indices[5]);
  EXPECT_EQ(indices[0], indices[8]);
  EXPECT_NE(indices[0], indices[1]);
  EXPECT_NE(indices[6], indices[7]);
}

// allocate and add_layer fill the new layer texels on all cores, in ranges:
// every one of them, past several ranges, is empty, whatever the arrays held
// before, and add_layer keeps the layers there were.
TEST(SnowMaps, AllocateAndAddLayerLeaveEveryNewTexelEmpty) {
  MapGrid grid;
  grid.width = 300;
  grid.height = 500;
  SnowMaps maps;
  maps.allocate(grid, 2);
  const auto scribble = [&maps] {
    std::fill(maps.ground.begin(), maps.ground.end(), 1.0f);
    std::fill(maps.ceiling.begin(), maps.ceiling.end(), 2.0f);
    std::fill(maps.normal.begin(), maps.normal.end(), glm::vec3(0, 1, 0));
    std::fill(maps.object.begin(), maps.object.end(), 7);
  };
  const auto empty_from = [&maps](size_t first) {
    size_t bad = 0;
    for (size_t k = first; k < maps.ground.size(); ++k) {
      bad += !std::isnan(maps.ground[k]) || maps.ceiling[k] != kOpenSky ||
             maps.normal[k] != glm::vec3(0.0f) || maps.object[k] != -1;
    }
    return bad;
  };
  scribble();
  maps.allocate(grid, 3);
  ASSERT_EQ(maps.ground.size(), 3 * grid.texels());
  ASSERT_EQ(maps.object.size(), 3 * grid.texels());
  EXPECT_EQ(empty_from(0), 0u);
  scribble();
  maps.add_layer();
  ASSERT_EQ(maps.layers, 4);
  ASSERT_EQ(maps.normal.size(), 4 * grid.texels());
  EXPECT_EQ(empty_from(3 * grid.texels()), 0u);
  EXPECT_EQ(std::count(maps.object.begin(), maps.object.end(), 7), ptrdiff_t(3 * grid.texels()));
}

TEST(MakeGrid, AutomaticTexelFromMaxSide) {
  Bounds b;
  b.extend({-5, 0, -2});
  b.extend({5, 3, 2});
  const MapGrid g = make_grid(b, settings_with_side(256));
  // Margin 2 % of 10 m on each side: 10.4 m over 256 texels.
  EXPECT_NEAR(g.texel, 10.4f / 256, 1e-6);
  EXPECT_EQ(g.width, 256);
  EXPECT_EQ(g.height, int(std::ceil(4.4 / (10.4 / 256) - 1e-3)));
  // Centred on the bounds, covering them with the margin.
  EXPECT_NEAR(g.origin.x + 0.5f * g.width * g.texel, 0.0f, 1e-5);
  EXPECT_NEAR(g.origin.y + 0.5f * g.height * g.texel, 0.0f, 1e-5);
  EXPECT_LE(g.origin.x, -5.2f + 1e-4f);
  EXPECT_LE(g.origin.y, -2.2f + 1e-4f);
}

TEST(MakeGrid, ExplicitTexelAndMargin) {
  Bounds b;
  b.extend({0, 0, 0});
  b.extend({2, 1, 1});
  PeelSettings s;
  s.texel = 0.1f;
  s.margin = 0.5f;
  const MapGrid g = make_grid(b, s);
  EXPECT_FLOAT_EQ(g.texel, 0.1f);
  EXPECT_EQ(g.width, 30);
  EXPECT_EQ(g.height, 20);
  // Automatic margin: at least 2 texels.
  s.margin = -1;
  const MapGrid g2 = make_grid(b, s);
  EXPECT_EQ(g2.width, 24);
}

TEST(MakeGrid, RejectsBadInput) {
  Bounds empty;
  EXPECT_THROW(make_grid(empty, {}), InputError);
  Bounds b;
  b.extend({0, 0, 0});
  b.extend({1, 1, 1});
  PeelSettings s;
  s.texel = -1;
  EXPECT_THROW(make_grid(b, s), InputError);
  s = {};
  s.layers = 0;
  EXPECT_THROW(make_grid(b, s), InputError);
  s = {};
  s.max_side = 0;
  EXPECT_THROW(make_grid(b, s), InputError);
  s = {};
  s.texel = 1e-12f;  // 1e12 texels a side
  EXPECT_THROW(make_grid(b, s), InputError);
  Bounds nan_bounds;
  nan_bounds.extend({0, 0, 0});
  nan_bounds.max.x = std::nanf("");
  EXPECT_THROW(make_grid(nan_bounds, {}), InputError);
}

TEST(MemoryGuard, HundredKilometresAtOneMillimetreThrowsBeforeAllocating) {
  const Scene scene = make_open_plane(100000.0f);  // 100 km
  PeelSettings s;
  s.texel = 0.001f;
  const MapGrid g = make_grid(scene.bounds, s);  // representable, just huge
  EXPECT_GT(g.width, 100000000);
  EXPECT_GT(estimate_memory(g, s.layers, {}), uint64_t(1) << 60);
  try {
    check_memory_budget(g, s.layers, {}, s.memory_budget);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("over the 4 GiB budget"), std::string::npos) << what;
    EXPECT_NE(what.find("--texel"), std::string::npos) << what;
    EXPECT_NE(what.find("--memory-budget"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos);
  }
  // peel_layers checks before touching GL or allocating maps (no context needed).
  EXPECT_THROW(peel_layers(scene, s, plan::GlFacts{}), InputError);
}

TEST(MemoryGuard, EstimateGrowsWithSizeAndSuggestionFits) {
  MapGrid g;
  g.texel = 0.01f;
  g.width = g.height = 20000;
  const uint64_t big = estimate_memory(g, 8, {});
  g.width = g.height = 1000;
  const uint64_t small = estimate_memory(g, 8, {});
  EXPECT_GT(big, 300 * small);
  EXPECT_GT(estimate_memory(g, 8, {}, 50.0f), small);  // taller scenes: bigger shadow maps
  EXPECT_NO_THROW(check_memory_budget(g, 8, {}, 4ull << 30));
  EXPECT_THROW(check_memory_budget(g, 8, {}, 1 << 20), InputError);
}

// The peel returns only the layers some column reaches: the table scene
// fills 3 of 8 (top or floor, the top's underside, the floor under it), a
// single plane 1; the same as with L = 3. drop_empty_layers trims empty
// layers added after them and keeps what is there.
TEST(Peel, KeepsOnlyTheLayersColumnsReach) {
  REQUIRE_GL();
  const SnowMaps full =
      peel_layers(make_table_scene(), settings_with_side(64, 8), plan::current_gl());
  ASSERT_EQ(full.layers, 3);
  const size_t n = 3 * full.grid.texels();
  ASSERT_EQ(full.ground.size(), n);
  ASSERT_EQ(full.object.size(), n);
  const SnowMaps three =
      peel_layers(make_table_scene(), settings_with_side(64, 3), plan::current_gl());
  ASSERT_EQ(three.layers, 3);
  for (size_t k = 0; k < n; ++k) {
    ASSERT_TRUE(three.ground[k] == full.ground[k] ||
                (std::isnan(three.ground[k]) && std::isnan(full.ground[k])));
    ASSERT_EQ(three.ceiling[k], full.ceiling[k]);
    ASSERT_EQ(three.object[k], full.object[k]);
  }
  for (int l = 0; l < 3; ++l) {
    bool any = false;
    for (size_t t = 0; t < full.grid.texels(); ++t)
      any |= !std::isnan(full.ground[l * full.grid.texels() + t]);
    EXPECT_TRUE(any) << "layer " << l;
  }

  SnowMaps padded = full;
  for (int l = 0; l < 5; ++l) padded.add_layer();
  ASSERT_EQ(padded.ground.size(), 8 * full.grid.texels());
  EXPECT_EQ(padded.drop_empty_layers(), 5);
  ASSERT_EQ(padded.layers, 3);
  EXPECT_EQ(padded.ground.size(), n);
  EXPECT_EQ(padded.ceiling, full.ceiling);
  EXPECT_EQ(padded.object, full.object);
  EXPECT_EQ(padded.drop_empty_layers(), 0);  // nothing more to drop

  SceneBuilder plane;
  plane.add_plane("Floor", 0.0f, {-1.0f, -1.0f}, {1.0f, 1.0f});
  const SnowMaps flat = peel_layers(plane.build(), settings_with_side(16), plan::current_gl());
  EXPECT_EQ(flat.layers, 1);
  EXPECT_EQ(flat.ground.size(), flat.grid.texels());
}

TEST(Peel, TableLayersAndCeilings) {
  REQUIRE_GL();
  TableDims dims;  // top at 0.75, 1 m square, 5 cm thick, on a 4 m floor
  const Scene scene = make_table_scene(dims);
  const SnowMaps maps = peel_layers(scene, settings_with_side(128), plan::current_gl());
  ASSERT_EQ(maps.layers, 3);  // of 8: no column holds a fourth surface
  EXPECT_EQ(maps.overflow_columns, 0u);
  const glm::ivec2 mid = texel_at(maps.grid, 0.01f, 0.01f);
  // Layer 0: the table top, facing up; no ceiling.
  size_t k = maps.index(0, mid.x, mid.y);
  EXPECT_NEAR(maps.ground[k], 0.75f, 1e-4);
  EXPECT_EQ(maps.object[k], 1);
  EXPECT_GT(maps.normal[k].y, 0.999f);
  EXPECT_TRUE(std::isinf(maps.ceiling[k]));
  // Layer 1: the top's underside, facing down, ceiling the top surface.
  k = maps.index(1, mid.x, mid.y);
  EXPECT_NEAR(maps.ground[k], 0.70f, 1e-4);
  EXPECT_EQ(maps.object[k], 1);
  EXPECT_LT(maps.normal[k].y, -0.999f);
  EXPECT_NEAR(maps.ceiling[k], 0.75f, 1e-4);
  // Layer 2: the floor under the table, ceiling the underside.
  k = maps.index(2, mid.x, mid.y);
  EXPECT_NEAR(maps.ground[k], 0.0f, 1e-5);
  EXPECT_EQ(maps.object[k], 0);
  EXPECT_NEAR(maps.ceiling[k], 0.70f, 1e-4);
  // Outside the table the floor is layer 0 under the open sky.
  const glm::ivec2 out = texel_at(maps.grid, 1.5f, 0.0f);
  k = maps.index(0, out.x, out.y);
  EXPECT_NEAR(maps.ground[k], 0.0f, 1e-5);
  EXPECT_EQ(maps.object[k], 0);
  EXPECT_TRUE(std::isinf(maps.ceiling[k]));
  EXPECT_TRUE(std::isnan(maps.ground[maps.index(1, out.x, out.y)]));
  // Beyond the floor (the margin) there is nothing.
  EXPECT_TRUE(std::isnan(maps.ground[maps.index(0, 0, 0)]));
  EXPECT_EQ(maps.object[maps.index(0, 0, 0)], -1);
}

TEST(Peel, GpuMatchesReferenceOnCannedScenes) {
  REQUIRE_GL();
  struct Case {
    const char* name;
    Scene scene;
  };
  Case cases[] = {
      {"open plane", make_open_plane(10.0f)},
      {"table", make_table_scene(0.75f, 1.0f, 4.0f)},
      {"closed box", make_closed_box_scene(1.0f)},
      {"wall", make_wall_scene(2.0f, 6.0f, 10.0f)},
      {"house", make_house_scene(45.0f, 0.5f)},
      {"bowl", make_bowl_scene()},
      {"stairs", make_stairs_scene()},
      {"terrain", make_terrain(20000).build()},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const PeelSettings s = settings_with_side(c.scene.triangle_count() > 1000 ? 256 : 96, 6);
    const SnowMaps gpu = peel_layers(c.scene, s, plan::current_gl());
    const SnowMaps cpu = reference::peel_layers(c.scene, gpu.grid, s.layers, s.merge_distance);
    const Agreement a = compare_maps(gpu, cpu);
    std::printf("%s: compared %zu mismatched %zu max err %g\n", c.name, a.compared, a.mismatched,
                a.max_height_error);
    EXPECT_GT(a.compared, 1000u);
    // Ties on triangle edges may differ (fill rule); nothing else may.
    EXPECT_LE(double(a.mismatched), 0.005 * double(a.compared)) << a.mismatched;
    // The heights are the CPU's, worked out on the triangle the GPU found,
    // not the ones it interpolated from corners snapped to its sub-pixel
    // grid (NVIDIA H200: up to 2.0e-4 m off on the house at 96 texels). Ties
    // on edges between two triangles of one object leave a rounding.
    EXPECT_LT(a.max_height_error, 1e-5f);
    EXPECT_EQ(gpu.overflow_columns, cpu.overflow_columns);
  }
}

// Triangles of a one-sided quad at height y over [x0,x1] x [z0,z1], wound
// so that its normal points up (up = true) or down.
void add_quad(Scene& scene, const std::string& name, float y, float x0, float x1, float z0,
              float z1, bool up) {
  SceneObject obj;
  obj.name = name;
  obj.first_triangle = uint32_t(scene.triangle_count());
  obj.triangle_count = 2;
  glm::vec3 a(x0, y, z0), b(x1, y, z0), c(x1, y, z1), d(x0, y, z1);
  // Counter-clockwise seen from above (+Y) is a -> d -> c -> b.
  const glm::vec3 tri[6] = {a, d, c, a, c, b};
  for (int k = 0; k < 6; ++k) {
    scene.positions.push_back(up ? tri[k] : tri[5 - k]);
    scene.normals.push_back(glm::vec3(0, up ? 1.0f : -1.0f, 0));
    scene.bounds.extend(tri[k]);
  }
  scene.objects.push_back(obj);
}

TEST(Peel, CoplanarDuplicatesMergeAndFlippedFacesAreFloors) {
  REQUIRE_GL();
  Scene scene;
  add_quad(scene, "Floor", 0.0f, -2, 2, -2, 2, /*up=*/false);  // flipped: still a floor
  add_quad(scene, "FloorCopy", 0.0f, -2, 2, -2, 2, true);      // coplanar duplicate
  add_quad(scene, "Decal", 0.0005f, -1, 1, -1, 1, true);       // 0.5 mm above: same layer
  add_quad(scene, "Shelf", 0.3f, -0.5f, 0.5f, -0.5f, 0.5f, true);
  const SnowMaps maps = peel_layers(scene, settings_with_side(64, 4), plan::current_gl());
  const glm::ivec2 mid = texel_at(maps.grid, 0.01f, 0.01f);
  EXPECT_NEAR(maps.ground[maps.index(0, mid.x, mid.y)], 0.3f, 1e-5);
  EXPECT_NEAR(maps.ground[maps.index(1, mid.x, mid.y)], 0.0005f, 1e-6);
  EXPECT_EQ(maps.object[maps.index(1, mid.x, mid.y)], 2);
  EXPECT_EQ(maps.layers, 2);  // the floor merged into the decal's layer: no third
  const glm::ivec2 side = texel_at(maps.grid, 1.5f, 0.01f);
  const size_t k = maps.index(0, side.x, side.y);
  EXPECT_NEAR(maps.ground[k], 0.0f, 1e-6);
  EXPECT_EQ(maps.object[k], 0);          // first drawn of the coplanar pair
  EXPECT_LT(maps.normal[k].y, -0.999f);  // the normal as wound: down
  EXPECT_TRUE(std::isnan(maps.ground[maps.index(1, side.x, side.y)]));
  const SnowMaps ref = reference::peel_layers(scene, maps.grid, 4);
  const Agreement a = compare_maps(maps, ref);
  EXPECT_EQ(a.mismatched, 0u);
}

TEST(Peel, CountsAndWarnsAboutOverflowColumnsOnce) {
  REQUIRE_GL();
  Scene scene;
  for (int k = 0; k < 5; ++k)
    add_quad(scene, "Plate" + std::to_string(k), 0.1f * k, -1, 1, -1, 1, true);
  for (const char* device : {"gpu", "cpu"}) {
    SCOPED_TRACE(device);
    clear_warnings();
    const SnowMaps maps = peel_layers(scene, settings_with_side(64, 3, device), plan::current_gl());
    // Every texel centre inside the plates holds 5 surfaces.
    size_t inside = 0;
    for (int j = 0; j < maps.grid.height; ++j) {
      for (int i = 0; i < maps.grid.width; ++i) {
        const glm::vec2 c = maps.grid.center(i, j);
        inside += std::abs(c.x) < 1.0f && std::abs(c.y) < 1.0f;
      }
    }
    EXPECT_EQ(maps.overflow_columns, inside);
    const SnowMaps ref = reference::peel_layers(scene, maps.grid, 3);
    EXPECT_EQ(ref.overflow_columns, inside);
    size_t warnings = 0;
    for (const std::string& w : recorded_warnings())
      warnings += w.find("more than 3") != std::string::npos;
    EXPECT_EQ(warnings, 1u);
    // The top three plates are kept, top down.
    const glm::ivec2 mid = texel_at(maps.grid, 0.01f, 0.01f);
    EXPECT_NEAR(maps.ground[maps.index(0, mid.x, mid.y)], 0.4f, 1e-5);
    EXPECT_NEAR(maps.ground[maps.index(2, mid.x, mid.y)], 0.2f, 1e-5);
    EXPECT_NEAR(maps.ceiling[maps.index(2, mid.x, mid.y)], 0.3f, 1e-5);
  }
}

TEST(Peel, EmptySceneGivesEmptyMaps) {
  REQUIRE_GL();
  Scene scene;
  scene.bounds.extend({0, 0, 0});
  scene.bounds.extend({1, 1, 1});
  for (const char* device : {"gpu", "cpu"}) {
    const SnowMaps maps = peel_layers(scene, settings_with_side(16, 2, device), plan::current_gl());
    EXPECT_EQ(maps.layers, 1) << device;
    for (float g : maps.ground) EXPECT_TRUE(std::isnan(g)) << device;
  }
}

// The CPU peel is the reference's vertical rays; "auto" takes it where GL
// runs in software (faster there at every size), the GPU passes on a GPU.
TEST(Peel, DeviceChoosesTheCpuInSoftware) {
  REQUIRE_GL();
  const Scene scene = make_table_scene(0.75f, 1.0f, 4.0f);
  const SnowMaps cpu = peel_layers(scene, settings_with_side(96, 6, "cpu"), plan::current_gl());
  const SnowMaps ref = reference::peel_layers(scene, cpu.grid, 6);
  EXPECT_EQ(compare_maps(cpu, ref).mismatched, 0u);
  EXPECT_EQ(cpu.ground.size(), ref.ground.size());
  for (int side : {96, 512}) {
    const SnowMaps automatic =
        peel_layers(scene, settings_with_side(side, 6, "auto"), plan::current_gl());
    const SnowMaps expected =
        peel_layers(scene, settings_with_side(side, 6, gl::renderer_is_software() ? "cpu" : "gpu"),
                    plan::current_gl());
    ASSERT_EQ(automatic.ground.size(), expected.ground.size()) << side;
    EXPECT_EQ(std::memcmp(automatic.ground.data(), expected.ground.data(),
                          automatic.ground.size() * sizeof(float)),
              0)
        << side;
  }
  EXPECT_THROW(peel_layers(scene, settings_with_side(96, 6, "tpu"), plan::current_gl()),
               InputError);
}

// "auto" peels on the CPU while the triangles' boxes hold at most
// kCpuPeelHits texel centres, or at most 4 per layer texel.
TEST(Peel, CpuPeelKeepsItsHitsWithinTheMaps) {
  const plan::GlFacts software{true, false};  // the choice alone: no GL needed
  // 3 stacked plates of 2 triangles, each box over nearly all of a 1024 x
  // 1024 map: about 5.5M box texels, over kCpuPeelHits (4.2M).
  SceneBuilder b;
  for (int k = 0; k < 3; ++k) {
    const float y = 0.1f * float(k);
    b.add_mesh("Plate" + std::to_string(k), {{-1, y, -1}, {1, y, -1}, {1, y, 1}, {-1, y, 1}},
               {0, 3, 2, 0, 2, 1});
  }
  const Scene scene = b.build();
  PeelSettings s = settings_with_side(1024, 2, "auto");
  EXPECT_TRUE(
      peels_on_cpu(scene, make_grid(scene.bounds, s), s, software));  // 4 x 2.1M layer texels
  s.layers = 1;
  EXPECT_FALSE(peels_on_cpu(scene, make_grid(scene.bounds, s), s, software));  // 4 x 1.05M
  s.device = "cpu";
  EXPECT_TRUE(peels_on_cpu(scene, make_grid(scene.bounds, s), s, software));
  s.device = "gpu";
  s.layers = 2;
  EXPECT_FALSE(peels_on_cpu(scene, make_grid(scene.bounds, s), s, software));
}

// Many large stacked triangles would make the CPU peel store every hit of
// every texel (kCpuPeelHits): "auto" keeps the GPU's passes for them.
TEST(Peel, ManyStackedTrianglesKeepTheGpu) {
  REQUIRE_GL();
  // 1100 tilted plates (2200 triangles) over all 64 x 64 texels: 9M box
  // texels.
  const auto plates = [](int count) {
    SceneBuilder b;
    for (int k = 0; k < count; ++k) {
      const auto at = [k](float x, float z) {
        return glm::vec3(x, 0.002f * float(k) + 0.05f * x + 0.03f * z, z);
      };
      b.add_mesh("Plate" + std::to_string(k), {at(-1, -1), at(1, -1), at(1, 1), at(-1, 1)},
                 {0, 3, 2, 0, 2, 1});
    }
    return b.build();
  };
  const Scene scene = plates(1100);
  const PeelSettings automatic = settings_with_side(64, 4, "auto");
  EXPECT_FALSE(
      peels_on_cpu(scene, make_grid(scene.bounds, automatic), automatic, plan::current_gl()));
  // A few of them are left to the CPU in software.
  const Scene few = plates(10);
  EXPECT_EQ(peels_on_cpu(few, make_grid(few.bounds, automatic), automatic, plan::current_gl()),
            gl::renderer_is_software());
  const SnowMaps peeled = peel_layers(scene, automatic, plan::current_gl());
  const SnowMaps gpu = peel_layers(scene, settings_with_side(64, 4, "gpu"), plan::current_gl());
  ASSERT_EQ(peeled.ground.size(), gpu.ground.size());
  EXPECT_EQ(std::memcmp(peeled.ground.data(), gpu.ground.data(), gpu.ground.size() * sizeof(float)),
            0);
}

}  // namespace
}  // namespace snow
