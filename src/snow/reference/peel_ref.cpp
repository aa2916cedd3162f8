// CPU reference of depth peeling from above (Tokoi 2006, section 3): one
// vertical ray per texel centre through all triangles, in double precision.
#include "snow/reference/peel_ref.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "core/parallel.h"

namespace snow::reference {
namespace {

struct Hit {
  float y;
  uint32_t triangle;
};

struct TexelHit {
  uint32_t texel;  // within its band
  Hit hit;
};

// Triangles per task of the loops over all triangles.
constexpr size_t kTriangleChunk = size_t(1) << 14;

// The texel centres a triangle's xz box holds: columns i0..i1, rows j0..j1.
struct Box {
  int i0, i1, j0, j1;
};
struct Boxed {
  uint32_t triangle;
  Box box;
};

// The triangles whose boxes of texel centres are not empty (a triangle seen
// edge-on, or between two centres, has none: most of a detailed model's on a
// coarse map), with their boxes, in index order, on all cores. Only those are
// stored: two arrays over every triangle (these boxes, and each triangle's
// normal and object, now worked out for the hits kept alone) would cost a
// detailed model's peel much of its time, in fresh pages.
std::vector<Boxed> boxed_triangles(const Scene& scene, const MapGrid& grid) {
  const double ox = grid.origin.x, oz = grid.origin.y, t = grid.texel;
  const size_t triangle_count = scene.triangle_count();
  const size_t chunks = (triangle_count + kTriangleChunk - 1) / kTriangleChunk;
  std::vector<std::vector<Boxed>> chunk_boxes(chunks);
  parallel_for(chunks, [&](size_t chunk) {
    const size_t begin = chunk * kTriangleChunk;
    const size_t end = std::min(triangle_count, begin + kTriangleChunk);
    for (size_t tri = begin; tri < end; ++tri) {
      const glm::dvec3 a(scene.positions[3 * tri]);
      const glm::dvec3 b(scene.positions[3 * tri + 1]);
      const glm::dvec3 c(scene.positions[3 * tri + 2]);
      // Signed doubled area of the xz projection; 0: seen edge-on, no hit.
      const double area = ColumnWeights::area(a, b, c);
      if (area == 0.0 || !std::isfinite(area)) continue;
      const double min_x = std::min({a.x, b.x, c.x}), max_x = std::max({a.x, b.x, c.x});
      const double min_z = std::min({a.z, b.z, c.z}), max_z = std::max({a.z, b.z, c.z});
      // Texel centres x = ox + (i + 0.5) t inside [min_x, max_x].
      const Box r{std::max(0, int(std::ceil((min_x - ox) / t - 0.5))),
                  std::min(grid.width - 1, int(std::floor((max_x - ox) / t - 0.5))),
                  std::max(0, int(std::ceil((min_z - oz) / t - 0.5))),
                  std::min(grid.height - 1, int(std::floor((max_z - oz) / t - 0.5)))};
      if (r.i0 <= r.i1 && r.j0 <= r.j1) chunk_boxes[chunk].push_back({uint32_t(tri), r});
    }
  });
  std::vector<Boxed> boxed;
  size_t total = 0;
  for (const auto& part : chunk_boxes) total += part.size();
  boxed.reserve(total);
  for (auto& part : chunk_boxes) {
    boxed.insert(boxed.end(), part.begin(), part.end());
    part = {};
  }
  return boxed;
}

// A band of rows: the hits of the triangles whose boxes meet it in one
// array, grouped by texel (counting sort: texel t's are hits[start[t -
// first], start[t - first + 1]), first = the band's first texel), sorted
// from the top down. A texel's hits and their order do not depend on the
// bands.
struct Band {
  int j0 = 0, j1 = 0;  // rows [j0, j1)
  std::vector<Hit> hits;
  std::vector<size_t> start;
  int used = 1;  // layers its columns fill
};

// The bands (4 per core, at most one per row) and the boxed triangles that
// meet each, in index order: band b's are boxed[listed[listed_start[b]]],
// ... up to listed_start[b + 1].
struct Bands {
  std::vector<Band> bands;
  std::vector<size_t> listed_start;
  std::vector<uint32_t> listed;
};

Bands make_bands(const MapGrid& grid, const std::vector<Boxed>& boxed) {
  Bands out;
  const size_t band_count =
      std::min<size_t>(size_t(grid.height), std::max<size_t>(1, 4 * size_t(default_threads())));
  out.bands.resize(band_count);
  std::vector<uint32_t> band_of_row(size_t(grid.height));
  for (size_t b = 0; b < band_count; ++b) {
    out.bands[b].j0 = int(b * size_t(grid.height) / band_count);
    out.bands[b].j1 = int((b + 1) * size_t(grid.height) / band_count);
    for (int j = out.bands[b].j0; j < out.bands[b].j1; ++j) band_of_row[size_t(j)] = uint32_t(b);
  }
  out.listed_start.assign(band_count + 1, 0);
  const auto each_band_of = [&](const Box& r, auto&& fn) {
    for (uint32_t b = band_of_row[size_t(r.j0)]; b <= band_of_row[size_t(r.j1)]; ++b) fn(b);
  };
  for (const Boxed& e : boxed) {
    each_band_of(e.box, [&](uint32_t b) { ++out.listed_start[b + 1]; });
  }
  for (size_t b = 0; b < band_count; ++b) out.listed_start[b + 1] += out.listed_start[b];
  out.listed.resize(out.listed_start.back());
  std::vector<size_t> next(out.listed_start.begin(), out.listed_start.end() - 1);
  for (size_t e = 0; e < boxed.size(); ++e) {
    each_band_of(boxed[e].box, [&](uint32_t b) { out.listed[next[b]++] = uint32_t(e); });
  }
  return out;
}

// The surfaces a column keeps from its hits, top down: at least
// merge_distance apart, at most `layers`.
struct SurfaceRule {
  size_t width;  // texels per row
  int layers;
  float merge_distance;  // metres

  // Calls fn(layer, hit, height above) for each surface kept of `texel`
  // (of `band`); returns whether some were left over.
  template <class Fn>
  bool operator()(const Band& band, size_t texel, Fn&& fn) const {
    const size_t at = texel - size_t(band.j0) * width;
    float last = kOpenSky;
    int layer = 0;
    for (size_t h = band.start[at]; h < band.start[at + 1]; ++h) {
      const Hit& hit = band.hits[h];
      if (layer > 0 && !(hit.y < last - merge_distance)) continue;
      if (layer == layers) return true;
      fn(layer, hit, last);
      last = hit.y;
      ++layer;
    }
    return false;
  }
};

// Every hit of the triangles listed for band b at its texel centres.
std::vector<TexelHit> find_hits(const Scene& scene, const MapGrid& grid,
                                const std::vector<Boxed>& boxed, const Bands& bands, size_t b) {
  const double ox = grid.origin.x, oz = grid.origin.y, t = grid.texel;
  const size_t width = size_t(grid.width);
  const Band& band = bands.bands[b];
  const size_t first = size_t(band.j0) * width;
  std::vector<TexelHit> found;
  for (size_t at = bands.listed_start[b]; at < bands.listed_start[b + 1]; ++at) {
    const size_t tri = boxed[bands.listed[at]].triangle;
    const Box& r = boxed[bands.listed[at]].box;
    const int j0 = std::max(r.j0, band.j0), j1 = std::min(r.j1, band.j1 - 1);
    const glm::dvec3 a(scene.positions[3 * tri]);
    const glm::dvec3 bv(scene.positions[3 * tri + 1]);
    const glm::dvec3 c(scene.positions[3 * tri + 2]);
    const double area = ColumnWeights::area(a, bv, c);
    for (int j = j0; j <= j1; ++j) {
      const double pz = oz + (j + 0.5) * t;
      for (int i = r.i0; i <= r.i1; ++i) {
        const double px = ox + (i + 0.5) * t;
        const ColumnWeights w(a, bv, c, px, pz);
        if (!w.inside(area)) continue;
        found.push_back({uint32_t(size_t(j) * width + size_t(i) - first),
                         {float(w.height(a, bv, c, area)), uint32_t(tri)}});
      }
    }
  }
  return found;
}

// Fills band b's hits, grouped by texel and sorted top down, and the layers
// its columns fill.
void sort_band(std::vector<TexelHit> found, const MapGrid& grid, const SurfaceRule& surfaces,
               Band& band) {
  const size_t first = size_t(band.j0) * size_t(grid.width);
  const size_t band_texels = size_t(band.j1 - band.j0) * size_t(grid.width);
  band.start.assign(band_texels + 1, 0);
  for (const TexelHit& f : found) ++band.start[f.texel + 1];
  for (size_t k = 0; k < band_texels; ++k) band.start[k + 1] += band.start[k];
  band.hits.resize(found.size());
  {
    std::vector<size_t> next(band.start.begin(), band.start.end() - 1);
    for (const TexelHit& f : found) band.hits[next[f.texel]++] = f.hit;
  }
  found = {};
  for (size_t k = 0; k < band_texels; ++k) {
    std::sort(band.hits.begin() + std::ptrdiff_t(band.start[k]),
              band.hits.begin() + std::ptrdiff_t(band.start[k + 1]),
              [](const Hit& p, const Hit& q) {
                return p.y != q.y ? p.y > q.y : p.triangle < q.triangle;
              });
    surfaces(band, first + k,
             [&](int layer, const Hit&, float) { band.used = std::max(band.used, layer + 1); });
  }
}

// The maps of the sorted bands: only the layers some column fills are
// allocated (allocating all and dropping the empty ones would fault in fresh
// memory for nothing). Bands on all cores.
SnowMaps fill_maps(const Scene& scene, const MapGrid& grid, const std::vector<Band>& bands,
                   const SurfaceRule& surfaces) {
  const size_t width = size_t(grid.width);
  int used = 1;
  for (const Band& band : bands) used = std::max(used, band.used);
  SnowMaps maps;
  maps.allocate(grid, used);
  std::vector<uint64_t> overflow(bands.size(), 0);
  parallel_for(bands.size(), [&](size_t b) {
    const Band& band = bands[b];
    for (size_t texel = size_t(band.j0) * width; texel < size_t(band.j1) * width; ++texel) {
      const int i = int(texel % width), j = int(texel / width);
      overflow[b] += surfaces(band, texel, [&](int layer, const Hit& hit, float above) {
        const size_t k = maps.index(layer, i, j);
        maps.ground[k] = hit.y;
        maps.ceiling[k] = above;
        maps.normal[k] = triangle_normal(scene, hit.triangle);
        maps.object[k] = int32_t(scene.object_of_triangle(hit.triangle));
      });
    }
  });
  for (const uint64_t o : overflow) maps.overflow_columns += o;
  return maps;
}

}  // namespace

SnowMaps peel_layers(const Scene& scene, const MapGrid& grid, int layers, float merge_distance) {
  if (layers < 1 || layers > 64) {
    throw InputError("reference peel: layers must be in 1..64, got " + std::to_string(layers));
  }
  if (grid.width < 1 || grid.height < 1 || !(grid.texel > 0.0f)) {
    throw InputError("reference peel: empty map grid");
  }
  if (grid.texels() > size_t(UINT32_MAX)) {
    throw InputError("reference peel: more than 2^32 texels");
  }
  const std::vector<Boxed> boxed = boxed_triangles(scene, grid);
  Bands bands = make_bands(grid, boxed);
  const SurfaceRule surfaces{size_t(grid.width), layers, merge_distance};
  parallel_for(bands.bands.size(), [&](size_t b) {
    sort_band(find_hits(scene, grid, boxed, bands, b), grid, surfaces, bands.bands[b]);
  });
  return fill_maps(scene, grid, bands.bands, surfaces);
}

}  // namespace snow::reference
