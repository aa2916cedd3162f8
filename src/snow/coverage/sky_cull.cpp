// The sky cull of the coverage stage: receivers lit or shaded along every
// fall direction, settled before any method runs (no shadow map, no ray).
// A line of fall from a receiver p at height y rises s metres while it
// moves at most s tan(theta_max) sideways, and hits within eps of the
// receiver (s <= eps) do not count (the reference's rule, for the
// receiver's own surface). So a scene point q can only be in its way if
// height(q) > top(q) = y + max(eps, cot(theta_max) |q - p|_xz): a cone with
// a flat top of radius eps / cot around p. The scene's BVH is walked with
// that test on each node's highest point at its box's xz distance, once per
// small tile of receivers (at the tile's distance and lowest receiver);
// then per receiver, in each leaf the tile kept whose node fails for it, a
// triangle is harmless when it lies wholly under top(): top minus the
// height, a convex function, is >= 0 at its minimum over the triangle,
// which lies on the flat top's rim or on an edge (found in closed form).
// The exact edge test keeps a terrain's ridges culled where the bound of
// the highest corner at the footprint's distance would not.
// So a receiver on a gentle slope or terrain is culled whatever its own
// triangles do, and nothing that shades a receiver is ever overlooked. The
// snow surface (snow on snow) is bounded by a max pyramid of the snowy tops.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "core/parallel.h"
#include "snow/bvh.h"
#include "snow/coverage/internal.h"
#include "snow/maps.h"
#include "snow/reference/coverage_ref.h"

namespace snow::cov {
namespace {

struct Cone {
  Cone(const glm::vec2& at, float height, float own, float cot_max)
      : p(at), y(height), eps(own), cot(cot_max), r0(double(own) / double(cot_max)) {}
  glm::dvec2 p;  // metres, the receiver's xz
  double y;      // metres, its height
  double eps;    // metres, surfaces less than this above it are its own
  double cot;    // cot(theta_max), metres up per metre sideways
  double r0;     // metres, radius of the flat top
  double top(double d) const { return y + std::max(eps, cot * d); }
};

// Distance in xz from p to the triangle's footprint (0 inside).
double distance_xz(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c,
                   const glm::vec2& p) {
  const glm::dvec2 q(p), v[3] = {{a.x, a.z}, {b.x, b.z}, {c.x, c.z}};
  const auto cross2 = [](const glm::dvec2& u, const glm::dvec2& w) {
    return u.x * w.y - u.y * w.x;
  };
  const double s0 = cross2(v[1] - v[0], q - v[0]), s1 = cross2(v[2] - v[1], q - v[1]),
               s2 = cross2(v[0] - v[2], q - v[2]);
  if ((s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0)) return 0.0;
  // The nearest edge by squared distance: one square root (the smallest of
  // the roots is the root of the smallest, rounding is monotone).
  double best = std::numeric_limits<double>::max();
  for (int e = 0; e < 3; ++e) {
    const glm::dvec2 u = v[e], w = v[(e + 1) % 3];
    const glm::dvec2 d = w - u;
    const double len2 = glm::dot(d, d);
    const double s = len2 > 0 ? std::clamp(glm::dot(q - u, d) / len2, 0.0, 1.0) : 0.0;
    const glm::dvec2 r = q - (u + s * d);
    best = std::min(best, glm::dot(r, r));
  }
  return std::sqrt(best);
}

// Smallest top(q) - h(q) over the segment q from u to w (xz in .x and .z,
// height h in .y, linear along it). It is convex along the segment: flat-
// topped near p, a cone beyond; so it is smallest at an end, where it
// crosses the flat top's rim, or at the cone's stationary point.
double edge_minimum(const glm::dvec3& u, const glm::dvec3& w, const Cone& cone) {
  const glm::dvec2 a(u.x - cone.p.x, u.z - cone.p.y), e(w.x - u.x, w.z - u.z);
  const auto value = [&](double t) {
    t = std::clamp(t, 0.0, 1.0);
    return cone.top(glm::length(a + t * e)) - (u.y + t * (w.y - u.y));
  };
  double best = std::min(value(0.0), value(1.0));
  const double ee = glm::dot(e, e);
  if (ee > 0.0) {
    // Where |a + t e| = r0 (the rim).
    const double ae = glm::dot(a, e);
    const double disc = ae * ae - ee * (glm::dot(a, a) - cone.r0 * cone.r0);
    if (disc >= 0.0) {
      best = std::min(
          {best, value((-ae - std::sqrt(disc)) / ee), value((-ae + std::sqrt(disc)) / ee)});
    }
    // Along the edge's line, s metres from the foot of the perpendicular
    // from p (at distance d): cot sqrt(d^2 + s^2) - k s, with k the height
    // gained per metre; stationary at s = k d / sqrt(cot^2 - k^2).
    const double len = std::sqrt(ee);
    const glm::dvec2 dir = e / len;
    const double s0 = -glm::dot(a, dir);  // the foot, metres from u
    const double d = std::abs(a.x * dir.y - a.y * dir.x);
    const double k = (w.y - u.y) / len;
    if (std::abs(k) < cone.cot) {
      best = std::min(best, value((s0 + k * d / std::sqrt(cone.cot * cone.cot - k * k)) / len));
    }
  }
  return best;
}

// The terms of triangle_harmless's first test that depend on the triangle
// alone (its plane's gradient g), worked out once per triangle where each
// is tested by many receivers.
struct TrianglePlane {
  double gx = 0.0, gz = 0.0;  // g, metres up per metre along x and z
  double slope = 0.0;         // |g|
  bool sloped = false;        // not seen edge-on from above
};

TrianglePlane triangle_plane(const glm::vec3* corner) {
  const glm::dvec3 a(corner[0]), b(corner[1]), c(corner[2]);
  const glm::dvec3 n = glm::cross(b - a, c - a);
  TrianglePlane plane;
  plane.sloped = std::abs(n.y) > 1e-9 * glm::length(n);
  plane.gx = plane.sloped ? -n.x / n.y : 0.0;
  plane.gz = plane.sloped ? -n.z / n.y : 0.0;
  plane.slope = std::sqrt(plane.gx * plane.gx + plane.gz * plane.gz);
  return plane;
}

bool triangle_harmless(const glm::vec3* corner, const TrianglePlane& plane, const Cone& cone) {
  const glm::dvec3 a(corner[0]), b(corner[1]), c(corner[2]);
  const bool sloped = plane.sloped;
  const double gx = plane.gx, gz = plane.gz, slope = plane.slope;
  // Over the plane, top - h is smallest inside the flat top at q* = p +
  // r0 g / |g| (g: the plane's gradient), and a gentle plane (|g| <= cot)
  // rises slower than the cone beyond it: then q* is the smallest over the
  // whole plane (the cheapest test, first).
  const double worst = a.y + gx * (cone.p.x - a.x) + gz * (cone.p.y - a.z) + cone.r0 * slope;
  if (sloped && slope <= cone.cot && worst <= cone.y + cone.eps) return true;
  // A corner over the cone is in the way; the highest corner under the cone
  // at the footprint's distance (every point of the triangle is at least
  // that far) is not.
  double highest = -std::numeric_limits<double>::infinity();
  for (const glm::dvec3* q : {&a, &b, &c}) {
    if (q->y > cone.top(glm::length(glm::dvec2(q->x, q->z) - cone.p))) return false;
    highest = std::max(highest, q->y);
  }
  if (highest <= cone.top(distance_xz(a, b, c, glm::vec2(cone.p)))) return true;
  // The exact answer: the smallest of top - h over the triangle lies at q*
  // (where the triangle holds it) or on an edge.
  if (sloped && worst > cone.y + cone.eps) {
    const glm::dvec2 q = slope > 0.0 ? cone.p + cone.r0 * glm::dvec2(gx, gz) / slope : cone.p;
    if (distance_xz(a, b, c, glm::vec2(q)) == 0.0) return false;
  }
  return std::min({edge_minimum(a, b, cone), edge_minimum(b, c, cone), edge_minimum(c, a, cone)}) >=
         0.0;
}

// The node test at the box's xz distance from the rectangle [lo, hi] (for
// a point, lo = hi): its highest point under the cone's top there.
bool node_harmless(const Bvh::Node& node, const glm::vec2& lo, const glm::vec2& hi,
                   const Cone& cone) {
  const double dx = std::max({double(node.min.x) - hi.x, double(lo.x) - node.max.x, 0.0});
  const double dz = std::max({double(node.min.z) - hi.y, double(lo.y) - node.max.z, 0.0});
  return double(node.max.y) <= cone.top(std::sqrt(dx * dx + dz * dz));
}

// The leaves of `bvh` that can hold a triangle in the way of a line of fall
// from some point of the xz rectangle [lo, hi] at height y or above (the
// stackless walk of Bvh::occluded with the node test above at the
// rectangle's distance), appended to `leaves`. A node that passes for the
// rectangle passes for each of its points, so a point's own walk reaches
// only leaves listed here.
void candidate_leaves(const Bvh& bvh, const glm::vec2& lo, const glm::vec2& hi, const Cone& cone,
                      std::vector<uint32_t>& leaves) {
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  const uint32_t count = uint32_t(nodes.size());
  for (uint32_t i = 0; i < count;) {
    const Bvh::Node& node = nodes[i];
    const bool harmless = node_harmless(node, lo, hi, cone);
    if (node.count == 0) {
      i = harmless ? node.first : i + 1;
      continue;
    }
    if (!harmless) leaves.push_back(i);
    ++i;
  }
}

// True when no triangle of the listed leaves can be in the way of a line of
// fall from (p, y): the node test, then each triangle's.
// `planes`: triangle_plane() of each triangle (leaf order), or none to work
// them out here.
bool leaves_open(const Bvh& bvh, const std::vector<TrianglePlane>& planes,
                 const std::vector<uint32_t>& leaves, const Cone& cone) {
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  const std::vector<glm::vec3>& corners = bvh.corners();
  const glm::vec2 p(cone.p);
  for (uint32_t leaf : leaves) {
    const Bvh::Node& node = nodes[leaf];
    if (node_harmless(node, p, p, cone)) continue;
    for (uint32_t t = node.first; t < node.first + node.count; ++t) {
      const glm::vec3* corner = &corners[3 * size_t(t)];
      const TrianglePlane plane = planes.empty() ? triangle_plane(corner) : planes[t];
      if (!triangle_harmless(corner, plane, cone)) return false;
    }
  }
  return true;
}

// True when triangle t (leaf order; false for Bvh::kNone) blocks every
// line of fall from p whose tilt from the vertical is at most
// atan(tan_max), higher than reference::own_surface(p.y) above p: p is
// shaded along every direction, as the reference's rays find (a receiver
// on the bottom of a solid whose top is t). The lines of the cone meet t's
// plane within R sideways of p, R = H tan_max / (1 - tan_max |g|) for a
// plane H above p rising |g| metres per metre, and at least
// H / (1 + tan_max |g|) above p; so that disc (with a margin for the rays'
// float rounding) must lie inside the triangle.
bool shades_cone(const Bvh& bvh, uint32_t t, const glm::vec3& p, double tan_max) {
  if (t == Bvh::kNone) return false;
  const float own = reference::own_surface(p.y);
  const glm::dvec3 a(bvh.corners()[3 * size_t(t)]), b(bvh.corners()[3 * size_t(t) + 1]),
      c(bvh.corners()[3 * size_t(t) + 2]), q(p);
  const glm::dvec3 m = glm::cross(b - a, c - a);
  if (!(std::abs(m.y) > 0.0)) return false;
  const double slope = std::hypot(m.x, m.z) / std::abs(m.y);
  if (!(tan_max * slope < 0.5)) return false;
  const double h = a.y - (m.x * (q.x - a.x) + m.z * (q.z - a.z)) / m.y - q.y;
  if (!(h / (1.0 + tan_max * slope) > 2.0 * double(own))) return false;
  const double scale = std::max({std::abs(q.x), std::abs(q.z), std::abs(a.x), std::abs(a.z),
                                 std::abs(b.x), std::abs(b.z), std::abs(c.x), std::abs(c.z)});
  const double r = h * tan_max / (1.0 - tan_max * slope) + 1e-5 * (1.0 + scale);
  const glm::dvec2 v[3] = {{a.x, a.z}, {b.x, b.z}, {c.x, c.z}}, at(q.x, q.z);
  const double turn = m.y > 0.0 ? -1.0 : 1.0;  // v runs counter-clockwise in (x, z) for m.y < 0
  for (int e = 0; e < 3; ++e) {
    const glm::dvec2 d = v[(e + 1) % 3] - v[e], w = at - v[e];
    if (!(turn * (d.x * w.y - d.y * w.x) >= r * glm::length(d))) return false;
  }
  return true;
}

// Max pyramid over the snowy tops (each spread over its 3 x 3 texel squares,
// since the heightfield spans texel centres): open(p, y) when every cell's
// max passes the test at the cell's distance.
class SnowBound {
 public:
  SnowBound(const SnowMaps& maps, const std::vector<float>& top) : g_(maps.grid) {
    const int w = g_.width, h = g_.height;
    std::vector<float> base(size_t(w) * size_t(h), -kOpenSky);
    const size_t texels = g_.texels();
    for (int l = 0; l < maps.layers; ++l) {
      for (int j = 0; j < h; ++j) {
        for (int i = 0; i < w; ++i) {
          const size_t k = size_t(l) * texels + size_t(j) * size_t(w) + size_t(i);
          const float v = top[k];
          if (std::isnan(v) || !(v > maps.ground[k])) continue;
          for (int dj = std::max(0, j - 1); dj <= std::min(h - 1, j + 1); ++dj) {
            for (int di = std::max(0, i - 1); di <= std::min(w - 1, i + 1); ++di) {
              float& m = base[size_t(dj) * size_t(w) + size_t(di)];
              m = std::max(m, v);
            }
          }
        }
      }
    }
    levels_.push_back(std::move(base));
    sizes_.emplace_back(w, h);
    while (sizes_.back().x > 1 || sizes_.back().y > 1) {
      const glm::ivec2 from = sizes_.back();
      const glm::ivec2 to((from.x + 1) / 2, (from.y + 1) / 2);
      std::vector<float> next(size_t(to.x) * size_t(to.y), -kOpenSky);
      const std::vector<float>& prev = levels_.back();
      for (int j = 0; j < from.y; ++j) {
        for (int i = 0; i < from.x; ++i) {
          float& m = next[size_t(j / 2) * size_t(to.x) + size_t(i / 2)];
          m = std::max(m, prev[size_t(j) * size_t(from.x) + size_t(i)]);
        }
      }
      levels_.push_back(std::move(next));
      sizes_.push_back(to);
    }
  }

  bool open(const Cone& cone) const {
    const glm::vec2 p(cone.p);
    struct Node {
      int level, i, j;
    };
    Node stack[4 * 40];
    int top = 0;
    stack[top++] = {int(levels_.size()) - 1, 0, 0};
    while (top > 0) {
      const Node n = stack[--top];
      const float span = g_.texel * float(1 << n.level);
      const glm::vec2 lo = g_.origin + glm::vec2(n.i, n.j) * span;
      const glm::vec2 d = glm::max(glm::max(lo - p, p - (lo + span)), glm::vec2(0.0f));
      const float m =
          levels_[size_t(n.level)][size_t(n.j) * size_t(sizes_[size_t(n.level)].x) + size_t(n.i)];
      if (double(m) <= cone.top(glm::length(glm::dvec2(d)))) continue;
      if (n.level == 0) return false;
      const glm::ivec2 size = sizes_[size_t(n.level) - 1];
      for (int c = 0; c < 4; ++c) {
        const int ci = 2 * n.i + (c & 1), cj = 2 * n.j + (c >> 1);
        if (ci < size.x && cj < size.y && top < 4 * 40) stack[top++] = {n.level - 1, ci, cj};
      }
    }
    return true;
  }

 private:
  MapGrid g_;
  std::vector<std::vector<float>> levels_;
  std::vector<glm::ivec2> sizes_;
};

// Receivers are culled in tiles of kTile x kTile texels (cull_receivers).
constexpr int kTile = 4;

// What the cull of each band of receivers reads.
struct CullInput {
  const Bvh& bvh;
  const SnowMaps& maps;
  const std::vector<glm::uvec4>& recv;
  const std::vector<uint32_t>& recv_index;
  const std::vector<TrianglePlane>& planes;  // triangle_plane of each triangle, or none
  const SnowBound* snow_bound;               // the snowy tops' bound (snow on snow), or null
  double tan_max;                            // of the fall directions
  float cot_max;                             // 1 / tan_max
};

// The first receiver of each band of kTile rows of a layer (a run of
// receivers: they come in layer, row, column order), then recv.size().
std::vector<size_t> receiver_bands(const std::vector<glm::uvec4>& recv,
                                   const std::vector<uint32_t>& recv_index, size_t texels) {
  const auto band_of = [&](size_t r) {
    return std::make_pair(recv_index[r] / texels, (recv[r].x >> 16) / uint32_t(kTile));
  };
  std::vector<size_t> bands;
  for (size_t r = 0; r < recv.size(); ++r) {
    if (r == 0 || band_of(r) != band_of(r - 1)) bands.push_back(r);
  }
  bands.push_back(recv.size());
  return bands;
}

// A receiver with a surface of the maps straight above it, higher than its
// own (by twice own_surface, for the peel's rounding), is shaded along the
// vertical line of fall, which every cone holds: the tile test would keep
// it. Most receivers under a layer are (the inside of solids, floors under
// roofs), so they skip that test, and their tiles' candidate leaves are the
// other receivers'. (One open after all would still be counted lit along
// every direction.) These are tested instead for a triangle above that
// shades them along every direction (shades_cone): the bottoms of solids,
// such as a ground slab's underside. One with a surface above no higher
// than that is a second sheet of it (reference::second_sheet): shaded too.
enum class Above { Open, SecondSheet, Covered };
Above above_of(const SnowMaps& maps, const glm::uvec4& packed, size_t k) {
  const size_t texels = maps.grid.texels();
  if (k < texels || std::isnan(maps.ground[k - texels])) return Above::Open;
  return reference::second_sheet(maps, k, receiver_height(packed)) ? Above::SecondSheet
                                                                   : Above::Covered;
}

// A receiver at height y in layer texel k is sealed under a thin cover
// when its column and the 8 around it each hold a surface of the maps
// higher than reference::own_surface(y) above it, the lowest of which lies
// at most kSealedReach texels / tan_max above it: every line of fall of the
// cone, which rises at least cot_max metres per metre sideways, meets that
// cover within half a texel of the receiver, between the covers' texel
// centres. The maps' surfaces are the scene at their resolution (as the
// stabilizer sees it), so this needs no triangle: the shadow maps could not
// tell such a cover, thinner than their bias and the receiver plane's rise
// over a shadow texel, from the receiver's own surface, and would count
// the snow that falls on the cover again on the receiver under it (the
// inner sheet of a double-sheeted cushion).
constexpr double kSealedReach = 0.5;  // texels sideways
bool sealed(const SnowMaps& maps, size_t k, float y, double tan_max) {
  const MapGrid& g = maps.grid;
  const size_t texels = g.texels();
  const int i = int(k % texels % size_t(g.width)), j = int(k % texels / size_t(g.width));
  const double reach = tan_max > 0.0 ? kSealedReach * double(g.texel) / tan_max : kOpenSky;
  const float above = y + reference::own_surface(y);
  for (int nj = j - 1; nj <= j + 1; ++nj) {
    for (int ni = i - 1; ni <= i + 1; ++ni) {
      if (ni < 0 || nj < 0 || ni >= g.width || nj >= g.height) return false;
      // Layers run from the top down: the last surface above is the lowest.
      // Bridges are not covers: they are no triangles (the rays pass them),
      // and the snow under them is masked off (mask_coverage).
      const int bridge = maps.bridge.empty() ? -1 : maps.bridge[size_t(nj) * g.width + ni];
      float cover = std::numeric_limits<float>::quiet_NaN();
      for (int l = 0; l < maps.layers; ++l) {
        const float ground = maps.ground[maps.index(l, ni, nj)];
        if (!(ground > above)) break;
        if (l != bridge) cover = ground;
      }
      if (!(double(cover) - double(y) <= reach)) return false;
    }
  }
  return true;
}

// Receivers [r0, r1) (a band) that are covered: kShaded in `culled` where
// they are second sheets or sealed under a thin cover, or a triangle above
// shades them along every direction. Returns the others.
std::vector<uint32_t> shade_covered(const CullInput& in, size_t r0, size_t r1,
                                    std::vector<uint8_t>& culled) {
  std::vector<uint32_t> order;
  order.reserve(r1 - r0);
  uint32_t shade = Bvh::kNone;
  for (size_t r = r0; r < r1; ++r) {
    const Above above = above_of(in.maps, in.recv[r], in.recv_index[r]);
    if (above == Above::Open) {
      order.push_back(uint32_t(r));
      continue;
    }
    if (above == Above::SecondSheet) {
      culled[r] = kShaded;
      continue;
    }
    const glm::vec3 p = receiver_point(in.maps.grid, in.recv[r]);
    if (sealed(in.maps, in.recv_index[r], p.y, in.tan_max)) {
      culled[r] = kShaded;
      continue;
    }
    // The last receiver's triangle, else the first the vertical line
    // up meets (tested again only if it is another).
    bool shaded = shades_cone(in.bvh, shade, p, in.tan_max);
    if (!shaded) {
      const uint32_t hit =
          in.bvh.first_hit(p, glm::vec3(0.0f, 1.0f, 0.0f), reference::own_surface(p.y), kOpenSky);
      shaded = hit != shade && shades_cone(in.bvh, hit, p, in.tan_max);
      shade = hit;
    }
    if (shaded) culled[r] = kShaded;
  }
  return order;
}

// The receivers of `order` (a band's, in order) walked in tiles of kTile x
// kTile texels: the tile's rectangle and lowest receiver list the BVH
// leaves that can shade any of them, and each receiver tests only those;
// kOpen in `culled` for those that nothing can shade.
void open_tiles(const CullInput& in, std::vector<uint32_t>& order, std::vector<uint8_t>& culled) {
  const auto tile_of = [&](size_t r) { return (in.recv[r].x & 0xffffu) / uint32_t(kTile); };
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t c) { return tile_of(a) < tile_of(c); });
  std::vector<uint32_t> leaves;
  for (size_t a = 0; a < order.size();) {
    size_t e = a;
    glm::vec2 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    float y_min = kOpenSky;
    for (; e < order.size() && tile_of(order[e]) == tile_of(order[a]); ++e) {
      const glm::vec3 p = receiver_point(in.maps.grid, in.recv[order[e]]);
      lo = glm::min(lo, glm::vec2(p.x, p.z));
      hi = glm::max(hi, glm::vec2(p.x, p.z));
      y_min = std::min(y_min, p.y);
    }
    leaves.clear();
    candidate_leaves(in.bvh, lo, hi, Cone(lo, y_min, reference::own_surface(0.0f), in.cot_max),
                     leaves);
    for (; a < e; ++a) {
      const glm::vec3 p = receiver_point(in.maps.grid, in.recv[order[a]]);
      const Cone cone(glm::vec2(p.x, p.z), p.y, reference::own_surface(p.y), in.cot_max);
      culled[order[a]] = leaves_open(in.bvh, in.planes, leaves, cone) &&
                                 (!in.snow_bound || in.snow_bound->open(cone))
                             ? kOpen
                             : kKept;
    }
  }
}

}  // namespace

double steepest_tan(const std::vector<glm::vec3>& dirs) {
  double tan_max = 0;
  for (const glm::vec3& d : dirs) {
    tan_max = std::max(tan_max, double(std::hypot(d.x, d.z)) / double(-d.y));
  }
  return tan_max;
}

std::vector<uint8_t> cull_receivers(const Bvh& bvh, const SnowMaps& maps,
                                    const std::vector<float>* snow_top,
                                    const std::vector<glm::uvec4>& recv,
                                    const std::vector<uint32_t>& recv_index, double tan_max) {
  const float cot_max = tan_max > 0 ? float(1.0 / tan_max) : 1e30f;
  std::unique_ptr<SnowBound> snow_bound;
  if (snow_top) snow_bound = std::make_unique<SnowBound>(maps, *snow_top);
  const std::vector<size_t> bands = receiver_bands(recv, recv_index, maps.grid.texels());
  // Surfaces less than reference::own_surface(y) above a receiver are its
  // own, as for the reference's rays, so rays give the reference's result
  // (the tiles' lists take its lowest value, at y = 0: a superset). The
  // shadow maps' bias (a quarter texel) would cull more receivers only
  // where a surface lies that close above one.
  std::vector<uint8_t> culled(recv.size(), kKept);
  // Each triangle is tested by the receivers around it: its plane's terms
  // are worked out once, unless the triangles far outnumber the receivers
  // (a small, dense model tests few of its triangles).
  const size_t triangles = bvh.triangle_count();
  std::vector<TrianglePlane> planes;
  if (triangles <= 4 * recv.size()) {
    planes.resize(triangles);
    constexpr size_t kChunk = 4096;
    parallel_for_ranges(triangles, kChunk, [&](size_t begin, size_t end) {
      for (size_t t = begin; t < end; ++t) planes[t] = triangle_plane(&bvh.corners()[3 * t]);
    });
  }
  const CullInput in{bvh, maps, recv, recv_index, planes, snow_bound.get(), tan_max, cot_max};
  parallel_for(bands.size() - 1, [&](size_t b) {
    std::vector<uint32_t> order = shade_covered(in, bands[b], bands[b + 1], culled);
    open_tiles(in, order, culled);
  });
  return culled;
}

void drop_culled(const std::vector<uint8_t>& culled, std::vector<glm::uvec4>& recv,
                 std::vector<uint32_t>& recv_index, std::vector<float>& coverage) {
  size_t kept = 0;
  for (size_t r = 0; r < recv.size(); ++r) {
    if (culled[r]) {
      coverage[recv_index[r]] = culled[r] == kOpen ? 1.0f : 0.0f;
      continue;
    }
    recv[kept] = recv[r];
    recv_index[kept] = recv_index[r];
    ++kept;
  }
  recv.resize(kept);
  recv_index.resize(kept);
}

}  // namespace snow::cov
