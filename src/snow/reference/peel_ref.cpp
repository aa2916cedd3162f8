// CPU reference of depth peeling from above (Tokoi 2006, section 3): one
// vertical ray per texel centre through all triangles, in double precision.
#include "snow/reference/peel_ref.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"

namespace snow::reference {
namespace {

struct Hit {
  float y;
  uint32_t triangle;
};

struct TexelHit {
  uint32_t texel;
  Hit hit;
};

}  // namespace

SnowMaps peel_layers(const Scene& scene, const MapGrid& grid, int layers, float merge_distance) {
  if (layers < 1 || layers > 64) {
    throw InputError("reference peel: layers must be in 1..64, got " + std::to_string(layers));
  }
  if (grid.width < 1 || grid.height < 1 || !(grid.texel > 0.0f)) {
    throw InputError("reference peel: empty map grid");
  }
  const size_t texels = grid.texels();
  if (texels > size_t(UINT32_MAX)) throw InputError("reference peel: more than 2^32 texels");
  // Every hit in one array, grouped by texel below (no allocation per
  // texel).
  std::vector<TexelHit> found;
  const double ox = grid.origin.x, oz = grid.origin.y, t = grid.texel;

  const size_t triangle_count = scene.triangle_count();
  for (size_t tri = 0; tri < triangle_count; ++tri) {
    const glm::dvec3 a(scene.positions[3 * tri]);
    const glm::dvec3 b(scene.positions[3 * tri + 1]);
    const glm::dvec3 c(scene.positions[3 * tri + 2]);
    // Signed doubled area of the xz projection; 0: seen edge-on, no hit.
    const double area = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
    if (area == 0.0 || !std::isfinite(area)) continue;
    const double min_x = std::min({a.x, b.x, c.x}), max_x = std::max({a.x, b.x, c.x});
    const double min_z = std::min({a.z, b.z, c.z}), max_z = std::max({a.z, b.z, c.z});
    // Texel centres x = ox + (i + 0.5) t inside [min_x, max_x].
    const int i0 = std::max(0, int(std::ceil((min_x - ox) / t - 0.5)));
    const int i1 = std::min(grid.width - 1, int(std::floor((max_x - ox) / t - 0.5)));
    const int j0 = std::max(0, int(std::ceil((min_z - oz) / t - 0.5)));
    const int j1 = std::min(grid.height - 1, int(std::floor((max_z - oz) / t - 0.5)));
    for (int j = j0; j <= j1; ++j) {
      const double pz = oz + (j + 0.5) * t;
      for (int i = i0; i <= i1; ++i) {
        const double px = ox + (i + 0.5) * t;
        // Barycentric weights from edge functions (same sign as area inside).
        const double wa = (b.x - px) * (c.z - pz) - (c.x - px) * (b.z - pz);
        const double wb = (c.x - px) * (a.z - pz) - (a.x - px) * (c.z - pz);
        const double wc = (a.x - px) * (b.z - pz) - (b.x - px) * (a.z - pz);
        const bool inside =
            area > 0 ? (wa >= 0 && wb >= 0 && wc >= 0) : (wa <= 0 && wb <= 0 && wc <= 0);
        if (!inside) continue;
        const double y = (wa * a.y + wb * b.y + wc * c.y) / area;
        found.push_back(
            {uint32_t(size_t(j) * size_t(grid.width) + size_t(i)), {float(y), uint32_t(tri)}});
      }
    }
  }

  // Per-triangle unit normal (as wound) and object, as the GPU pass uploads.
  std::vector<glm::vec3> tri_normal(triangle_count);
  std::vector<int32_t> tri_object(triangle_count, -1);
  for (size_t tri = 0; tri < triangle_count; ++tri) {
    const glm::dvec3 a(scene.positions[3 * tri]);
    const glm::dvec3 n = glm::cross(glm::dvec3(scene.positions[3 * tri + 1]) - a,
                                    glm::dvec3(scene.positions[3 * tri + 2]) - a);
    const double len = glm::length(n);
    tri_normal[tri] = len > 0 ? glm::vec3(n / len) : glm::vec3(0.0f);
  }
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const SceneObject& obj = scene.objects[o];
    for (uint32_t k = 0; k < obj.triangle_count && obj.first_triangle + k < triangle_count; ++k) {
      tri_object[obj.first_triangle + k] = int32_t(o);
    }
  }

  // The hits grouped by texel (counting sort): texel t's are hits[start[t],
  // start[t + 1]).
  std::vector<size_t> start(texels + 1, 0);
  for (const TexelHit& f : found) ++start[f.texel + 1];
  for (size_t t = 0; t < texels; ++t) start[t + 1] += start[t];
  std::vector<Hit> hits(found.size());
  {
    std::vector<size_t> next(start.begin(), start.end() - 1);
    for (const TexelHit& f : found) hits[next[f.texel]++] = f.hit;
  }
  found = {};

  // Each column's hits top down; the surfaces kept (at least merge_distance
  // apart, at most `layers`) go to fn(layer, hit, height above); returns
  // whether some were left over.
  const auto surfaces = [&](size_t texel, auto&& fn) {
    float last = kOpenSky;
    int layer = 0;
    for (size_t h = start[texel]; h < start[texel + 1]; ++h) {
      const Hit& hit = hits[h];
      if (layer > 0 && !(hit.y < last - merge_distance)) continue;
      if (layer == layers) return true;
      fn(layer, hit, last);
      last = hit.y;
      ++layer;
    }
    return false;
  };
  // Only the layers some column fills are allocated (allocating all and
  // dropping the empty ones cost the Kenney tiles 10 ms of fresh memory).
  int used = 1;
  for (size_t texel = 0; texel < texels; ++texel) {
    std::sort(hits.begin() + std::ptrdiff_t(start[texel]),
              hits.begin() + std::ptrdiff_t(start[texel + 1]), [](const Hit& p, const Hit& q) {
                return p.y != q.y ? p.y > q.y : p.triangle < q.triangle;
              });
    surfaces(texel, [&](int layer, const Hit&, float) { used = std::max(used, layer + 1); });
  }
  SnowMaps maps;
  maps.allocate(grid, used);
  for (size_t texel = 0; texel < texels; ++texel) {
    const int i = int(texel % grid.width), j = int(texel / grid.width);
    maps.overflow_columns += surfaces(texel, [&](int layer, const Hit& hit, float above) {
      const size_t k = maps.index(layer, i, j);
      maps.ground[k] = hit.y;
      maps.ceiling[k] = above;
      maps.normal[k] = tri_normal[hit.triangle];
      maps.object[k] = tri_object[hit.triangle];
    });
  }
  return maps;
}

}  // namespace snow::reference
