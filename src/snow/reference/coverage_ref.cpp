// CPU reference of coverage from multi-direction visibility (Tokoi 2006,
// section 4): exact ray casting against the scene instead of shadow maps.
#include "snow/reference/coverage_ref.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "core/parallel.h"
#include "snow/bvh.h"
#include "snow/coverage.h"

namespace snow::reference {
namespace {

float clean_depth(float s) { return std::isfinite(s) && s > 0.0f ? s : 0.0f; }

}  // namespace

std::vector<glm::vec3> snow_surface_triangles(const SnowMaps& maps,
                                              const std::vector<float>& snow_depth) {
  std::vector<glm::vec3> out;
  const MapGrid& grid = maps.grid;
  if (snow_depth.size() != maps.ground.size()) {
    throw InputError("snow depth has " + std::to_string(snow_depth.size()) +
                     " values, the maps have " + std::to_string(maps.ground.size()));
  }
  const float cut = kSnowSurfaceCutTexels * grid.texel;
  for (int l = 0; l < maps.layers; ++l) {
    for (int j = 0; j + 1 < grid.height; ++j) {
      for (int i = 0; i + 1 < grid.width; ++i) {
        const int ci[4] = {i, i + 1, i + 1, i};
        const int cj[4] = {j, j, j + 1, j + 1};
        glm::vec3 p[4];
        bool has[4];
        bool snowy[4];
        for (int c = 0; c < 4; ++c) {
          const size_t k = maps.index(l, ci[c], cj[c]);
          has[c] = !std::isnan(maps.ground[k]);
          const float s = clean_depth(snow_depth[k]);
          snowy[c] = s > 0.0f;
          const glm::vec2 xz = grid.center(ci[c], cj[c]);
          p[c] = glm::vec3(xz.x, has[c] ? maps.ground[k] + s : 0.0f, xz.y);
        }
        static const int kTri[2][3] = {{0, 1, 2}, {0, 2, 3}};
        for (const auto& tri : kTri) {
          bool ok = true, any_snow = false;
          float lo = kOpenSky, hi = -kOpenSky;
          for (int c : tri) {
            ok = ok && has[c];
            any_snow = any_snow || snowy[c];
            lo = std::min(lo, p[c].y);
            hi = std::max(hi, p[c].y);
          }
          if (!ok || !any_snow || hi - lo > cut) continue;
          for (int c : tri) out.push_back(p[c]);
        }
      }
    }
  }
  return out;
}

bool sees_sky(std::initializer_list<const Bvh*> occluders, const glm::vec3& p, const glm::vec3& d) {
  const float rise = -d.y;  // height gained per unit of t along -d
  if (!(rise > 0.0f)) return false;
  const float t_min = own_surface(p.y) / rise;
  for (const Bvh* bvh : occluders) {
    if (bvh && bvh->occluded(p, -d, t_min, kOpenSky)) return false;
  }
  return true;
}

int open_directions(std::initializer_list<const Bvh*> occluders, const glm::vec3& p,
                    const std::vector<glm::vec3>& directions) {
  int lit = 0;
  for (const glm::vec3& d : directions) lit += sees_sky(occluders, p, d);
  return lit;
}

std::vector<float> compute_coverage(const Scene& scene, const SnowMaps& maps,
                                    const std::vector<glm::vec3>& directions,
                                    const std::vector<float>* snow_depth) {
  if (directions.empty()) throw InputError("reference coverage: no directions");
  std::vector<glm::vec3> corners = scene.positions;
  if (snow_depth) {
    const std::vector<glm::vec3> snow = snow_surface_triangles(maps, *snow_depth);
    corners.insert(corners.end(), snow.begin(), snow.end());
  }
  const Bvh bvh(corners);
  std::vector<float> coverage(maps.ground.size(), 0.0f);
  const MapGrid& grid = maps.grid;
  // Rows in parallel (each writes its own texels).
  parallel_for(size_t(std::max(maps.layers, 0)) * size_t(grid.height), [&](size_t row) {
    const int l = int(row / size_t(grid.height)), j = int(row % size_t(grid.height));
    for (int i = 0; i < grid.width; ++i) {
      const size_t k = maps.index(l, i, j);
      if (std::isnan(maps.ground[k])) continue;
      const float s = snow_depth ? clean_depth((*snow_depth)[k]) : 0.0f;
      const glm::vec2 xz = grid.center(i, j);
      const glm::vec3 p(xz.x, maps.ground[k] + s, xz.y);
      if (second_sheet(maps, k, p.y)) continue;
      coverage[k] = float(open_directions({&bvh}, p, directions)) / float(directions.size());
    }
  });
  return coverage;
}

}  // namespace snow::reference
