// Per-patch fields on texel centres: the snow thickness s and the ground
// height g over the patch's window, with the ground extrapolated one sample
// beyond the patch so the outline (where s falls to min_thickness) can be
// interpolated, and the mass-conserving smoothing of the snow surface g + s.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "core/parallel.h"
#include "mesh/polygonize/steps.h"
#include "snow/column.h"

namespace snow::poly {

PatchField build_field(const SnowMaps& maps, const LayerArray<float>& depth,
                       const PatchTexels& patch) {
  PatchField f;
  // Each step below writes each sample once and reads only what the steps
  // before wrote, so it runs on all cores in chunks with the serial result.
  auto each_texel = [&](unsigned threads, const auto& fn) {
    parallel_for_ranges(
        patch.texels.size(), kFieldChunk,
        [&](size_t begin, size_t end) {
          TexelRows rows(maps);
          for (size_t t = begin; t < end; ++t) fn(patch.texels[t], rows(patch.texels[t]), t);
        },
        threads);
  };
  // The bounding box of each chunk of texels, then of all.
  struct Box {
    int i0, j0, i1, j1;
  };
  std::vector<Box> boxes((patch.texels.size() + kFieldChunk - 1) / kFieldChunk,
                         Box{maps.grid.width, maps.grid.height, -1, -1});
  each_texel(threads_for(patch.texels.size()), [&](size_t, const TexelCoord& c, size_t t) {
    Box& b = boxes[t / kFieldChunk];
    b = {std::min(b.i0, c.i), std::min(b.j0, c.j), std::max(b.i1, c.i), std::max(b.j1, c.j)};
  });
  Box box{maps.grid.width, maps.grid.height, -1, -1};
  for (const Box& b : boxes) {
    box = {std::min(box.i0, b.i0), std::min(box.j0, b.j0), std::max(box.i1, b.i1),
           std::max(box.j1, b.j1)};
  }
  f.i0 = box.i0 - 1;
  f.j0 = box.j0 - 1;
  f.w = box.i1 - f.i0 + 2;
  f.h = box.j1 - f.j0 + 2;
  const size_t count = size_t(f.w) * size_t(f.h);
  f.member.resize(count);
  f.s.resize(count);
  f.g.resize(count);
  f.gx.resize(count);
  f.gz.resize(count);
  const unsigned threads = threads_for(count);
  parallel_for(
      size_t(f.h),
      [&](size_t row) {
        const size_t a = row * size_t(f.w), b = a + size_t(f.w);
        std::fill(f.member.begin() + a, f.member.begin() + b, uint8_t(0));
        std::fill(f.s.begin() + a, f.s.begin() + b, 0.0f);
        std::fill(f.g.begin() + a, f.g.begin() + b, kNoSurface);
        std::fill(f.gx.begin() + a, f.gx.begin() + b, 0.0f);
        std::fill(f.gz.begin() + a, f.gz.begin() + b, 0.0f);
      },
      threads);
  each_texel(threads, [&](size_t k, const TexelCoord& c, size_t) {
    const size_t a = f.at(c.i - f.i0, c.j - f.j0);
    f.member[a] = 1;
    f.s[a] = depth[k];
    f.g[a] = maps.ground[k];
  });
  // Ground slope of members: from the surface normal where it is not too
  // steep, else from differences with member neighbours.
  const float texel = maps.grid.texel;
  const float kMaxSlope = 4.0f;
  each_texel(threads, [&](size_t k, const TexelCoord& c, size_t) {
    const int wi = c.i - f.i0, wj = c.j - f.j0;
    const size_t a = f.at(wi, wj);
    const glm::vec3 n = maps.normal[k];
    float sx = 0.0f, sz = 0.0f;
    if (std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z) &&
        std::abs(n.y) > 0.25f * glm::length(n)) {
      sx = -n.x / n.y;
      sz = -n.z / n.y;
    } else {
      auto diff = [&](int di, int dj) {
        const size_t p = f.at(wi + di, wj + dj);
        const size_t m = f.at(wi - di, wj - dj);
        if (f.member[p] && f.member[m]) return (f.g[p] - f.g[m]) / (2.0f * texel);
        if (f.member[p]) return (f.g[p] - f.g[a]) / texel;
        if (f.member[m]) return (f.g[a] - f.g[m]) / texel;
        return 0.0f;
      };
      sx = diff(1, 0);
      sz = diff(0, 1);
    }
    f.gx[a] = std::clamp(sx, -kMaxSlope, kMaxSlope);
    f.gz[a] = std::clamp(sz, -kMaxSlope, kMaxSlope);
  });
  // Ground of non-member samples next to members: the members' ground planes
  // extrapolated to the sample, averaged.
  each_sample(f, threads, [&](int wi, int wj, size_t a) {
    if (f.member[a]) return;
    double sum = 0.0;
    int n = 0;
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        const int ni = wi + di, nj = wj + dj;
        if (ni < 0 || nj < 0 || ni >= f.w || nj >= f.h) continue;
        const size_t b = f.at(ni, nj);
        if (!f.member[b]) continue;
        sum += f.g[b] - (f.gx[b] * float(di) + f.gz[b] * float(dj)) * texel;
        ++n;
      }
    }
    if (n > 0) f.g[a] = float(sum / n);
  });
  return f;
}

namespace {

// Distances over the members of `f` by dead reckoning (Grevera 2004): two
// chamfer sweeps over the window, forward and back, that pass on each
// sample's nearest seed rather than a sum of step costs, so d becomes the
// Euclidean distance (texels) to the nearest member where it is 0 (that
// member in seed), up to the sweeps' rare misses.
void member_distances(const PatchField& f, std::vector<float>& d, std::vector<glm::ivec2>& seed) {
  for (int wj = 0; wj < f.h; ++wj) {
    for (int wi = 0; wi < f.w; ++wi) seed[f.at(wi, wj)] = glm::ivec2(wi, wj);
  }
  for (int pass = 0; pass < 2; ++pass) {
    const bool forward = pass == 0;
    const int back = forward ? -1 : 1;
    for (int jj = 0; jj < f.h; ++jj) {
      const int wj = forward ? jj : f.h - 1 - jj;
      for (int ii = 0; ii < f.w; ++ii) {
        const int wi = forward ? ii : f.w - 1 - ii;
        const size_t a = f.at(wi, wj);
        if (!f.member[a]) continue;
        const auto relax = [&](int di, int dj) {
          const int ni = wi + di, nj = wj + dj;
          if (ni < 0 || nj < 0 || ni >= f.w || nj >= f.h) return;
          const size_t b = f.at(ni, nj);
          if (!f.member[b] || !std::isfinite(d[b])) return;
          const glm::vec2 to = glm::vec2(seed[b]) - glm::vec2(float(wi), float(wj));
          const float via = std::sqrt(glm::dot(to, to));
          if (via < d[a]) {
            d[a] = via;
            seed[a] = seed[b];
          }
        };
        relax(back, 0);
        relax(0, back);
        relax(back, back);
        relax(-back, back);
      }
    }
  }
}

}  // namespace

void round_shoulders(PatchField& f, const SnowMaps& maps, const LayerArray<float>& depth,
                     const PatchTexels& patch, float radius, const Bounds& open_beyond) {
  const auto goes_on = [&](int i, int j) {
    if (open_beyond.empty()) return false;
    const glm::vec2 c = maps.grid.center(i, j);
    return c.x < open_beyond.min.x || c.x > open_beyond.max.x || c.y < open_beyond.min.z ||
           c.y > open_beyond.max.z;
  };
  const float texel = maps.grid.texel;
  const float reach = std::ceil(radius / texel);  // texels (inf on absurdly fine maps)
  // Distance (texels) from the nearest free-edge member; far: +inf.
  std::vector<float> steps(f.s.size(), std::numeric_limits<float>::infinity());
  std::vector<size_t> edge;
  TexelRows rows(maps);
  static const int kDi[4] = {1, -1, 0, 0}, kDj[4] = {0, 0, 1, -1};
  for (size_t k : patch.texels) {
    const TexelCoord c = rows(k);
    const size_t a = f.at(c.i - f.i0, c.j - f.j0);
    const float s = depth[k], top = maps.ground[k] + s;
    for (int n = 0; n < 4; ++n) {
      if (f.member[f.at(c.i - f.i0 + kDi[n], c.j - f.j0 + kDj[n])]) continue;
      const int ni = c.i + kDi[n], nj = c.j + kDj[n];
      if (goes_on(ni, nj)) continue;
      const int l = landing(maps, depth.data(), ni, nj, top, maps.ground[k]);
      bool drop = l == kLandVoid;
      if (l >= 0) {
        const size_t kn = maps.index(l, ni, nj);
        drop = top - (maps.ground[kn] + std::max(depth[kn], 0.0f)) > 0.5f * s;
      }
      if (drop) {
        steps[a] = 0.0f;
        if (f.drop_edge.empty()) f.drop_edge.assign(f.s.size(), 0);
        f.drop_edge[a] = l == kLandVoid ? kDropToVoid : kDropToSurface;
        edge.push_back(a);
        break;
      }
    }
  }
  if (edge.empty()) return;
  std::vector<glm::ivec2> seed(f.s.size());  // each sample's nearest seed, after a chamfer
  const auto chamfer = [&](std::vector<float>& d) { member_distances(f, d, seed); };
  chamfer(steps);
  // The core: members a shoulder's width or more from every free edge, and
  // the ridges of strips narrower than two shoulders (members no nearer to
  // an edge than any neighbour). The shoulder follows the distance to the
  // core: a member lies x = x_core - d from the outline, x_core the core
  // sample's own distance from it (the shoulder's width, or a narrow
  // strip's half width) and d the distance to it. That rounds convex
  // corners in plan too (the inward offsets of a square have mitred
  // corners; those of the core, grown back, round ones).
  std::vector<float> to_core(f.s.size(), std::numeric_limits<float>::infinity());
  const auto ridge = [&](int wi, int wj) {
    const float d = steps[f.at(wi, wj)];
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        const int ni = wi + di, nj = wj + dj;
        if (ni < 0 || nj < 0 || ni >= f.w || nj >= f.h) continue;
        const size_t b = f.at(ni, nj);
        if (f.member[b] && steps[b] > d) return false;
      }
    }
    return true;
  };
  for (int wj = 0; wj < f.h; ++wj) {
    for (int wi = 0; wi < f.w; ++wi) {
      const size_t a = f.at(wi, wj);
      if (!f.member[a]) continue;
      if ((steps[a] + 1.0f) * texel >= radius || ridge(wi, wj)) to_core[a] = 0.0f;
    }
  }
  chamfer(to_core);
  std::vector<float> x_of(f.s.size(), 0.0f);  // m, from the rounded outline
  for (size_t a = 0; a < f.s.size(); ++a) {
    if (!f.member[a] || !std::isfinite(to_core[a])) continue;
    const size_t core = f.at(seed[a].x, seed[a].y);
    const float x_core = std::min(radius, (steps[core] + 1.0f) * texel);
    x_of[a] = x_core - to_core[a] * texel;
    // Only the edges of snow wider than two shoulders bulge (add_lips).
    if (x_core < radius && !f.drop_edge.empty()) f.drop_edge[a] = 0;
  }
  // The thickness (m) of shoulder member a, s thick, at x from the rounded
  // outline: a quarter circle of radius min(radius, s) rising from it; none
  // beyond it (a square corner's tip): the outline rounds there.
  const auto shaped = [&](size_t a) {
    const float x = x_of[a];
    if (x <= 0.0f) return 0.0f;
    const float s = f.s[a], r = std::min(radius, s);
    if (x >= r) return s;
    const float u = r - x;
    return s - r + std::sqrt(std::max(r * r - u * u, 0.0f));
  };
  f.shoulder.assign(f.s.size(), 0);
  // The snow the shoulders give up stays in the patch: every member is
  // raised by its share first (the shoulders' loss barely depends on the
  // depth), so the mesh holds the snow the maps hold.
  double removed = 0.0;  // m, thickness the shoulders give up, summed over samples
  size_t members = 0;
  for (size_t a = 0; a < f.s.size(); ++a) {
    if (!f.member[a]) continue;
    ++members;
    if (steps[a] > reach) continue;
    f.shoulder[a] = 1;
    removed += double(f.s[a]) - double(shaped(a));
  }
  const float raise = float(removed / double(members));
  for (size_t a = 0; a < f.s.size(); ++a) {
    if (f.member[a]) f.s[a] += raise;
  }
  for (size_t a = 0; a < f.s.size(); ++a) {
    if (f.shoulder[a]) f.s[a] = shaped(a);
  }
}

// Each sample gathers its four fluxes, on all cores, in the order a serial
// sweep over the rows would add them: from the member above, from the one
// to the left, then its own to the right and down.
void smooth_field(PatchField& f, int iterations, float min_thickness) {
  const float kRate = 0.125f;
  // The flux from member a to member b.
  auto flux = [&](size_t a, size_t b) {
    if (!f.shoulder.empty() && (f.shoulder[a] || f.shoulder[b])) return 0.0f;
    const float flow = kRate * ((f.g[a] + f.s[a]) - (f.g[b] + f.s[b]));  // a -> b
    return std::clamp(flow, -0.25f * std::max(f.s[b] - min_thickness, 0.0f),
                      0.25f * std::max(f.s[a] - min_thickness, 0.0f));
  };
  // The pairs a serial sweep visits: a sample with a right and a lower
  // neighbour in the window sends to both, if both are members.
  auto sends = [&](int i, int j) { return i < f.w - 1 && j < f.h - 1; };
  LayerArray<float> next(f.s.size());  // each sample written in each iteration
  for (int it = 0; it < iterations; ++it) {
    each_sample(f, threads_for(f.s.size()), [&](int wi, int wj, size_t a) {
      float delta = 0.0f;
      if (f.member[a]) {
        if (wj > 0 && sends(wi, wj - 1) && f.member[f.at(wi, wj - 1)]) {
          delta += flux(f.at(wi, wj - 1), a);
        }
        if (wi > 0 && sends(wi - 1, wj) && f.member[f.at(wi - 1, wj)]) {
          delta += flux(f.at(wi - 1, wj), a);
        }
        if (sends(wi, wj)) {
          if (f.member[f.at(wi + 1, wj)]) delta -= flux(a, f.at(wi + 1, wj));
          if (f.member[f.at(wi, wj + 1)]) delta -= flux(a, f.at(wi, wj + 1));
        }
      }
      next[a] = f.s[a] + delta;
    });
    f.s.swap(next);
  }
}

}  // namespace snow::poly
