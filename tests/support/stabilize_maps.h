#pragma once
// Shared by the stabilizer's tests (test_stabilize.cpp,
// test_stabilize_piles.cpp): maps built from analytic columns, snow on them,
// the GL context, and the measures the tests compare (the largest movable
// excess, volumes, GPU against CPU depths).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <vector>

#include <glm/glm.hpp>

#include "core/error.h"
#include "gl/context.h"
#include "scene/scene.h"
#include "snow/column.h"
#include "snow/maps.h"
#include "snow/peel.h"
#include "snow/reference/peel_ref.h"
#include "snow/stabilize.h"
#include "snow/stabilize_cpu.h"
#include "support/gl_context.h"

namespace snow::test {

inline constexpr float kDeg = 3.14159265358979f / 180.0f;

// The stabilizer's settings for loose snow (no cohesion): the tests of the
// repose relaxation, the routing, the drains and the piles check those
// mechanics on their own; test_snow_physics checks cohesive snow, and
// StabilizeGpu.CohesiveSnowMatchesReference the GPU's cohesion.
inline StabilizeSettings loose_settings() {
  StabilizeSettings settings;
  settings.cohesion = loose_snow();
  return settings;
}

// --- Analytic maps -----------------------------------------------------------

struct Surface {
  float y;      // metres
  glm::vec3 n;  // normal as wound
};
// The surfaces of the column through (x, z), from the top down.
using ColumnFn = std::function<std::vector<Surface>(float x, float z)>;

inline const glm::vec3 kUp(0.0f, 1.0f, 0.0f);
inline const glm::vec3 kDown(0.0f, -1.0f, 0.0f);

inline SnowMaps make_maps(int width, int height, float texel, int layers, const ColumnFn& column) {
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
inline std::vector<float> snow_on_top(const SnowMaps& maps, float amount) {
  std::vector<float> depth(size_t(maps.layers) * maps.grid.texels(), 0.0f);
  for (int j = 0; j < maps.grid.height; ++j) {
    for (int i = 0; i < maps.grid.width; ++i) {
      if (maps.has_surface(0, i, j)) depth[maps.index(0, i, j)] = amount;
    }
  }
  return depth;
}

// Per-texel movable excess of a converged state: for every texel with more
// than `min_depth` of snow, the largest (h - h_land) - distance * tan(repose)
// over its neighbours that it can reach (a void neighbour counts as infinite).
inline float largest_excess(const SnowMaps& maps, const std::vector<float>& depth,
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

inline double sum_where(const SnowMaps& maps, const std::vector<float>& depth,
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

// Bumpy terrain with holes (void columns), a floating slab (three layers)
// and a low shelf, for the property tests.
inline SnowMaps bumpy_maps(int size, int layers) {
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

inline std::vector<float> random_snow(const SnowMaps& maps, float max_depth, uint32_t seed) {
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

// A 2.4 m floor (48 texels of 5 cm) with a square slab over x, z in (lo,
// hi): top 0.15 m, underside 0.1 m above the floor.
inline SnowMaps slab_maps(float lo, float hi) {
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
inline SnowMaps shelf_maps() { return slab_maps(0.8f, 1.6f); }

// The maps of a builder scene, peeled by the CPU reference.
inline SnowMaps scene_maps(const Scene& scene, int side, int layers = 8) {
  PeelSettings settings;
  settings.max_side = side;
  settings.layers = layers;
  return reference::peel_layers(scene, make_grid(scene.bounds, settings), layers);
}

// --- Comparing depths --------------------------------------------------------

/// The tolerance within which the GPU's and the CPU's stabilizers agree:
/// per layer texel (m), and on the snow volume (share). Each backend is
/// deterministic on its own; across backends the order of float operations
/// may differ.
constexpr float kBackendTexelTolerance = 1e-3f;
constexpr double kBackendVolumeTolerance = 1e-3;

/// The GPU's depths agree with the CPU's on `maps` within the tolerance
/// above: every texel, and the snow volume.
inline void expect_agree(const SnowMaps& maps, const std::vector<float>& gpu,
                         const std::vector<float>& cpu) {
  ASSERT_EQ(gpu.size(), cpu.size());
  float worst = 0.0f;
  for (size_t k = 0; k < gpu.size(); ++k) worst = std::max(worst, std::abs(gpu[k] - cpu[k]));
  const double vg = snow_volume(maps, gpu), vc = snow_volume(maps, cpu);
  std::printf("GPU vs CPU: largest difference %.3e m, volumes %.6g and %.6g m^3\n", worst, vg, vc);
  EXPECT_LE(worst, kBackendTexelTolerance);
  EXPECT_LE(std::abs(vg - vc), kBackendVolumeTolerance * std::max(vc, 1e-12));
}

// Bit for bit the same depths.
inline void expect_identical(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  size_t differ = 0;
  for (size_t k = 0; k < a.size(); ++k) differ += std::memcmp(&a[k], &b[k], sizeof(float)) != 0;
  EXPECT_EQ(differ, 0u);
}

}  // namespace snow::test
