// Stage 2: snow coverage from jittered multi-direction shadow maps.
// Tokoi, "A Shadow Buffer Technique for Simulating Snow-Covered Shapes"
// (2006), section 4 (shadow buffers from many directions, composited);
// flake flutter and wind after Fearing, "Computer Modelling of Fallen Snow"
// (SIGGRAPH 2000), section 4.1. Direction sampling: stratified in cos(angle)
// with a golden-ratio azimuth sequence (a jittered spherical Fibonacci
// pattern), uniform in solid angle over the cone. Shadow-map comparison with
// a receiver-plane depth bias (Isidoro, "Shadow Mapping: GPU-based Tips and
// Techniques", GDC 2006); uncertain texels resolved by exact ray casting
// through a BVH (shaders/coverage_common.glsl explains the two passes).
#include "snow/coverage.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <numeric>
#include <optional>
#include <string>

#include <glm/gtc/packing.hpp>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "shaders/bindings.h"
#include "snow/bvh.h"
#include "snow/gpu_scene.h"
#include "snow/reference/coverage_ref.h"

namespace snow {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kGoldenFraction = 0.6180339887498949;  // frac of the golden ratio
constexpr uint64_t kJitterStream = 0xD1B54A32D192ED03ull;
constexpr float kNoSnowSurface = -3.0e38f;  // "no surface" in the snow-surface texture
constexpr int kLocalSize = 64;              // coverage.comp's local_size_x
constexpr int kMaxShadowSide = 16384;       // texels, also capped by GL_MAX_TEXTURE_SIZE
constexpr int kMaxBatch = 32;               // shadow maps per batch (a 32-bit direction mask)
/// splitmix64 (Steele, Lea and Flood 2014): tiny, fast, same stream everywhere.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1), 53 bits.
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  uint64_t state_;
};

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

std::string seconds(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f s", v);
  return text;
}

void validate(const CoverageSettings& s) {
  if (s.directions < 1 || s.directions > 4096) {
    throw InputError("directions must be in 1..4096, got " + std::to_string(s.directions));
  }
  if (!(s.flutter_deg >= 0.0f && s.flutter_deg <= 60.0f)) {
    throw InputError("flutter must be in 0..60 degrees, got " + number(s.flutter_deg));
  }
  if (s.batch < 0 || s.batch > kMaxBatch) {
    throw InputError("shadow-map batch must be in 1..32 (0: automatic), got " +
                     std::to_string(s.batch));
  }
  if (!std::isfinite(s.bias)) throw InputError("shadow bias must be finite");
  if (s.method != "auto" && s.method != "shadow-maps" && s.method != "rays" &&
      s.method != "cpu-rays" && s.method != "cpu-shadow-maps") {
    throw InputError(
        "coverage method must be auto, shadow-maps, rays, cpu-rays or cpu-shadow-maps, got '" +
        s.method + "'");
  }
  const glm::dvec3 m(mean_fall_direction(s));
  const double tilt = std::acos(std::clamp(-m.y, -1.0, 1.0)) * 180.0 / kPi;
  if (tilt + s.flutter_deg > kMaxFallAngleDeg) {
    throw InputError("wind of " + number(glm::length(s.wind)) + " m/s against a fall speed of " +
                     number(s.fall_speed) + " m/s tilts the snow by " + number(tilt) +
                     " degrees; with " + number(s.flutter_deg) +
                     " degrees of flutter that exceeds " + number(kMaxFallAngleDeg) +
                     " degrees from the vertical");
  }
}

// Uploads the batch's direction parameters to `batch_directions[]`.
void set_batch_directions(const gl::Program& program, const glm::vec4* params, int n) {
  const GLint location = glGetUniformLocation(program.id(), "batch_directions");
  glProgramUniform4fv(program.id(), location, n, &params[0].x);
  program.set("direction_count", n);
}

glm::vec3 gradient_normal(const SnowMaps& maps, const std::vector<float>& top, int l, int i,
                          int j) {
  // Snow-surface normal from one-sided height differences on the same layer:
  // per axis, the steeper available side (bias must cover both triangles).
  const MapGrid& g = maps.grid;
  const float cut = kSnowSurfaceCutTexels * g.texel;
  const float h = top[maps.index(l, i, j)];
  const auto slope = [&](int di, int dj) {
    float best = 0.0f;
    for (int side : {-1, 1}) {
      const int ni = i + side * di, nj = j + side * dj;
      if (ni < 0 || nj < 0 || ni >= g.width || nj >= g.height) continue;
      const float hn = top[maps.index(l, ni, nj)];
      if (std::isnan(hn) || std::abs(hn - h) > cut) continue;
      const float s = (hn - h) * float(side) / g.texel;
      if (std::abs(s) > std::abs(best)) best = s;
    }
    return best;
  };
  return glm::normalize(glm::vec3(-slope(1, 0), 1.0f, -slope(0, 1)));
}

// Culling of receivers that see the open sky along every direction, before
// any GPU work. A line of fall from a receiver p at height y rises s metres
// while it moves at most s tan(theta_max) sideways, and hits within eps of
// the receiver (s <= eps) do not count (the reference's rule, for the
// receiver's own surface). So a scene point q can only be in its way if
// height(q) > top(q) = y + max(eps, cot(theta_max) |q - p|_xz): a cone with
// a flat top of radius eps / cot around p. The scene's BVH is walked with
// that test on each node's highest point at its box's xz distance, once per
// small tile of receivers (at the tile's distance and lowest receiver);
// then per receiver, in each leaf the tile kept whose node fails for it, a
// triangle is harmless when it lies wholly under top(): top minus the
// height, a convex function, is >= 0 at its minimum over the triangle,
// which lies on the flat top's rim or on an edge (found in closed form).
// The exact edge test keeps a terrain's ridges culled where the bound it
// replaced (the highest corner at the footprint's distance) did not.
// So a receiver on a gentle slope or terrain is culled whatever its own
// triangles do, and nothing that shades a receiver is ever overlooked. The
// snow surface (snow on snow) is bounded by a max pyramid of the snowy tops.
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
// is tested by many receivers (culling on a 100k-triangle terrain at 512
// texels: 0.35 -> 0.28 s of CPU time).
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

}  // namespace

int shadow_batch(const CoverageSettings& settings, double shadow_texels) {
  return plan::choose_shadow_batch(settings.batch, settings.directions, shadow_texels, kMaxBatch);
}

glm::vec3 mean_fall_direction(const CoverageSettings& s) {
  if (!(s.fall_speed > 0.0f) || !std::isfinite(s.fall_speed)) {
    throw InputError("flake fall speed must be a finite number > 0 m/s, got " +
                     number(s.fall_speed));
  }
  if (!std::isfinite(s.wind.x) || !std::isfinite(s.wind.y)) {
    throw InputError("wind must be finite");
  }
  const glm::dvec3 v(s.wind.x, -double(s.fall_speed), s.wind.y);
  return glm::vec3(v / glm::length(v));
}

std::vector<glm::vec3> fall_directions(const CoverageSettings& s) {
  validate(s);
  const glm::dvec3 m(mean_fall_direction(s));
  // Orthonormal frame (m, e1, e2).
  const glm::dvec3 ref = std::abs(m.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 0, 1);
  const glm::dvec3 e1 = glm::normalize(glm::cross(m, ref));
  const glm::dvec3 e2 = glm::cross(m, e1);
  const double cos_max = std::cos(double(s.flutter_deg) * kPi / 180.0);
  SplitMix64 rng(s.seed);
  const double rotation = rng.uniform();
  const int k_count = s.directions;
  std::vector<glm::vec3> out;
  out.reserve(size_t(k_count));
  for (int k = 0; k < k_count; ++k) {
    const double u1 = (k + rng.uniform()) / k_count;  // stratum k, jittered
    const double cos_t = 1.0 - u1 * (1.0 - cos_max);
    const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
    double turn = k * kGoldenFraction + rotation + (rng.uniform() - 0.5) / k_count;
    turn -= std::floor(turn);
    const double phi = 2.0 * kPi * turn;
    const glm::dvec3 d = cos_t * m + sin_t * (std::cos(phi) * e1 + std::sin(phi) * e2);
    out.push_back(glm::vec3(glm::normalize(d)));
  }
  return out;
}

std::vector<glm::vec2> shadow_origin_jitter(const CoverageSettings& s) {
  SplitMix64 rng(s.seed ^ kJitterStream);
  std::vector<glm::vec2> out(size_t(std::max(0, s.directions)));
  for (glm::vec2& j : out) {
    const double x = rng.uniform();
    const double y = rng.uniform();
    j = glm::vec2(float(x), float(y));
    // float rounding of values just below 1 must not reach 1.
    j = glm::min(j, glm::vec2(std::nextafter(1.0f, 0.0f)));
  }
  return out;
}

// A receiver as packed for the passes (coverage_common.glsl's Receivers):
// its texel, its height and its point.
glm::ivec2 receiver_texel(const glm::uvec4& r) { return {int(r.x & 0xffffu), int(r.x >> 16)}; }
float receiver_height(const glm::uvec4& r) {
  float y;
  std::memcpy(&y, &r.y, sizeof y);
  return y;
}
glm::vec3 receiver_point(const MapGrid& grid, const glm::uvec4& r) {
  const glm::ivec2 t = receiver_texel(r);
  const glm::vec2 xz = grid.center(t.x, t.y);
  return {xz.x, receiver_height(r), xz.y};
}

// --- Shadow maps on the CPU (CoverageMethod::CpuShadowMaps) ------------------

constexpr float kNoShadow = -std::numeric_limits<float>::infinity();  // no surface drawn

/// Where a direction's shadow map lies: (a, b, u0, v0) as in shadow.vert
/// (shadow-map metres u = x - a y - u0, v = z - b y - v0), texels of st
/// metres, `size` texels.
struct ShadowFrame {
  glm::dvec4 params;
  double st;
  glm::ivec2 size;
  double inv_st = 1.0 / st;
  glm::dvec2 texel_of(const glm::vec3& q) const {  // texel coordinates (centres at i + 0.5)
    return glm::dvec2((double(q.x) - params.z - double(q.y) * params.x) * inv_st,
                      (double(q.z) - params.w - double(q.y) * params.y) * inv_st);
  }
};

namespace {

// floor(x) and ceil(x) clamped to [lo, hi], as int(std::clamp(std::floor(x),
// lo, hi)) and int(std::clamp(std::ceil(x), lo, hi)) for x not NaN:
// clamping first, then truncating, saves the floating-point rounding that
// x86-64's baseline (SSE2) lacks (a third of the classification's time).
inline int floor_in(double x, int lo, int hi) {
  const double c = std::clamp(x, double(lo), double(hi));
  const int t = int(c);
  return t - int(c < double(t));
}
inline int ceil_in(double x, int lo, int hi) {
  const double c = std::clamp(x, double(lo), double(hi));
  const int t = int(c);
  return t + int(c > double(t));
}

}  // namespace

/// A texel of a CPU shadow map drawn by no scene triangle (or by the snow
/// surface's).
constexpr uint32_t kNoTriangle = ~0u;
// Texels a triangle's box spans along x from which its rows are drawn as runs.
constexpr int kMinRun = 8;

/// The tiles of kShift x kShift texels of a CPU shadow map that some
/// receiver reads: a triangle whose box meets none of them is not drawn.
struct TexelMask {
  static constexpr int kShift = 4;
  int tiles_x = 0;
  std::vector<uint8_t> on;

  void reset(glm::ivec2 size) {
    tiles_x = ((size.x - 1) >> kShift) + 1;
    on.assign(size_t(tiles_x) * size_t(((size.y - 1) >> kShift) + 1), 0);
  }
  /// Marks texels [i0, i1] x [j0, j1].
  void mark(int i0, int i1, int j0, int j1) {
    for (int b = j0 >> kShift; b <= j1 >> kShift; ++b) {
      std::fill_n(on.begin() + ptrdiff_t(size_t(b) * size_t(tiles_x) + size_t(i0 >> kShift)),
                  (i1 >> kShift) - (i0 >> kShift) + 1, uint8_t(1));
    }
  }
  /// fn(s, e) for each longest span [s, e] of texels [a, b] of row j that
  /// lies in marked tiles, left to right.
  template <class Fn>
  void each_span(int j, int a, int b, const Fn& fn) const {
    const uint8_t* row = on.data() + size_t(j >> kShift) * size_t(tiles_x);
    for (int t = a >> kShift; t <= b >> kShift;) {
      if (!row[t]) {
        ++t;
        continue;
      }
      const int s = std::max(a, t << kShift);
      while (t <= b >> kShift && row[t]) ++t;
      fn(s, std::min(b, (t << kShift) - 1));
    }
  }
  /// Sets the marked tiles' texels of a map of `size` texels to v.
  void fill(std::vector<float>& map, glm::ivec2 size, float v) const {
    for (int j = 0; j < size.y; ++j) {
      each_span(j, 0, size.x - 1, [&](int s, int e) {
        std::fill_n(map.begin() + ptrdiff_t(size_t(j) * size_t(size.x) + size_t(s)), e - s + 1, v);
      });
    }
  }
  /// Whether a tile of texels [i0, i1] x [j0, j1] is marked.
  bool any(int i0, int i1, int j0, int j1) const {
    for (int b = j0 >> kShift; b <= j1 >> kShift; ++b) {
      const uint8_t* row = on.data() + size_t(b) * size_t(tiles_x);
      for (int a = i0 >> kShift; a <= i1 >> kShift; ++a) {
        if (row[a]) return true;
      }
    }
    return false;
  }
};

/// Draws a soup of triangles into a CPU shadow map: each texel keeps the
/// highest surface at its centre along the direction's lines of fall (the
/// depth test of the GL pass), and in `drawn` (unless empty) the index of
/// the triangle it came from (`numbered`: the soup's t / 3; else
/// kNoTriangle), a likely occluder for the exact casts. A centre is drawn
/// when it is inside or on
/// the triangle's edges; the height is the triangle's plane in the sheared
/// space, as GL interpolates depth. Triangles seen edge-on draw nothing, nor
/// do those whose box meets no tile of `read` (given): no receiver reads
/// their texels; and rows drawn as runs leave out the texels of tiles not
/// in `read`. Draws the soup's triangles [first, first + count). Returns
/// how many `read` left out.
size_t draw_cpu_shadow_map(const std::vector<glm::vec3>& corners, const ShadowFrame& f,
                           std::vector<float>& height, std::vector<uint32_t>& drawn, bool numbered,
                           const TexelMask* read = nullptr, size_t first = 0,
                           size_t count = std::numeric_limits<size_t>::max()) {
  size_t skipped = 0;
  const size_t end = 3 * std::min(corners.size() / 3, first + std::min(count, corners.size()));
  for (size_t t = 3 * first; t < end; t += 3) {
    glm::dvec2 q[3];
    double h[3];
    for (int e = 0; e < 3; ++e) {
      q[e] = f.texel_of(corners[t + size_t(e)]);
      h[e] = corners[t + size_t(e)].y;
    }
    const glm::dvec2 e1 = q[1] - q[0], e2 = q[2] - q[0];
    const double area = e1.x * e2.y - e1.y * e2.x;
    if (!(std::abs(area) > 0.0)) continue;  // edge-on, or not finite
    const glm::dvec2 lo = glm::min(q[0], glm::min(q[1], q[2]));
    const glm::dvec2 hi = glm::max(q[0], glm::max(q[1], q[2]));
    // Clamped before the conversion: triangles far outside the map.
    const int i0 = ceil_in(lo.x - 0.5, 0, f.size.x);
    const int j0 = ceil_in(lo.y - 0.5, 0, f.size.y);
    const int i1 = floor_in(hi.x - 0.5, -1, f.size.x - 1);
    const int j1 = floor_in(hi.y - 0.5, -1, f.size.y - 1);
    if (i0 > i1 || j0 > j1) continue;
    if (read && !read->any(i0, i1, j0, j1)) {
      ++skipped;
      continue;
    }
    // Height h0 + gx (x - q0.x) + gy (y - q0.y); edge functions A x + B y +
    // C, >= 0 inside whichever way the triangle winds.
    const double gx = ((h[1] - h[0]) * e2.y - (h[2] - h[0]) * e1.y) / area;
    const double gy = ((h[2] - h[0]) * e1.x - (h[1] - h[0]) * e2.x) / area;
    const double sign = area > 0.0 ? 1.0 : -1.0;
    double ea[3], eb[3], ec[3];
    for (int e = 0; e < 3; ++e) {
      const glm::dvec2& a = q[e];
      const glm::dvec2& b = q[(e + 1) % 3];
      ea[e] = -(b.y - a.y) * sign;
      eb[e] = (b.x - a.x) * sign;
      ec[e] = -(ea[e] * a.x + eb[e] * a.y);
    }
    // Rows as runs (below) where they are long enough to pay for finding
    // them, and the coefficients are finite, far from overflowing.
    bool runs = i1 - i0 >= kMinRun;
    for (int e = 0; e < 3 && runs; ++e) {
      runs = std::abs(ea[e]) < 1e300 && std::abs(eb[e]) < 1e300 && std::abs(ec[e]) < 1e300;
    }
    const uint32_t id = numbered ? uint32_t(t / 3) : kNoTriangle;
    for (int j = j0; j <= j1; ++j) {
      const double y = j + 0.5;
      const size_t at = size_t(j) * size_t(f.size.x);
      float* row = height.data() + at;
      uint32_t* row_drawn = drawn.empty() ? nullptr : drawn.data() + at;
      // The row's terms of the sums below, rounded as they were there:
      // (A x + B y) + C and (h0 + gx (x - q0.x)) + gy (y - q0.y).
      const double eby[3] = {eb[0] * y, eb[1] * y, eb[2] * y};
      const double rise_y = gy * (y - q[0].y);
      const auto draw = [&](int i, double x) {
        const float v = float(h[0] + gx * (x - q[0].x) + rise_y);
        if (row[i] < v) {  // std::max(row[i], v), the depth test
          row[i] = v;
          if (row_drawn) row_drawn[i] = id;
        }
      };
      if (!runs) {
        for (int i = i0; i <= i1; ++i) {
          const double x = i + 0.5;
          if (ea[0] * x + eby[0] + ec[0] < 0.0 || ea[1] * x + eby[1] + ec[1] < 0.0 ||
              ea[2] * x + eby[2] + ec[2] < 0.0) {
            continue;
          }
          draw(i, x);
        }
        continue;
      }
      // An edge function so rounded is monotone in x (rounding is), so the
      // centres inside make a run: found by stepping from each edge's
      // solution with the exact test, they are the centres the test above
      // keeps (a 117 x 118 map of grass-trees, 380 triangles: 25 % less time).
      const auto inside = [&](int e, int i) { return ea[e] * (i + 0.5) + eby[e] + ec[e] >= 0.0; };
      int a = i0, b = i1;
      for (int e = 0; e < 3 && a <= b; ++e) {
        if (ea[e] > 0.0) {  // inside from some x on: the first inside
          const double x = -(eby[e] + ec[e]) / ea[e] - 0.5;
          int s = ceil_in(x, a, b + 1);
          while (s > a && inside(e, s - 1)) --s;
          while (s <= b && !inside(e, s)) ++s;
          a = s;
        } else if (ea[e] < 0.0) {  // inside up to some x: the last inside
          const double x = -(eby[e] + ec[e]) / ea[e] - 0.5;
          int s = floor_in(x, a - 1, b);
          while (s < b && inside(e, s + 1)) ++s;
          while (s >= a && !inside(e, s)) --s;
          b = s;
        } else if (!inside(e, a)) {
          b = a - 1;
        }
      }
      if (read) {
        read->each_span(j, a, b, [&](int s, int e) {
          for (int i = s; i <= e; ++i) draw(i, i + 0.5);
        });
      } else {
        for (int i = a; i <= b; ++i) draw(i, i + 0.5);
      }
    }
  }
  return skipped;
}

/// Bounds [lo, hi] of texel_of(q) - 0.5 (classify_on_cpu's c, before its
/// clamping) over the points q of the box [box_lo, box_hi] in map f: each
/// bound is texel_of's sum with the box's extreme terms, and rounding keeps
/// the order of such sums, so no point of the box falls outside.
inline void box_coordinates(const ShadowFrame& f, const glm::vec3& box_lo, const glm::vec3& box_hi,
                            glm::dvec2& lo, glm::dvec2& hi) {
  const double a = f.params.x, b = f.params.y;
  const double ay_lo = std::min(a * box_lo.y, a * box_hi.y);
  const double ay_hi = std::max(a * box_lo.y, a * box_hi.y);
  const double by_lo = std::min(b * box_lo.y, b * box_hi.y);
  const double by_hi = std::max(b * box_lo.y, b * box_hi.y);
  lo = glm::dvec2((double(box_lo.x) - f.params.z - ay_hi) * f.inv_st - 0.5,
                  (double(box_lo.z) - f.params.w - by_hi) * f.inv_st - 0.5);
  hi = glm::dvec2((double(box_hi.x) - f.params.z - ay_lo) * f.inv_st - 0.5,
                  (double(box_hi.z) - f.params.w - by_lo) * f.inv_st - 0.5);
}

/// The share of the triangles a worker's first CPU shadow map must leave
/// out for the worker to go on culling (TexelMask).
constexpr double kCullShare = 0.25;

/// The first triangle (leaf order) under node n of a BVH's nodes
/// (`triangles`, the count, for n past the last node).
size_t first_triangle(const std::vector<Bvh::Node>& nodes, size_t n, size_t triangles) {
  if (n >= nodes.size()) return triangles;
  while (nodes[n].count == 0) ++n;  // an inner node's left child follows it
  return nodes[n].first;
}

/// draw_cpu_shadow_map of the BVH's triangles (numbered in leaf order), a
/// subtree at a time: one whose box's texels (padded by one) lie off the
/// map, or meet no tile of `read` (given), is left out whole, as each of
/// its triangles would be. The others are drawn in leaf order, as the soup
/// is, so ties keep the same triangle. Returns the triangles left out.
size_t draw_cpu_shadow_map(const Bvh& bvh, const ShadowFrame& f, std::vector<float>& height,
                           std::vector<uint32_t>& drawn, const TexelMask* read) {
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  size_t skipped = 0;
  for (size_t n = 0; n < nodes.size();) {
    const Bvh::Node& node = nodes[n];
    // Texel centres i + 0.5 inside the box's sheared shadow (texel_of).
    glm::dvec2 lo, hi;
    box_coordinates(f, node.min, node.max, lo, hi);
    const int i0 = ceil_in(lo.x, -2, f.size.x + 1) - 1;
    const int i1 = floor_in(hi.x, -2, f.size.x + 1) + 1;
    const int j0 = ceil_in(lo.y, -2, f.size.y + 1) - 1;
    const int j1 = floor_in(hi.y, -2, f.size.y + 1) + 1;
    const int ci0 = std::max(i0, 0), ci1 = std::min(i1, f.size.x - 1);
    const int cj0 = std::max(j0, 0), cj1 = std::min(j1, f.size.y - 1);
    const bool off = ci0 > ci1 || cj0 > cj1 || (read && !read->any(ci0, ci1, cj0, cj1));
    if (node.count > 0) {  // leaf
      if (off) {
        skipped += node.count;
      } else {
        skipped += draw_cpu_shadow_map(bvh.corners(), f, height, drawn, true, read, node.first,
                                       node.count);
      }
      ++n;
    } else if (off) {
      const size_t next = node.first;
      skipped += first_triangle(nodes, next, bvh.triangle_count()) -
                 first_triangle(nodes, n, bvh.triangle_count());
      n = next;
    } else {
      ++n;
    }
  }
  return skipped;
}

/// classify() of shaders/coverage_common.glsl on a CPU shadow map, for the
/// receiver at p with normal n and n_dot_p = n.p: which of the four texels
/// around it hold a surface above its plane, bits 0..3 for (i0, j0), (i1,
/// j0), (i0, j1), (i1, j1) (none: lit, all: blocked, else uncertain); `at`
/// is the index of texel (i0, j0). The plane test h > own + bias, own =
/// (n.p - n.x u - n.z v) / D, is made without the division: (h - bias) D
/// against n.p - n.x u - n.z v, the comparison turned over where D < 0.
inline int classify_on_cpu(const std::vector<float>& height, const ShadowFrame& f,
                           const glm::vec3& p, const glm::vec3& n, double n_dot_p, float bias,
                           size_t& at) {
  const glm::dvec2 c = f.texel_of(p) - 0.5;
  const int i0 = floor_in(c.x, 0, f.size.x - 2);
  const int j0 = floor_in(c.y, 0, f.size.y - 2);
  at = size_t(j0) * size_t(f.size.x) + size_t(i0);
  const float* row0 = height.data() + at;
  const float* row1 = row0 + f.size.x;
  const double h00 = row0[0], h10 = row0[1], h01 = row1[0], h11 = row1[1];
  const double plane_d = double(n.x) * f.params.x + double(n.y) + double(n.z) * f.params.y;
  if (std::abs(plane_d) > 1e-3) {
    const double u0 = f.params.z + (i0 + 0.5) * f.st, v0 = f.params.w + (j0 + 0.5) * f.st;
    const double g00 = n_dot_p - n.x * u0 - n.z * v0;
    const double du = -n.x * f.st, dv = -n.z * f.st;
    const double g10 = g00 + du, g01 = g00 + dv, g11 = g00 + du + dv;
    const double a00 = (h00 - bias) * plane_d, a10 = (h10 - bias) * plane_d;
    const double a01 = (h01 - bias) * plane_d, a11 = (h11 - bias) * plane_d;
    if (plane_d > 0.0) {
      return int(a00 > g00) | int(a10 > g10) << 1 | int(a01 > g01) << 2 | int(a11 > g11) << 3;
    }
    return int(a00 < g00) | int(a10 < g10) << 1 | int(a01 < g01) << 2 | int(a11 < g11) << 3;
  }
  const double y = double(p.y) + bias;
  return int(h00 > y) | int(h10 > y) << 1 | int(h01 > y) << 2 | int(h11 > y) << 3;
}

/// About how many triangles a CPU shadow map draws once those far from what
/// the receivers read are left out (TexelMask, draw_cpu_shadow_map of a
/// BVH), for choose_coverage_method: seen from straight above, those in
/// leaves whose box comes within `reach` metres (the lines of fall's
/// sideways travel over the scene's heights) of a column holding a receiver
/// that is not `culled` (lit or shaded along every direction), on a grid of
/// 16-texel tiles.
size_t triangles_near_receivers(const Bvh& bvh, const MapGrid& grid,
                                const std::vector<glm::uvec4>& recv,
                                const std::vector<uint8_t>& culled, double reach) {
  constexpr int kTile = 16;
  const int tw = (grid.width + kTile - 1) / kTile, th = (grid.height + kTile - 1) / kTile;
  // Receivers per tile, summed (sum[(b + 1) (tw + 1) + a + 1]: tiles below b, left of a).
  std::vector<uint32_t> sum(size_t(tw + 1) * size_t(th + 1), 0);
  for (size_t r = 0; r < recv.size(); ++r) {
    if (culled[r]) continue;
    const glm::ivec2 t = receiver_texel(recv[r]) / kTile;
    sum[size_t(t.y + 1) * size_t(tw + 1) + size_t(t.x + 1)] = 1;
  }
  for (int b = 1; b <= th; ++b) {
    for (int a = 1; a <= tw; ++a) {
      const size_t at = size_t(b) * size_t(tw + 1) + size_t(a);
      sum[at] += sum[at - 1] + sum[at - size_t(tw + 1)] - sum[at - size_t(tw + 1) - 1];
    }
  }
  const double tile = double(grid.texel) * kTile;
  const auto tile_of = [&](double x, double origin, int tiles) {
    return int(std::clamp(std::floor((x - origin) / tile), -1.0, double(tiles)));
  };
  const std::vector<Bvh::Node>& nodes = bvh.nodes();
  if (nodes.empty()) return 0;
  // Receivers in every tile, and the root's box on the grid: every node's
  // box, within the root's, meets some tile, so every node is near (ToyCar,
  // 109k triangles on 16 x 16 texels: a walk of every node saved).
  const Bvh::Node& root = nodes.front();
  if (sum.back() == uint32_t(tw) * uint32_t(th) && tile_of(root.min.x, grid.origin.x, tw) >= 0 &&
      tile_of(root.max.x, grid.origin.x, tw) < tw && tile_of(root.min.z, grid.origin.y, th) >= 0 &&
      tile_of(root.max.z, grid.origin.y, th) < th) {
    return bvh.triangle_count();
  }
  size_t drawn = 0;
  for (size_t n = 0; n < nodes.size();) {
    const Bvh::Node& node = nodes[n];
    const int a0 = std::max(0, tile_of(double(node.min.x) - reach, grid.origin.x, tw));
    const int a1 = std::min(tw - 1, tile_of(double(node.max.x) + reach, grid.origin.x, tw));
    const int b0 = std::max(0, tile_of(double(node.min.z) - reach, grid.origin.y, th));
    const int b1 = std::min(th - 1, tile_of(double(node.max.z) + reach, grid.origin.y, th));
    const bool near = a0 <= a1 && b0 <= b1 &&
                      sum[size_t(b1 + 1) * size_t(tw + 1) + size_t(a1 + 1)] -
                              sum[size_t(b0) * size_t(tw + 1) + size_t(a1 + 1)] -
                              sum[size_t(b1 + 1) * size_t(tw + 1) + size_t(a0)] +
                              sum[size_t(b0) * size_t(tw + 1) + size_t(a0)] >
                          0;
    if (node.count > 0 && near) drawn += node.count;
    n = node.count > 0 || near ? n + 1 : size_t(node.first);
  }
  return drawn;
}

/// A run of receivers (indices [r0, r1) of the list) on one row of one layer,
/// with the bounds of their points and normals: classify_run_on_cpu settles
/// all of a run's pairs with one direction at once where their shadow-map
/// texels all lie above or all below every receiver's plane.
struct ReceiverRun {
  uint32_t r0 = 0, r1 = 0;
  float x_lo = 0, x_hi = 0, z_lo = 0, z_hi = 0, y_lo = 0, y_hi = 0;
  float ny_lo = 0, ny_hi = 0;  // n.y
  float nxz = 0;               // |n.x| + |n.z|
  bool bounded = false;        // every bound above finite

  /// Takes in the bounds of `other`, which follows this run.
  void join(const ReceiverRun& other) {
    r1 = other.r1;
    x_lo = std::min(x_lo, other.x_lo);
    x_hi = std::max(x_hi, other.x_hi);
    z_lo = std::min(z_lo, other.z_lo);
    z_hi = std::max(z_hi, other.z_hi);
    y_lo = std::min(y_lo, other.y_lo);
    y_hi = std::max(y_hi, other.y_hi);
    ny_lo = std::min(ny_lo, other.ny_lo);
    ny_hi = std::max(ny_hi, other.ny_hi);
    nxz = std::max(nxz, other.nxz);
    bounded = bounded && other.bounded;
  }
};
/// Receivers are settled in runs of at most kRunTexels columns, and these
/// in groups of kRunsPerGroup runs, where a group is settled whole: one
/// size does not fit all (runs of 16 settled 94 % of the courtyard's pairs
/// but 33 % of grass-trees', whose rows cross trees).
constexpr int kRunTexels = 4;
constexpr size_t kRunsPerGroup = 4;

/// Bounds [lo, hi] of classify_on_cpu's texel coordinates c (before their
/// clamping) of the run's points on map f, padded for rounding; not finite
/// for a run that is not bounded.
inline void run_coordinates(const ShadowFrame& f, const ReceiverRun& run, glm::dvec2& lo,
                            glm::dvec2& hi) {
  constexpr double kPad = 1e-3;
  box_coordinates(f, glm::vec3(run.x_lo, run.y_lo, run.z_lo),
                  glm::vec3(run.x_hi, run.y_hi, run.z_hi), lo, hi);
  lo -= kPad;
  hi += kPad;
}

/// Marks in `read` the texels that classify_on_cpu reads for the run's
/// receivers on map f (all of them for a run that is not bounded).
inline void mark_run_texels(const ShadowFrame& f, const ReceiverRun& run, TexelMask& read) {
  glm::dvec2 lo, hi;
  run_coordinates(f, run, lo, hi);
  if (!run.bounded || !std::isfinite(lo.x) || !std::isfinite(lo.y) || !std::isfinite(hi.x) ||
      !std::isfinite(hi.y)) {
    read.mark(0, f.size.x - 1, 0, f.size.y - 1);
    return;
  }
  read.mark(floor_in(lo.x, 0, f.size.x - 2), floor_in(hi.x, 0, f.size.x - 2) + 1,
            floor_in(lo.y, 0, f.size.y - 2), floor_in(hi.y, 0, f.size.y - 2) + 1);
}

/// What classify_on_cpu gives every receiver of a run on one map: all 0,
/// all 15, or not known without classifying each.
enum class RunVerdict { Lit, Blocked, Mixed };

/// classify_on_cpu for all of a run's receivers at once, where the texels
/// they read bound it. A receiver p with normal n reads the four texels
/// around its point's texel coordinates c (when c lies inside the map, so
/// none is clamped), each at most one texel from c along u and v. The
/// surface of a texel (i, j) is above the plane where h - bias > own, own
/// being the plane's height on the texel's line of fall: own = p.y + (n.x
/// dx + n.z dz) / D, with D = n.x a + n.y + n.z b (a, b: the shear) and
/// |dx|, |dz| <= st. So |own - p.y| <= st (|n.x| + |n.z|) / |D|, and every
/// bit is set (or none is) where the highest (lowest) texel of the run's
/// region clears the highest (lowest) own by a margin far above the
/// rounding of classify_on_cpu's sums. Runs with |D| near classify_on_cpu's
/// 1e-3 (planes along the lines of fall) are Mixed. Same bits as
/// classifying each receiver; pairs settled by runs with the defaults: the
/// courtyard 98 % (coverage 1.17 -> 0.48 s on 2 cores), Kenney tiles at
/// 0.3 m 67-89 %, where the exact casts of the uncertain pairs then take
/// most of the time.
inline RunVerdict classify_run_on_cpu(const std::vector<float>& height, const ShadowFrame& f,
                                      const ReceiverRun& run, float bias) {
  if (!run.bounded) return RunVerdict::Mixed;
  const double a = f.params.x, b = f.params.y;
  glm::dvec2 lo, hi;
  run_coordinates(f, run, lo, hi);
  if (!(lo.x >= 0.0 && lo.y >= 0.0 && hi.x <= f.size.x - 2 && hi.y <= f.size.y - 2)) {
    return RunVerdict::Mixed;  // a texel clamped at the map's edge, or not finite
  }
  const int i_lo = int(lo.x), i_hi = int(hi.x) + 1;
  const int j_lo = int(lo.y), j_hi = int(hi.y) + 1;
  if ((i_hi - i_lo + 1) * (j_hi - j_lo + 1) > 64) return RunVerdict::Mixed;
  // |D| >= |n.y| - (|n.x| + |n.z|) max(|a|, |b|), the same sign for all.
  const double tilt = double(run.nxz) * std::max(std::abs(a), std::abs(b));
  double d_min = double(run.ny_lo) - tilt;
  if (!(d_min > 2e-3)) d_min = -double(run.ny_hi) - tilt;
  if (!(d_min > 2e-3)) return RunVerdict::Mixed;
  const double reach = f.st * double(run.nxz) / d_min;
  float h_lo = std::numeric_limits<float>::infinity(), h_hi = -h_lo;
  for (int j = j_lo; j <= j_hi; ++j) {
    const float* row = height.data() + size_t(j) * size_t(f.size.x);
    for (int i = i_lo; i <= i_hi; ++i) {
      h_lo = std::min(h_lo, row[i]);
      h_hi = std::max(h_hi, row[i]);
    }
  }
  const double scale =
      1.0 + std::max({std::abs(double(run.x_lo)), std::abs(double(run.x_hi)),
                      std::abs(double(run.z_lo)), std::abs(double(run.z_hi)),
                      std::abs(double(run.y_lo)), std::abs(double(run.y_hi)), reach});
  const double margin = 1e-7 * scale;
  if (double(h_lo) - double(bias) > double(run.y_hi) + reach + margin) return RunVerdict::Blocked;
  if (double(h_hi) - double(bias) < double(run.y_lo) - reach - margin) return RunVerdict::Lit;
  return RunVerdict::Mixed;
}

// --- CoverageRenderer --------------------------------------------------------

namespace {

/// reference::sees_sky from p along up = -d (up.y > 0; t_min as there), for
/// rays cast in turn from neighbouring receivers in the same direction: the
/// scene triangle that blocked the last of them (`last`, kept up to date) is
/// tried first, unless it is `tried` already. Where Bvh::reaches finds it
/// hit, the walk would find the ray blocked too, so the answer is the
/// reference's. Measured with the earlier median-split BVH: the 1M-triangle
/// terrain at 2048, K = 64, CPU rays: the casts 1.06-1.29 -> 0.85-0.90 s on
/// 2 cores; the courtyard's CPU shadow maps: it settles 14,877 of the 17,439
/// blocked pairs their hints leave, coverage 1.76 -> 1.60 s (the 165,613
/// pairs that see the sky still walk).
bool sees_sky_after(const Bvh& bvh, const Bvh* snow_bvh, const glm::vec3& p, const glm::vec3& up,
                    float t_min, uint32_t& last, uint32_t tried = Bvh::kNone) {
  if (last != Bvh::kNone && last != tried && bvh.reaches(last, p, up, t_min, kOpenSky)) {
    return false;
  }
  const uint32_t hit = bvh.first_hit(p, up, t_min, kOpenSky);
  if (hit != Bvh::kNone) {
    last = hit;
    return false;
  }
  return !(snow_bvh && snow_bvh->occluded(p, up, t_min, kOpenSky));
}

// The GL side of a CoverageRenderer: programs, the scene's buffers, shadow
// maps and the passes' buffers. Made on the first compute that draws shadow
// maps or casts rays on the GPU: runs whose rays are cast on the CPU upload
// nothing (ToyCar: 0.04 s; a 1M-triangle terrain's shadow-pass vertices
// and indices).
struct GpuSide {
  // One buffer of triangles in BVH leaf order, ray cast by the exact pass
  // (storage buffer); the shadow passes draw `vertices` (welded, or those
  // corners) through an index buffer in the same order.
  GpuSide(const Bvh& bvh, const std::vector<glm::vec3>& vertices,
          const std::vector<uint32_t>& indices)
      : shadow({"shadow.vert", "depth_only.frag"}),
        shadow_snow({"shadow_snow.vert", "depth_only.frag"}),
        count({"coverage.comp"}),
        count_snow({"coverage_snow.comp"}),
        exact({"coverage_exact.comp"}),
        exact_snow({"coverage_exact_snow.comp"}),
        dispatch({"coverage_dispatch.comp"}),
        vao(gl::create_vertex_array()),
        empty_vao(gl::create_vertex_array()),
        triangles(bvh.triangle_count()) {
    if (triangles == 0) return;
    triangle_buffer = gl::create_buffer();
    glNamedBufferStorage(triangle_buffer.id(), GLsizeiptr(bvh.corners().size() * sizeof(glm::vec3)),
                         bvh.corners().data(), 0);
    gl::check_error("coverage scene triangles");
    nodes = bvh.nodes().size();
    node_buffer = gl::create_buffer();
    glNamedBufferStorage(node_buffer.id(), GLsizeiptr(nodes * sizeof(Bvh::Node)),
                         bvh.nodes().data(), 0);
    gl::check_error("coverage scene BVH");
    vertex_buffer = gl::create_buffer();
    glNamedBufferStorage(vertex_buffer.id(), GLsizeiptr(vertices.size() * sizeof(glm::vec3)),
                         vertices.data(), 0);
    index_buffer = gl::create_buffer();
    glNamedBufferStorage(index_buffer.id(), GLsizeiptr(indices.size() * sizeof(uint32_t)),
                         indices.data(), 0);
    gl::check_error("coverage scene vertices");
    glVertexArrayVertexBuffer(vao.id(), 0, vertex_buffer.id(), 0, sizeof(glm::vec3));
    glVertexArrayElementBuffer(vao.id(), index_buffer.id());
    glEnableVertexArrayAttrib(vao.id(), SNOW_ATTR_POSITION);
    glVertexArrayAttribFormat(vao.id(), SNOW_ATTR_POSITION, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao.id(), SNOW_ATTR_POSITION, 0);
    gl::check_error("coverage scene vertex array");
  }

  gl::Program shadow;       // scene depth into a shadow map
  gl::Program shadow_snow;  // snow heightfield depth into a shadow map
  gl::Program count;        // pass 1: certain cases counted, the others queued
  gl::Program count_snow;   // the same with a snow surface in the shadow maps
  gl::Program exact;        // pass 2: exact ray casts of the queued pairs
  gl::Program exact_snow;
  gl::Program dispatch;  // queue length -> indirect dispatch size
  gl::VertexArray vao;
  gl::VertexArray empty_vao;
  gl::Buffer triangle_buffer;  // float[9] per triangle, BVH leaf order (exact pass)
  gl::Buffer node_buffer;      // Bvh::Node per node
  gl::Buffer vertex_buffer;    // the shadow passes' vertices
  gl::Buffer index_buffer;     // 3 per triangle, BVH leaf order
  size_t triangles = 0;
  size_t nodes = 0;

  // Shadow maps: one DEPTH32F array layer per direction of a batch.
  gl::Texture shadow_depth;
  glm::ivec2 shadow_size{0};
  int shadow_layers = 0;
  std::vector<gl::Framebuffer> fbos;
  gl::Texture snow_surface;  // RG32F array (top, depth)
  glm::ivec3 snow_size{0};
  gl::Buffer receivers, counts, queue, dispatch_args;

  void draw_scene() const {
    if (triangles == 0) return;
    glBindVertexArray(vao.id());
    glDrawElements(GL_TRIANGLES, GLsizei(triangles * 3), GL_UNSIGNED_INT, nullptr);
  }

  void ensure_shadow_maps(glm::ivec2 size, int layers) {
    if (shadow_depth && size == shadow_size && layers == shadow_layers) return;
    fbos.clear();
    shadow_depth.reset();
    shadow_depth = gl::create_texture_2d_array(GL_DEPTH_COMPONENT32F, size.x, size.y, layers,
                                               "coverage shadow maps");
    glTextureParameteri(shadow_depth.id(), GL_TEXTURE_COMPARE_MODE, GL_NONE);
    shadow_size = size;
    shadow_layers = layers;
    for (int k = 0; k < layers; ++k) {
      gl::Framebuffer fbo = gl::create_framebuffer();
      glNamedFramebufferTextureLayer(fbo.id(), GL_DEPTH_ATTACHMENT, shadow_depth.id(), 0, k);
      glNamedFramebufferDrawBuffer(fbo.id(), GL_NONE);
      glNamedFramebufferReadBuffer(fbo.id(), GL_NONE);
      gl::check_framebuffer(fbo, "coverage shadow framebuffer");
      fbos.push_back(std::move(fbo));
    }
  }

  static void upload(gl::Buffer& buffer, const void* data, size_t bytes, const char* what) {
    if (!buffer) buffer = gl::create_buffer();
    glNamedBufferData(buffer.id(), GLsizeiptr(std::max<size_t>(bytes, 4)), data, GL_DYNAMIC_DRAW);
    gl::check_error(what);
  }
};

// The BVH for a scene of `triangles` whose coverage is computed on `maps`
// (plan::coverage_bvh_morton: its walks scale with the receivers, its build
// with the triangles).
Bvh::Build bvh_build_for(size_t triangles, const SnowMaps* maps) {
  if (!maps) return Bvh::Build::Sah;
  const size_t receivers = size_t(std::count_if(maps->ground.begin(), maps->ground.end(),
                                                [](float y) { return !std::isnan(y); }));
  return coverage_bvh_build(triangles, receivers);
}

}  // namespace

Bvh::Build coverage_bvh_build(size_t triangles, size_t receivers) {
  return plan::coverage_bvh_morton(triangles, receivers) ? Bvh::Build::Morton : Bvh::Build::Sah;
}

CoverageBvh build_coverage_bvh(const Scene& scene, Bvh::Build build) {
  if (scene.triangle_count() * 3 > size_t(0x7fffffff)) {
    throw InputError("scene has " + std::to_string(scene.triangle_count()) +
                     " triangles, more than one draw call can take");
  }
  const double t0 = now_seconds();
  CoverageBvh out;
  out.build = build;
  out.bvh = Bvh(scene.positions, build);
  out.seconds = now_seconds() - t0;
  return out;
}

struct CoverageRenderer::Impl {
  Impl(const Scene& scene, CoverageBvh built)
      : bounds(scene.bounds), build(built.build), bvh(std::move(built.bvh)) {
    triangles = bvh.triangle_count();
    log_debug("coverage: BVH of " + std::to_string(triangles) + " triangles in " +
              seconds(built.seconds));
  }

  // The GL side, made on first use. The shadow passes draw the triangles in
  // leaf order through an index buffer, their corners welded first where
  // the plan says so (plan::weld_shadow_vertices).
  GpuSide& gpu() {
    if (!gpu_side) {
      std::vector<glm::vec3> welded;
      std::vector<uint32_t> indices;
      const bool weld = plan::weld_shadow_vertices(gl_now);
      if (weld) {
        weld_vertices(bvh.corners(), welded, indices);
      } else {
        indices.resize(bvh.corners().size());
        std::iota(indices.begin(), indices.end(), 0u);
      }
      gpu_side = std::make_unique<GpuSide>(bvh, weld ? welded : bvh.corners(), indices);
    }
    return *gpu_side;
  }

  Bounds bounds;
  Bvh::Build build = Bvh::Build::Sah;
  Bvh bvh;  // the scene's triangles in leaf order, for the exact pass, CPU rays and sky culling
  size_t triangles = 0;
  std::unique_ptr<GpuSide> gpu_side;
  Timings timings;
  glm::ivec2 shadow_size{0};  // of the last compute's shadow maps (0 without)
  std::optional<plan::GlFacts> gl;  // as given by set_gl; else plan::current_gl() per compute
  plan::GlFacts gl_now;              // the facts of the compute running
  bool profiling = false;
  bool run_bounds = true;  // CPU shadow maps: runs of receivers settled at once, and only
                           // the triangles they read drawn

  // CoverageMethod::CpuRays: the reference's casts (reference::compute_coverage)
  // for the receivers left, on all cores; with a snow surface its triangles
  // get a BVH of their own. Progress is reported between kRounds rounds
  // (Progress is not thread-safe), in directions as by the other methods.
  void cast_on_cpu(const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
                   const std::vector<float>* snow_depth, const std::vector<glm::uvec4>& recv,
                   const std::vector<uint32_t>& recv_index, std::vector<float>& coverage,
                   Progress& progress) const {
    std::unique_ptr<Bvh> snow_bvh;
    if (snow_depth) {
      snow_bvh = std::make_unique<Bvh>(reference::snow_surface_triangles(maps, *snow_depth));
    }
    // Each chunk's receivers (neighbours along a row) are cast in turn:
    // reference::open_directions with the last occluder of each direction
    // tried first (sees_sky_after). A chunk holds at most kChunk receivers,
    // and there are at least 4 chunks per core where there are enough
    // receivers; a round takes at least 4 chunks per core. (With 256
    // receivers a chunk and a chunk a round, up to 4096 receivers were cast
    // on one core: ToyCar's 93, 4.2-4.3 -> 2.6-3.5 ms.)
    constexpr size_t kChunk = 256, kRounds = 16;
    const size_t threads = default_threads();
    const size_t chunk = std::clamp(recv.size() / (4 * threads), size_t(8), kChunk);
    const auto cast_chunk = [&](size_t c) {
      std::vector<uint32_t> last(dirs.size(), Bvh::kNone);
      for (size_t r = c * chunk; r < std::min(recv.size(), (c + 1) * chunk); ++r) {
        const glm::vec3 p = receiver_point(maps.grid, recv[r]);
        int lit = 0;
        for (size_t k = 0; k < dirs.size(); ++k) {
          const glm::vec3 up = -dirs[k];
          if (!(up.y > 0.0f)) continue;  // as sees_sky
          const float t_min = reference::own_surface(p.y) / up.y;
          lit += sees_sky_after(bvh, snow_bvh.get(), p, up, t_min, last[k]);
        }
        coverage[recv_index[r]] = float(lit) / float(dirs.size());
      }
    };
    const size_t chunks = (recv.size() + chunk - 1) / chunk;
    const size_t per_round = std::max((chunks + kRounds - 1) / kRounds, 4 * threads);
    for (size_t first = 0; first < chunks; first += per_round) {
      parallel_for(std::min(per_round, chunks - first), [&](size_t c) { cast_chunk(first + c); });
      progress.update(double(dirs.size()) * double(first + per_round) / double(chunks));
    }
  }

  // CoverageMethod::CpuShadowMaps: the shadow-map method on all cores. Each
  // worker draws a direction's map (the scene, and the snow surface's
  // triangles), classifies every receiver on it (classify_on_cpu, runs of
  // receivers at once where classify_run_on_cpu can: timings.settled) and
  // casts the uncertain pairs exactly (reference::sees_sky, as CPU rays).
  // Returns the uncertain pairs.
  uint64_t shadow_maps_on_cpu(const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
                              const std::vector<ShadowFrame>& frames, float bias,
                              const std::vector<float>* snow_depth,
                              const std::vector<glm::uvec4>& recv,
                              const std::vector<uint32_t>& recv_index, std::vector<float>& coverage,
                              Progress& progress) {
    std::vector<glm::vec3> snow_triangles;
    std::unique_ptr<Bvh> snow_bvh;
    if (snow_depth) {
      snow_triangles = reference::snow_surface_triangles(maps, *snow_depth);
      snow_bvh = std::make_unique<Bvh>(snow_triangles);
    }
    struct Point {
      glm::vec3 p, n;
      double n_dot_p;
    };
    std::vector<Point> points(recv.size());
    for (size_t r = 0; r < recv.size(); ++r) {
      const glm::vec3 p = receiver_point(maps.grid, recv[r]);
      const glm::vec3 n(glm::unpackHalf2x16(recv[r].z), glm::unpackHalf2x16(recv[r].w).x);
      points[r] = {p, n, double(n.x) * p.x + double(n.y) * p.y + double(n.z) * p.z};
    }
    // Runs of receivers for classify_run_on_cpu (with run_bounds on), and
    // groups of them.
    std::vector<ReceiverRun> runs, groups;
    std::vector<uint32_t> group_runs;  // first run of each group, then runs.size()
    const size_t texels = maps.grid.texels();
    const auto same_row = [&](size_t r, size_t first, int span) {
      const glm::ivec2 t = receiver_texel(recv[r]), t0 = receiver_texel(recv[first]);
      return recv_index[r] / texels == recv_index[first] / texels && t.y == t0.y &&
             t.x - t0.x < span;
    };
    for (size_t r = 0; r < recv.size(); ++r) {
      const Point& q = points[r];
      ReceiverRun run;
      run.r0 = uint32_t(r);
      run.r1 = uint32_t(r + 1);
      run.x_lo = run.x_hi = q.p.x;
      run.z_lo = run.z_hi = q.p.z;
      run.y_lo = run.y_hi = q.p.y;
      run.ny_lo = run.ny_hi = q.n.y;
      run.nxz = std::abs(q.n.x) + std::abs(q.n.z);
      run.bounded = std::isfinite(q.p.x) && std::isfinite(q.p.y) && std::isfinite(q.p.z) &&
                    std::isfinite(q.n.y) && std::isfinite(run.nxz);
      if (!runs.empty() && same_row(r, runs.back().r0, kRunTexels)) {
        runs.back().join(run);
      } else {
        runs.push_back(run);
      }
    }
    for (size_t u = 0; u < runs.size(); ++u) {
      if (!groups.empty() && u - group_runs.back() < kRunsPerGroup &&
          same_row(runs[u].r0, groups.back().r0, int(kRunsPerGroup) * kRunTexels)) {
        groups.back().join(runs[u]);
      } else {
        groups.push_back(runs[u]);
        group_runs.push_back(uint32_t(u));
      }
    }
    group_runs.push_back(uint32_t(runs.size()));
    // A map and a count per receiver for each worker (at most 4096
    // directions: 16 bits each); and the triangle drawn into each texel
    // where that memory is left.
    const glm::ivec2 size = frames.front().size;
    const double map_bytes = 4.0 * double(size.x) * double(size.y);
    const size_t workers =
        size_t(std::clamp(plan::kCpuShadowBytes / map_bytes, 1.0,
                          double(std::min<size_t>(default_threads(), dirs.size()))));
    const bool hints = 2.0 * map_bytes * double(workers) <= plan::kCpuShadowBytes;
    std::vector<std::vector<float>> height(workers);
    std::vector<std::vector<uint32_t>> drawn(workers);  // triangle per texel
    std::vector<std::vector<uint16_t>> lit(workers);
    std::vector<uint64_t> uncertain(workers, 0), settled(workers, 0), left_out(workers, 0);
    // With runs of receivers, each map marks the tiles that its groups of
    // receivers read (TexelMask), and clears and draws only those.
    // Where the triangles outnumber the groups, it also draws only the
    // triangles whose box meets a marked tile, found through the BVH (the
    // 100k-triangle terrain at 2048: 126k receivers left, in 9k groups; 95 %
    // of the triangles left out, coverage 0.81 -> 0.58 s). Where a worker's
    // first map leaves out less than kCullShare that way, the walk costs
    // more than it saves (SheenChair at 0.3 m: 40k triangles, receivers all
    // over the chair), and it draws every triangle.
    const bool masks = run_bounds;
    const bool culls = masks && bvh.triangle_count() + snow_triangles.size() / 3 >= groups.size();
    std::vector<TexelMask> mask(masks ? workers : 0);
    std::vector<uint8_t> cull_on(workers, 1);
    try {
      for (size_t w = 0; w < workers; ++w) {
        height[w].resize(size_t(size.x) * size_t(size.y));
        if (hints) drawn[w].resize(height[w].size());
        lit[w].assign(recv.size(), 0);
      }
    } catch (const std::bad_alloc&) {
      throw InputError("coverage: out of memory for shadow maps of " + std::to_string(size.x) +
                       " x " + std::to_string(size.y) + " texels; use a coarser texel size");
    }
    const size_t per_round = 4 * workers;  // progress between rounds (Progress is not thread-safe)
    for (size_t k0 = 0; k0 < dirs.size(); k0 += per_round) {
      const size_t k1 = std::min(dirs.size(), k0 + per_round);
      parallel_for(
          workers,
          [&](size_t w) {
            for (size_t k = k0 + w; k < k1; k += workers) {
              TexelMask* read = nullptr;
              if (masks) {
                read = &mask[w];
                read->reset(size);
                for (const ReceiverRun& group : groups) mark_run_texels(frames[k], group, *read);
                read->fill(height[w], size, kNoShadow);
              } else {
                std::fill(height[w].begin(), height[w].end(), kNoShadow);
              }
              // Each worker culls its first map; it goes on culling only
              // where that left out a good share of the triangles.
              const bool cull = culls && cull_on[w];
              const size_t out =
                  (cull ? draw_cpu_shadow_map(bvh, frames[k], height[w], drawn[w], read)
                        : draw_cpu_shadow_map(bvh.corners(), frames[k], height[w], drawn[w], true,
                                              read)) +
                  draw_cpu_shadow_map(snow_triangles, frames[k], height[w], drawn[w], false, read);
              left_out[w] += out;
              if (cull && k < workers) {
                cull_on[w] = double(out) >= kCullShare * double(bvh.triangle_count());
              }
              const glm::vec3 up = -dirs[k];  // the casts' ray, as reference::sees_sky's
              const size_t sx = size_t(size.x);
              uint32_t last = Bvh::kNone;
              // Receivers [r0, r1), each on its own.
              const auto classify_each = [&](size_t r0, size_t r1) {
                for (size_t r = r0; r < r1; ++r) {
                  const glm::vec3& p = points[r].p;
                  size_t at = 0;
                  const int above = classify_on_cpu(height[w], frames[k], p, points[r].n,
                                                    points[r].n_dot_p, bias, at);
                  if (above == 0 || above == 15) {
                    lit[w][r] += above == 0;
                    continue;
                  }
                  ++uncertain[w];
                  // Most uncertain pairs are blocked (60-80 %), often by a
                  // triangle drawn into a texel above the receiver: one that
                  // the walk would reach and find hit (Bvh::reaches) settles
                  // the pair as the whole walk would.
                  const float t_min = reference::own_surface(p.y) / up.y;  // as sees_sky
                  const size_t texel[4] = {at, at + 1, at + sx, at + sx + 1};
                  uint32_t tried = kNoTriangle;
                  bool blocked = !(up.y > 0.0f);  // (fall directions point down)
                  for (int e = 0; e < 4 && hints && !blocked; ++e) {
                    const uint32_t id = drawn[w][texel[e]];
                    if (!(above >> e & 1) || id == kNoTriangle || id == tried) continue;
                    tried = id;
                    blocked = bvh.reaches(id, p, up, t_min, kOpenSky);
                  }
                  // Then the triangle that blocked the last pair cast, then the walk.
                  lit[w][r] +=
                      !blocked && sees_sky_after(bvh, snow_bvh.get(), p, up, t_min, last, tried);
                }
              };
              // Whether the run's receivers were settled together.
              const auto settle = [&](const ReceiverRun& run) {
                const RunVerdict verdict = classify_run_on_cpu(height[w], frames[k], run, bias);
                if (verdict == RunVerdict::Mixed) return false;
                if (verdict == RunVerdict::Lit) {
                  for (size_t r = run.r0; r < run.r1; ++r) ++lit[w][r];
                }
                settled[w] += run.r1 - run.r0;
                return true;
              };
              for (size_t g = 0; g < groups.size(); ++g) {
                if (run_bounds && settle(groups[g])) continue;
                for (size_t u = group_runs[g]; u < group_runs[g + 1]; ++u) {
                  if (!run_bounds || !settle(runs[u])) classify_each(runs[u].r0, runs[u].r1);
                }
              }
            }
          },
          unsigned(workers));
      progress.update(double(k1));
    }
    for (size_t r = 0; r < recv.size(); ++r) {
      uint32_t sum = 0;
      for (size_t w = 0; w < workers; ++w) sum += lit[w][r];
      coverage[recv_index[r]] = float(sum) / float(dirs.size());
    }
    timings.settled = std::accumulate(settled.begin(), settled.end(), uint64_t(0));
    timings.left_out = std::accumulate(left_out.begin(), left_out.end(), uint64_t(0));
    return std::accumulate(uncertain.begin(), uncertain.end(), uint64_t(0));
  }
};

CoverageRenderer::CoverageRenderer(const Scene& scene, const SnowMaps* maps) {
  try {
    impl_ = std::make_unique<Impl>(
        scene, build_coverage_bvh(scene, bvh_build_for(scene.triangle_count(), maps)));
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory uploading " + std::to_string(scene.triangle_count()) +
                     " triangles");
  }
}

CoverageRenderer::CoverageRenderer(const Scene& scene, CoverageBvh bvh)
    : impl_(std::make_unique<Impl>(scene, std::move(bvh))) {}
CoverageRenderer::~CoverageRenderer() = default;

const CoverageRenderer::Timings& CoverageRenderer::timings() const { return impl_->timings; }
void CoverageRenderer::set_profiling(bool on) { impl_->profiling = on; }
void CoverageRenderer::set_gl(const plan::GlFacts& gl) { impl_->gl = gl; }
void CoverageRenderer::set_run_bounds(bool on) { impl_->run_bounds = on; }
glm::ivec2 CoverageRenderer::shadow_map_size() const { return impl_->shadow_size; }
Bvh::Build CoverageRenderer::bvh_build() const { return impl_->build; }

std::vector<float> CoverageRenderer::compute(const SnowMaps& maps, const CoverageSettings& settings,
                                             const std::vector<float>* snow_depth) {
  return compute(maps, fall_directions(settings), shadow_origin_jitter(settings), settings,
                 snow_depth);
}

std::vector<float> CoverageRenderer::compute(const SnowMaps& maps,
                                             const std::vector<glm::vec3>& dirs,
                                             const std::vector<glm::vec2>& jitter,
                                             const CoverageSettings& settings,
                                             const std::vector<float>* snow_depth) {
  try {
    return compute_checked(maps, dirs, jitter, settings, snow_depth);
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory for maps of " + std::to_string(maps.grid.width) +
                     " x " + std::to_string(maps.grid.height) + " texels x " +
                     std::to_string(maps.layers) + " layers; use a coarser texel size");
  }
}

std::vector<float> CoverageRenderer::compute_checked(const SnowMaps& maps,
                                                     const std::vector<glm::vec3>& dirs,
                                                     const std::vector<glm::vec2>& jitter,
                                                     const CoverageSettings& settings,
                                                     const std::vector<float>* snow_depth) {
  Impl& im = *impl_;
  im.timings = Timings{};
  im.shadow_size = glm::ivec2(0);
  const double t_start = now_seconds();
  validate(settings);
  if (dirs.empty() || jitter.size() != dirs.size()) {
    throw InputError("coverage: " + std::to_string(dirs.size()) + " directions and " +
                     std::to_string(jitter.size()) + " shadow-origin offsets");
  }
  for (const glm::vec3& d : dirs) {
    if (!(d.y < -0.2f) || !std::isfinite(d.x) || !std::isfinite(d.z)) {
      throw InputError(
          "coverage: a fall direction points less than 11.5 degrees below the horizon");
    }
  }
  const MapGrid& grid = maps.grid;
  const size_t texels = grid.texels();
  const size_t total = size_t(std::max(maps.layers, 0)) * texels;
  if (maps.ground.size() != total || maps.normal.size() != total || grid.width < 1 ||
      grid.height < 1 || !(grid.texel > 0.0f)) {
    throw InputError("coverage: the snow maps are inconsistent (arrays do not match the grid)");
  }
  if (grid.width > 65536 || grid.height > 65536) {
    throw InputError("coverage: maps wider than 65536 texels are not supported");
  }
  if (snow_depth && snow_depth->size() != total) {
    throw InputError("coverage: snow depth has " + std::to_string(snow_depth->size()) +
                     " values, the maps have " + std::to_string(total));
  }
  // From here: the stage's time includes finding and culling the receivers
  // (about 1 s of a 2048 map), not only the shadow passes.
  Progress progress("coverage", double(dirs.size()));

  std::vector<float> coverage;
  std::vector<glm::uvec4> recv;
  std::vector<uint32_t> recv_index;  // layer texel index of each receiver
  std::vector<float> top;            // ground + depth per layer texel (snow-on-snow only)
  std::vector<int> snowy_layers;
  std::vector<glm::ivec4> snowy_quads;  // per snowy layer: quads [x, z) x [y, w) to draw
  float y_lo = kOpenSky, y_hi = -kOpenSky;
  try {
    coverage.assign(total, 0.0f);
    if (total > size_t(std::numeric_limits<uint32_t>::max())) {
      throw InputError("coverage: more than 2^32 layer texels");
    }
    if (snow_depth) {
      top.assign(total, kNoSurface);
      for (size_t k = 0; k < total; ++k) {
        const float s = (*snow_depth)[k];
        if (!std::isnan(maps.ground[k])) {
          top[k] = maps.ground[k] + (std::isfinite(s) && s > 0.0f ? s : 0.0f);
        }
      }
    }
    // Every layer texel with a surface is a receiver, listed in layer, row,
    // column order: each row of each layer on all cores, at the offset that
    // the rows before it take (the serial loop took 0.1-0.3 s of the
    // 1M-triangle terrain at 2048).
    const size_t rows = size_t(maps.layers) * size_t(grid.height);
    std::vector<size_t> row_start(rows + 1, 0);
    parallel_for(rows, [&](size_t row) {
      const size_t k0 = row * size_t(grid.width);
      row_start[row + 1] = size_t(std::count_if(maps.ground.begin() + ptrdiff_t(k0),
                                                maps.ground.begin() + ptrdiff_t(k0 + grid.width),
                                                [](float g) { return !std::isnan(g); }));
    });
    std::partial_sum(row_start.begin(), row_start.end(), row_start.begin());
    recv.resize(row_start[rows]);
    recv_index.resize(row_start[rows]);
    struct RowBounds {
      float y_lo = kOpenSky, y_hi = -kOpenSky;
      glm::ivec4 snowy{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(), -1, -1};
    };
    std::vector<RowBounds> row_bounds(rows);
    parallel_for(rows, [&](size_t row) {
      const int l = int(row / size_t(grid.height));
      const int j = int(row % size_t(grid.height));
      RowBounds& b = row_bounds[row];
      size_t r = row_start[row];
      for (int i = 0; i < grid.width; ++i) {
        const size_t k = maps.index(l, i, j);
        const float g = maps.ground[k];
        if (std::isnan(g)) continue;
        float y = g;
        glm::vec3 n = maps.normal[k];
        if (snow_depth) {
          const float s = (*snow_depth)[k];
          if (std::isfinite(s) && s > 0.0f) {
            y = top[k];
            n = gradient_normal(maps, top, l, i, j);
            b.snowy = glm::ivec4(std::min(b.snowy.x, i), std::min(b.snowy.y, j),
                                 std::max(b.snowy.z, i), std::max(b.snowy.w, j));
          }
        }
        b.y_lo = std::min(b.y_lo, y);
        b.y_hi = std::max(b.y_hi, y);
        uint32_t y_word;
        std::memcpy(&y_word, &y, sizeof y);
        recv[r] = glm::uvec4(uint32_t(i) | (uint32_t(j) << 16), y_word,
                             glm::packHalf2x16(glm::vec2(n.x, n.y)),
                             glm::packHalf2x16(glm::vec2(n.z, 0.0f)));
        recv_index[r] = uint32_t(k);
        ++r;
      }
    });
    for (int l = 0; l < maps.layers; ++l) {
      // Texel bounds of the layer's snow (min i, min j, max i, max j).
      glm::ivec4 snowy(grid.width, grid.height, -1, -1);
      for (int j = 0; j < grid.height; ++j) {
        const RowBounds& b = row_bounds[size_t(l) * size_t(grid.height) + size_t(j)];
        y_lo = std::min(y_lo, b.y_lo);
        y_hi = std::max(y_hi, b.y_hi);
        snowy =
            glm::ivec4(glm::min(glm::ivec2(snowy), glm::ivec2(b.snowy)),
                       glm::max(glm::ivec2(snowy.z, snowy.w), glm::ivec2(b.snowy.z, b.snowy.w)));
      }
      const bool layer_has_snow = snowy.z >= 0;
      if (layer_has_snow && grid.width > 1 && grid.height > 1) {
        // Quads with a snowy corner: quad (i, j) has corners i..i+1, j..j+1.
        snowy_layers.push_back(l);
        snowy_quads.push_back(
            glm::ivec4(std::max(0, snowy.x - 1), std::min(grid.width - 1, snowy.z + 1),
                       std::max(0, snowy.y - 1), std::min(grid.height - 1, snowy.w + 1)));
      }
    }
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory for " + std::to_string(total) +
                     " layer texels; use a coarser texel size");
  }
  log_debug("coverage: " + std::to_string(recv.size()) + " receivers listed in " +
            seconds(now_seconds() - t_start));
  if (recv.empty()) return coverage;
  if (recv.size() > size_t(std::numeric_limits<int32_t>::max())) {
    throw InputError("coverage: " + std::to_string(recv.size()) +
                     " surface texels, more than 2^31; use a coarser texel size");
  }

  // Depth range: the scene and every receiver (snow tops may rise above the scene).
  const float scene_lo = im.bounds.empty() ? y_lo : std::min(im.bounds.min.y, y_lo);
  const float scene_hi = im.bounds.empty() ? y_hi : std::max(im.bounds.max.y, y_hi);
  const double pad = 1e-3 * std::max(1.0, double(scene_hi) - scene_lo) + 1e-3;
  const float y_top = float(scene_hi + pad);
  const float y_range = float(double(scene_hi) - scene_lo + 2 * pad);
  const float bias =
      settings.bias >= 0.0f ? settings.bias : float(0.25 * grid.texel + 1e-5 * y_range);

  CoverageWork work;  // for choose_coverage_method: drawn per shadow map, the scene and
                      // two triangles per snowy quad
  work.triangles = double(im.triangles);
  for (const glm::ivec4& q : snowy_quads) work.triangles += 2.0 * (q.y - q.x) * (q.w - q.z);
  work.snow = !snowy_layers.empty();
  im.gl_now = im.gl ? *im.gl : plan::current_gl();
  work.software = im.gl_now.software;
  work.gl_cold = !im.gl_now.software && !im.gl_now.started;
  CoverageMethod method = CoverageMethod::ShadowMaps;

  // Receivers open to the sky along every direction are lit without GPU work.
  glm::ivec4 texel_box(0, 0, grid.width - 1, grid.height - 1);  // the others' (i, j) bounds
  double tan_max = 0;                                           // of the fall directions
  {
    for (const glm::vec3& d : dirs) {
      tan_max = std::max(tan_max, double(std::hypot(d.x, d.z)) / double(-d.y));
    }
    const float cot_max = tan_max > 0 ? float(1.0 / tan_max) : 1e30f;
    std::unique_ptr<SnowBound> snow_bound;
    if (snow_depth) snow_bound = std::make_unique<SnowBound>(maps, top);
    // Receivers come in layer, row, column order. Per band of kTile rows
    // of a layer (a run of receivers), they are walked in tiles of kTile x
    // kTile texels: the tile's rectangle and lowest receiver list the BVH
    // leaves that can shade any of them, and each receiver tests only those
    // (1M-triangle terrain at 2048, 3.9M receivers: 2.2 -> 0.75 s; tiles of
    // 2 and 8 texels: 0.9 and 1.0 s).
    constexpr int kTile = 4;
    const auto band_of = [&](size_t r) {
      return std::make_pair(recv_index[r] / texels, (recv[r].x >> 16) / uint32_t(kTile));
    };
    std::vector<size_t> bands;  // first receiver of each band, then recv.size()
    for (size_t r = 0; r < recv.size(); ++r) {
      if (r == 0 || band_of(r) != band_of(r - 1)) bands.push_back(r);
    }
    bands.push_back(recv.size());
    // Surfaces less than reference::own_surface(y) above a receiver are its
    // own, as for the reference's rays, so rays give the reference's result
    // (the tiles' lists take its lowest value, at y = 0: a superset). Culling
    // with the shadow maps' bias (a quarter texel) instead kept fewer
    // receivers only where a surface lies that close above one: 125462
    // against 125791 of 3.9M on the 1M-triangle terrain at 2048.
    // Per receiver: 0, kOpen (lit along every direction) or kShaded (shaded
    // along every direction).
    constexpr uint8_t kOpen = 1, kShaded = 2;
    std::vector<uint8_t> culled(recv.size(), 0);
    // A receiver with a surface of the maps straight above it, higher than
    // its own (by twice own_surface, for the peel's rounding), is shaded
    // along the vertical line of fall, which every cone holds: the test
    // below would keep it. Most receivers under a layer are (the inside of
    // solids, floors under roofs), so they skip the test, and their tiles'
    // candidate leaves are the other receivers'. (One open after all would
    // still be counted lit along every direction.) Culling, the same
    // receivers kept: SheenChair at --depth 0.01 386 -> 135 ms, the
    // courtyard 131 -> 74 ms, grass-trees 6.0 -> 3.6 ms. These are tested
    // instead for a triangle above that shades them along every direction
    // (shades_cone): the bottoms of solids, such as the courtyard's ground
    // slab's underside (1.37M -> 0.27M receivers left for the shadow maps,
    // coverage 0.65 -> 0.40 s).
    const auto covered = [&](size_t r) {
      const size_t k = recv_index[r];
      if (k < texels) return false;  // layer 0
      const float above = maps.ground[k - texels];
      const float y = receiver_height(recv[r]);
      return !std::isnan(above) && above > y + 2.0f * reference::own_surface(y);
    };
    // Each triangle is tested by the receivers around it: its plane's terms
    // are worked out once, unless the triangles far outnumber the receivers
    // (a small, dense model tests few of its triangles).
    std::vector<TrianglePlane> planes;
    if (im.triangles <= 4 * recv.size()) {
      planes.resize(im.triangles);
      constexpr size_t kChunk = 4096;
      parallel_for_ranges(im.triangles, kChunk, [&](size_t begin, size_t end) {
        for (size_t t = begin; t < end; ++t) planes[t] = triangle_plane(&im.bvh.corners()[3 * t]);
      });
    }
    parallel_for(bands.size() - 1, [&](size_t b) {
      const size_t r0 = bands[b], r1 = bands[b + 1];
      const auto tile_of = [&](size_t r) { return (recv[r].x & 0xffffu) / uint32_t(kTile); };
      std::vector<uint32_t> order;
      order.reserve(r1 - r0);
      uint32_t shade = Bvh::kNone;
      for (size_t r = r0; r < r1; ++r) {
        if (!covered(r)) {
          order.push_back(uint32_t(r));
          continue;
        }
        // The last receiver's triangle, else the first the vertical line
        // up meets (tested again only if it is another).
        const glm::vec3 p = receiver_point(grid, recv[r]);
        bool shaded = shades_cone(im.bvh, shade, p, tan_max);
        if (!shaded) {
          const uint32_t hit = im.bvh.first_hit(p, glm::vec3(0.0f, 1.0f, 0.0f),
                                                reference::own_surface(p.y), kOpenSky);
          shaded = hit != shade && shades_cone(im.bvh, hit, p, tan_max);
          shade = hit;
        }
        if (shaded) culled[r] = kShaded;
      }
      std::stable_sort(order.begin(), order.end(),
                       [&](uint32_t a, uint32_t c) { return tile_of(a) < tile_of(c); });
      std::vector<uint32_t> leaves;
      for (size_t a = 0; a < order.size();) {
        size_t e = a;
        glm::vec2 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
        float y_min = kOpenSky;
        for (; e < order.size() && tile_of(order[e]) == tile_of(order[a]); ++e) {
          const glm::vec3 p = receiver_point(grid, recv[order[e]]);
          lo = glm::min(lo, glm::vec2(p.x, p.z));
          hi = glm::max(hi, glm::vec2(p.x, p.z));
          y_min = std::min(y_min, p.y);
        }
        leaves.clear();
        candidate_leaves(im.bvh, lo, hi, Cone(lo, y_min, reference::own_surface(0.0f), cot_max),
                         leaves);
        for (; a < e; ++a) {
          const glm::vec3 p = receiver_point(grid, recv[order[a]]);
          const Cone cone(glm::vec2(p.x, p.z), p.y, reference::own_surface(p.y), cot_max);
          culled[order[a]] =
              leaves_open(im.bvh, planes, leaves, cone) && (!snow_bound || snow_bound->open(cone))
                  ? kOpen
                  : 0;
        }
      }
    });
    // The receivers left: their count, heights and texel box (about a
    // shadow map's), from which the method is chosen.
    y_lo = kOpenSky;
    y_hi = -kOpenSky;
    texel_box = glm::ivec4(grid.width, grid.height, -1, -1);
    for (size_t r = 0; r < recv.size(); ++r) {
      if (culled[r]) continue;
      ++work.receivers;
      const float y = receiver_height(recv[r]);
      y_lo = std::min(y_lo, y);
      y_hi = std::max(y_hi, y);
      const glm::ivec2 t = receiver_texel(recv[r]);
      texel_box = glm::ivec4(glm::min(glm::ivec2(texel_box), t),
                             glm::max(glm::ivec2(texel_box.z, texel_box.w), t));
    }
    work.shadow_texels = double(std::max(texel_box.z - texel_box.x + 1, 0)) *
                         double(std::max(texel_box.w - texel_box.y + 1, 0));
    if ((work.software || work.gl_cold) && !work.snow && work.receivers > 0) {
      const double reach = tan_max * std::max(0.0, double(scene_hi) - double(y_lo));
      work.drawn = double(triangles_near_receivers(im.bvh, grid, recv, culled, reach));
    }
    method = choose_coverage_method(settings, work);
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
    im.timings.culled = culled.size() - kept;
    im.timings.shaded = size_t(std::count(culled.begin(), culled.end(), kShaded));
  }
  im.timings.method = method;
  if (recv.empty()) return coverage;
  if (method == CoverageMethod::CpuRays) {
    log_debug("coverage: " + std::to_string(recv.size()) +
              " receivers neither open to the sky nor under a solid, every line cast on the CPU");
    im.cast_on_cpu(maps, dirs, snow_depth, recv, recv_index, coverage, progress);
    im.timings.shadow = now_seconds() - t_start;
    im.timings.pairs = uint64_t(recv.size()) * uint64_t(dirs.size());
    progress.finish();
    return coverage;
  }
  const bool on_cpu = method == CoverageMethod::CpuShadowMaps;

  // Shadow-map regions: each direction's map covers the remaining
  // receivers' box projected along it, origin jittered by a sub-texel offset.
  GLint max_texture = 0;
  if (!on_cpu) {
    gl::require_context();
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_texture);
  }
  const int limit = std::min(kMaxShadowSide, max_texture > 0 ? int(max_texture) : kMaxShadowSide);
  const double gx0 = grid.origin.x + double(texel_box.x) * grid.texel;
  const double gz0 = grid.origin.y + double(texel_box.y) * grid.texel;
  const double gx1 = grid.origin.x + double(texel_box.z + 1) * grid.texel;
  const double gz1 = grid.origin.y + double(texel_box.w + 1) * grid.texel;
  const size_t k_count = dirs.size();
  std::vector<glm::dvec2> shear(k_count);
  double span_u = 0, span_v = 0;
  for (size_t k = 0; k < k_count; ++k) {
    shear[k] = glm::dvec2(double(dirs[k].x) / dirs[k].y, double(dirs[k].z) / dirs[k].y);
    span_u = std::max(span_u, gx1 - gx0 + std::abs(shear[k].x) * (double(y_hi) - y_lo));
    span_v = std::max(span_v, gz1 - gz0 + std::abs(shear[k].y) * (double(y_hi) - y_lo));
  }
  double st = grid.texel;
  const double longest = std::max(span_u, span_v);
  if (longest / st + 2 > limit) st = longest / (limit - 2);
  const glm::ivec2 size(int(std::ceil(span_u / st)) + 2, int(std::ceil(span_v / st)) + 2);
  std::vector<glm::vec4> dir_params(k_count);
  std::vector<ShadowFrame> frames(k_count);
  for (size_t k = 0; k < k_count; ++k) {
    const double a = shear[k].x, b = shear[k].y;
    const double u_min = gx0 - std::max(a * y_lo, a * y_hi);
    const double v_min = gz0 - std::max(b * y_lo, b * y_hi);
    dir_params[k] = glm::vec4(float(a), float(b), float(u_min - jitter[k].x * st),
                              float(v_min - jitter[k].y * st));
    frames[k] = ShadowFrame{glm::dvec4(dir_params[k]), st, size};
  }
  if (method != CoverageMethod::GpuRays) im.shadow_size = size;
  const bool rays = method == CoverageMethod::GpuRays;
  log_debug("coverage: " + std::to_string(recv.size()) +
            " receivers neither open to the sky nor under a solid, " +
            std::to_string(size_t(work.triangles)) + " triangles per shadow map" +
            (on_cpu && work.drawn >= 0.0
                 ? " (about " + std::to_string(size_t(work.drawn)) + " near the receivers)"
                 : std::string()) +
            ": " +
            (rays ? "every line cast by the GPU"
                  : "shadow maps of " + std::to_string(size.x) + " x " + std::to_string(size.y) +
                        " texels" + (on_cpu ? " drawn on the CPU" : "")));
  if (on_cpu) {
    im.timings.queued = im.shadow_maps_on_cpu(maps, dirs, frames, bias, snow_depth, recv,
                                              recv_index, coverage, progress);
    im.timings.shadow = now_seconds() - t_start;
    im.timings.pairs = uint64_t(recv.size()) * uint64_t(k_count);
    char line[200];
    std::snprintf(
        line, sizeof line,
        "coverage: %.0f %% of the pairs settled by runs of receivers, %.0f %% cast "
        "exactly; %.0f %% of the triangles left out of the maps",
        100.0 * double(im.timings.settled) / double(im.timings.pairs),
        100.0 * double(im.timings.queued) / double(im.timings.pairs),
        100.0 * double(im.timings.left_out) / std::max(1.0, work.triangles * double(k_count)));
    log_debug(line);
    progress.finish();
    return coverage;
  }
  GpuSide& gpu = im.gpu();
  const int batch = rays ? std::min(kMaxBatch, settings.directions)
                         : shadow_batch(settings, double(size.x) * double(size.y));

  GlStateGuard state;
  if (!rays) gpu.ensure_shadow_maps(size, batch);
  GpuSide::upload(gpu.receivers, recv.data(), recv.size() * sizeof(glm::uvec4),
                  "coverage receivers");
  GpuSide::upload(gpu.counts, nullptr, recv.size() * sizeof(uint32_t), "coverage counts");
  const GLuint zero = 0;
  glClearNamedBufferData(gpu.counts.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
  // Queue of receivers with uncertain directions: a 16-byte header (the
  // count), then up to one (receiver, direction mask) entry per receiver.
  GpuSide::upload(gpu.queue, nullptr, 16 + recv.size() * sizeof(glm::uvec2), "coverage queue");
  const GLuint dispatch_init[4] = {1, 1, 1, 0};
  GpuSide::upload(gpu.dispatch_args, dispatch_init, sizeof dispatch_init, "coverage dispatch");
  if (!snowy_layers.empty()) {
    std::vector<glm::vec2> surface(total);
    for (size_t k = 0; k < total; ++k) {
      const float s = (*snow_depth)[k];
      surface[k] = std::isnan(top[k]) ? glm::vec2(kNoSnowSurface, 0.0f)
                                      : glm::vec2(top[k], std::isfinite(s) && s > 0.0f ? s : 0.0f);
    }
    const glm::ivec3 snow_size(grid.width, grid.height, maps.layers);
    if (!gpu.snow_surface || gpu.snow_size != snow_size) {
      gpu.snow_surface.reset();
      gpu.snow_surface = gl::create_texture_2d_array(GL_RG32F, grid.width, grid.height, maps.layers,
                                                     "coverage snow surface");
      gpu.snow_size = snow_size;
    }
    glTextureSubImage3D(gpu.snow_surface.id(), 0, 0, 0, 0, grid.width, grid.height, maps.layers,
                        GL_RG, GL_FLOAT, surface.data());
    gl::check_error("coverage snow surface upload");
  }

  const glm::vec2 map_extent(float(size.x * st), float(size.y * st));
  for (gl::Program* p : {&gpu.shadow, &gpu.shadow_snow}) {
    p->set("map_extent", map_extent);
    p->set("y_top", y_top);
    p->set("y_range", y_range);
  }
  gpu.shadow_snow.set("grid_origin", grid.origin);
  gpu.shadow_snow.set("texel", grid.texel);
  gpu.shadow_snow.set("cut", kSnowSurfaceCutTexels * grid.texel);
  const bool snow = !snowy_layers.empty();
  gl::Program& count = snow ? gpu.count_snow : gpu.count;
  gl::Program& exact = snow ? gpu.exact_snow : gpu.exact;
  for (gl::Program* p : {&count, &exact}) {
    p->set("grid_origin", grid.origin);
    p->set("texel", grid.texel);
    p->set("shadow_texel", float(st));
    p->set("shadow_size", size);
    p->set("shadow_scale", glm::vec2(float(1.0 / (st * size.x)), float(1.0 / (st * size.y))));
    p->set("bias", bias);
    p->set("y_top", y_top);
    p->set("y_range", y_range);
  }
  count.set("receiver_count", int(recv.size()));
  exact.set("node_count", int(gpu.nodes));
  if (snow) {
    exact.set("grid_size", glm::ivec2(grid.width, grid.height));
    exact.set("cut", kSnowSurfaceCutTexels * grid.texel);
    std::vector<GLint> layers(snowy_layers.begin(), snowy_layers.end());
    std::vector<GLfloat> tops(layers.size(), -kOpenSky);
    for (size_t m = 0; m < layers.size(); ++m) {
      for (size_t t = 0; t < texels; ++t) {
        const float h = top[size_t(layers[m]) * texels + t];
        if (!std::isnan(h)) tops[m] = std::max(tops[m], h);
      }
    }
    exact.set("snow_layer_count", int(layers.size()));
    glProgramUniform1iv(exact.id(), glGetUniformLocation(exact.id(), "snow_layers"),
                        GLsizei(layers.size()), layers.data());
    glProgramUniform1fv(exact.id(), glGetUniformLocation(exact.id(), "snow_top"),
                        GLsizei(tops.size()), tops.data());
  }

  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  glViewport(0, 0, size.x, size.y);
  if (im.profiling) glFinish();
  double t_mark = now_seconds();
  im.timings.setup = t_mark - t_start;

  const int max_groups = 65535;
  uint32_t queued_mask = 0;  // rays: the direction mask of the queue uploaded last
  for (size_t b0 = 0; b0 < k_count; b0 += size_t(batch)) {
    const int n = int(std::min(size_t(batch), k_count - b0));
    for (int k = 0; k < n && !rays; ++k) {
      glBindFramebuffer(GL_FRAMEBUFFER, gpu.fbos[size_t(k)].id());
      const GLfloat clear_depth = 1.0f;
      glClearBufferfv(GL_DEPTH, 0, &clear_depth);
      gpu.shadow.set("shear_origin", dir_params[b0 + size_t(k)]);
      gpu.shadow.use();
      gpu.draw_scene();
      if (!snowy_layers.empty()) {
        gpu.shadow_snow.set("shear_origin", dir_params[b0 + size_t(k)]);
        gpu.shadow_snow.use();
        glBindTextureUnit(SNOW_SHADOW_SNOW_TEXTURE, gpu.snow_surface.id());
        glBindVertexArray(gpu.empty_vao.id());
        for (size_t m = 0; m < snowy_layers.size(); ++m) {
          const glm::ivec4& q = snowy_quads[m];
          gpu.shadow_snow.set("layer", snowy_layers[m]);
          gpu.shadow_snow.set("quad_origin", glm::ivec2(q.x, q.z));
          gpu.shadow_snow.set("quad_columns", q.y - q.x);
          glDrawArrays(GL_TRIANGLES, 0, 6 * (q.y - q.x) * (q.w - q.z));
        }
      }
    }
    gl::check_error("coverage shadow pass");
    if (im.profiling) {
      glFinish();
      const double t = now_seconds();
      im.timings.shadow += t - t_mark;
      t_mark = t;
    }
    if (!rays) glBindTextureUnit(SNOW_COVERAGE_SHADOW_TEXTURE, gpu.shadow_depth.id());
    if (snow) glBindTextureUnit(SNOW_COVERAGE_SNOW_TEXTURE, gpu.snow_surface.id());
    if (im.triangles > 0) {
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_BVH_NODES, gpu.node_buffer.id());
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_BVH_TRIANGLES,
                       gpu.triangle_buffer.id());
    }
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_RECEIVERS, gpu.receivers.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_COUNTS, gpu.counts.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_QUEUE, gpu.queue.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_DISPATCH, gpu.dispatch_args.id());
    if (rays) {
      // Every receiver queued with every direction of the batch.
      const uint32_t mask = n == 32 ? ~0u : (1u << n) - 1u;
      if (mask != queued_mask) {
        std::vector<glm::uvec2> queue(2 + recv.size(), glm::uvec2(0u));  // 16-byte header
        queue[0].x = uint32_t(recv.size());
        for (size_t r = 0; r < recv.size(); ++r) queue[2 + r] = glm::uvec2(uint32_t(r), mask);
        glNamedBufferSubData(gpu.queue.id(), 0, GLsizeiptr(queue.size() * sizeof(glm::uvec2)),
                             queue.data());
        queued_mask = mask;
      }
    } else {
      glClearNamedBufferSubData(gpu.queue.id(), GL_R32UI, 0, 4, GL_RED_INTEGER, GL_UNSIGNED_INT,
                                &zero);
      // Pass 1: certain cases counted, uncertain ones queued.
      count.use();
      set_batch_directions(count, &dir_params[b0], n);
      for (size_t first = 0; first < recv.size(); first += size_t(max_groups) * kLocalSize) {
        const size_t left = recv.size() - first;
        const GLuint groups =
            GLuint(std::min<size_t>(max_groups, (left + kLocalSize - 1) / kLocalSize));
        count.set("first_receiver", int(first));
        glDispatchCompute(groups, 1, 1);
      }
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      gpu.dispatch.use();
      glDispatchCompute(1, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
    }
    // Pass 2: exact tests of the queue, sized on the GPU (no readback).
    exact.use();
    set_batch_directions(exact, &dir_params[b0], n);
    if (rays) {
      glDispatchCompute(
          GLuint(std::min<size_t>(max_groups, (recv.size() + kLocalSize - 1) / kLocalSize)), 1, 1);
    } else {
      glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, gpu.dispatch_args.id());
      glDispatchComputeIndirect(0);
      glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    gl::check_error("coverage counting pass");
    im.timings.pairs += uint64_t(recv.size()) * uint64_t(n);
    if (im.profiling) {
      GLuint queued = 0;
      glGetNamedBufferSubData(gpu.queue.id(), 0, sizeof queued, &queued);
      im.timings.queued += queued;
      const double t = now_seconds();
      im.timings.composite += t - t_mark;
      t_mark = t;
    }
    progress.update(double(b0 + size_t(n)));
  }
  if (!im.profiling) {
    glFinish();
    const double t = now_seconds();
    im.timings.shadow = t - t_mark;  // shadow and counting together when not profiling
    t_mark = t;
  }

  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<uint32_t> counts(recv.size());
  glGetNamedBufferSubData(gpu.counts.id(), 0, GLsizeiptr(counts.size() * sizeof(uint32_t)),
                          counts.data());
  gl::check_error("coverage readback");
  glBindTextureUnit(SNOW_COVERAGE_SHADOW_TEXTURE, 0);
  glBindTextureUnit(SNOW_COVERAGE_SNOW_TEXTURE, 0);
  glBindTextureUnit(SNOW_SHADOW_SNOW_TEXTURE, 0);
  for (size_t r = 0; r < counts.size(); ++r) {
    coverage[recv_index[r]] =
        float(std::min<uint32_t>(counts[r], uint32_t(k_count))) / float(k_count);
  }
  progress.finish();
  im.timings.readback = now_seconds() - t_mark;
  return coverage;
}

std::vector<float> compute_coverage(const Scene& scene, const SnowMaps& maps,
                                    const CoverageSettings& settings,
                                    const std::vector<float>* snow_depth) {
  CoverageRenderer renderer(scene);
  return renderer.compute(maps, settings, snow_depth);
}

}  // namespace snow
