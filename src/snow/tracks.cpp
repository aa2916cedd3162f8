// Tracks in the snow (snow/tracks.h).
#include "snow/tracks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <queue>
#include <unordered_map>

#include "core/error.h"
#include "core/log.h"
#include "snow/column.h"
#include "snow/weather.h"

namespace snow {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
/// A floor less than this below the snow's top presses nothing, m.
constexpr float kTrackTolerance = 1e-4f;

/// The texels a contact's underside covers at one pose: per column of
/// `rect` (texels [i0, i1) x [j0, j1)) the lowest height of the shape
/// there (world y), +inf where it covers none.
struct Underside {
  int i0 = 0, j0 = 0, i1 = 0, j1 = 0;
  std::vector<float> y;
  float& at(int i, int j) { return y[size_t(j - j0) * size_t(i1 - i0) + size_t(i - i0)]; }
};

/// The texel range a world box in x, z covers, clamped to the grid.
void cover(const MapGrid& g, glm::vec2 lo, glm::vec2 hi, int& i0, int& j0, int& i1, int& j1) {
  const auto cell = [&](float v, float o) { return (v - o) / g.texel - 0.5f; };
  i0 = std::max(0, int(std::ceil(cell(lo.x, g.origin.x))));
  j0 = std::max(0, int(std::ceil(cell(lo.y, g.origin.y))));
  i1 = std::min(g.width, int(std::floor(cell(hi.x, g.origin.x))) + 1);
  j1 = std::min(g.height, int(std::floor(cell(hi.y, g.origin.y))) + 1);
}

void raster_triangle(const MapGrid& g, glm::vec3 a, glm::vec3 b, glm::vec3 c, Underside& u) {
  const glm::vec2 pa(a.x, a.z), pb(b.x, b.z), pc(c.x, c.z);
  const float area = (pb.x - pa.x) * (pc.y - pa.y) - (pc.x - pa.x) * (pb.y - pa.y);
  if (!(std::abs(area) > 1e-12f)) return;  // seen edge on from above
  int i0, j0, i1, j1;
  cover(g, glm::min(pa, glm::min(pb, pc)), glm::max(pa, glm::max(pb, pc)), i0, j0, i1, j1);
  i0 = std::max(i0, u.i0), j0 = std::max(j0, u.j0);
  i1 = std::min(i1, u.i1), j1 = std::min(j1, u.j1);
  for (int j = j0; j < j1; ++j) {
    for (int i = i0; i < i1; ++i) {
      const glm::vec2 p = g.center(i, j);
      const float wa = ((pb.x - p.x) * (pc.y - p.y) - (pc.x - p.x) * (pb.y - p.y)) / area;
      const float wb = ((pc.x - p.x) * (pa.y - p.y) - (pa.x - p.x) * (pc.y - p.y)) / area;
      const float wc = 1.0f - wa - wb;
      if (wa < -1e-6f || wb < -1e-6f || wc < -1e-6f) continue;
      float& y = u.at(i, j);
      y = std::min(y, wa * a.y + wb * b.y + wc * c.y);
    }
  }
}

void raster_segment(const MapGrid& g, glm::vec3 a, glm::vec3 b, float half, Underside& u) {
  const glm::vec2 pa(a.x, a.z), pb(b.x, b.z), ab = pb - pa;
  const float length2 = glm::dot(ab, ab);
  int i0, j0, i1, j1;
  cover(g, glm::min(pa, pb) - half, glm::max(pa, pb) + half, i0, j0, i1, j1);
  i0 = std::max(i0, u.i0), j0 = std::max(j0, u.j0);
  i1 = std::min(i1, u.i1), j1 = std::min(j1, u.j1);
  for (int j = j0; j < j1; ++j) {
    for (int i = i0; i < i1; ++i) {
      const glm::vec2 p = g.center(i, j);
      const float t =
          length2 > 0.0f ? std::clamp(glm::dot(p - pa, ab) / length2, 0.0f, 1.0f) : 0.0f;
      if (glm::distance(p, pa + t * ab) > half) continue;
      float& y = u.at(i, j);
      y = std::min(y, a.y + t * (b.y - a.y));
    }
  }
}

Underside underside(const MapGrid& g, const TrackSource& s, const glm::mat4& pose) {
  const auto place = [&](glm::vec3 p) { return glm::vec3(pose * glm::vec4(p, 1.0f)); };
  std::vector<glm::vec3> tri(s.triangles.size()), seg(s.segments.size());
  std::transform(s.triangles.begin(), s.triangles.end(), tri.begin(), place);
  std::transform(s.segments.begin(), s.segments.end(), seg.begin(), place);
  const float half = 0.5f * s.width;
  glm::vec2 lo(kInf), hi(-kInf);
  for (const glm::vec3& p : tri)
    lo = glm::min(lo, glm::vec2(p.x, p.z)), hi = glm::max(hi, {p.x, p.z});
  for (const glm::vec3& p : seg) {
    lo = glm::min(lo, glm::vec2(p.x, p.z) - half), hi = glm::max(hi, glm::vec2(p.x, p.z) + half);
  }
  Underside u;
  if (!(lo.x <= hi.x && lo.y <= hi.y)) return u;
  cover(g, lo, hi, u.i0, u.j0, u.i1, u.j1);
  if (u.i1 <= u.i0 || u.j1 <= u.j0) return u;
  u.y.assign(size_t(u.i1 - u.i0) * size_t(u.j1 - u.j0), kInf);
  for (size_t t = 0; t + 2 < tri.size(); t += 3)
    raster_triangle(g, tri[t], tri[t + 1], tri[t + 2], u);
  for (size_t t = 0; t + 1 < seg.size(); t += 2) raster_segment(g, seg[t], seg[t + 1], half, u);
  return u;
}

/// What the tracks work on: the maps, the pack, which objects are sources.
struct Field {
  const SnowMaps& maps;
  SnowPack& pack;
  std::vector<uint8_t> skip;  // per object: a source's own surfaces

  bool skipped(size_t k) const {
    const int32_t o = maps.object[k];
    return o >= 0 && size_t(o) < skip.size() && skip[size_t(o)];
  }
  /// Snow water per metre of depth (m/m), kSettledSnowDensity's where none lies.
  float water_per_depth(size_t k) const {
    return pack.depth[k] > 0.0f ? pack.swe[k] / pack.depth[k] : kSettledSnowDensity / kWaterDensity;
  }
  /// The layer a contact whose underside is at `c` presses in column (i, j).
  int pressed_layer(int i, int j, float c) const {
    for (int l = 0; l < maps.layers; ++l) {
      const size_t k = maps.index(l, i, j);
      if (std::isnan(maps.ground[k])) break;
      if (!skipped(k) && maps.ground[k] <= c + kContactReach) return l;
    }
    return -1;
  }
  /// The layer of column (i, j) on the same surface as ground height `from`
  /// `step` texels away (snow/column.h's continuity), -1 where none.
  int same_surface(float from, int i, int j, float step) const {
    int best = -1;
    float nearest = kSurfaceContinuityTexels * maps.grid.texel * step;
    for (int l = 0; l < maps.layers; ++l) {
      const size_t k = maps.index(l, i, j);
      if (std::isnan(maps.ground[k])) break;
      if (skipped(k) || gap_is_solid(maps, l, i, j)) continue;
      const float rise = std::abs(maps.ground[k] - from);
      if (rise <= nearest) best = l, nearest = rise;
    }
    return best;
  }
};

/// The lowest floor of every pose of `s` per layer texel it presses (the
/// order of the poses does not change a minimum; lower() sorts the texels).
using Floors = std::unordered_map<size_t, float>;

void press_pose(const Field& f, const TrackSource& s, const glm::mat4& pose,
                const TrackSettings& settings, Floors& floors) {
  Underside u = underside(f.maps.grid, s, pose);
  struct Hit {
    size_t k;
    float c;
  };
  std::vector<Hit> hits;
  float lift = -kInf;  // raises (or lowers) the contact onto the floor it makes
  for (int j = u.j0; j < u.j1; ++j) {
    for (int i = u.i0; i < u.i1; ++i) {
      const float c = u.at(i, j);
      if (c == kInf) continue;
      const int l = f.pressed_layer(i, j, c);
      if (l < 0) continue;
      const size_t k = f.maps.index(l, i, j);
      const float d = f.pack.depth[k];
      const float keep = s.mode == TrackMode::Clear
                             ? 0.0f
                             : pressed_depth(d, f.water_per_depth(k) * kWaterDensity,
                                             settings.pressure_kpa, settings.displaced_share);
      lift = std::max(lift, f.maps.ground[k] + keep - c);
      hits.push_back({k, c});
    }
  }
  for (const Hit& h : hits) {
    const float floor = h.c + lift;
    if (!(floor < f.maps.ground[h.k] + f.pack.depth[h.k] - kTrackTolerance)) continue;
    const auto [it, added] = floors.emplace(h.k, floor);
    if (!added) it->second = std::min(it->second, floor);
  }
}

/// Snow sent out of a pressed or cleared texel.
struct Sent {
  double swe = 0.0;    // m of water over one texel
  double depth = 0.0;  // m of snow over one texel, at the density it had
};

/// Lowers the texels of `floors` to their floors; returns what each sends.
std::map<size_t, Sent> lower(Field& f, const Floors& floors, TrackMode mode,
                             const TrackSettings& settings) {
  std::map<size_t, Sent> sent;
  std::vector<std::pair<size_t, float>> sorted(floors.begin(), floors.end());
  std::sort(sorted.begin(), sorted.end());
  for (const auto& [k, floor] : sorted) {
    const float d = f.pack.depth[k];
    const float kept = std::clamp(floor - f.maps.ground[k], 0.0f, d);
    const double per = double(f.water_per_depth(k));
    const bool all = mode == TrackMode::Clear ? kept <= 0.0f : kept <= 0.0f || d <= 0.0f;
    const double share = mode == TrackMode::Clear ? 1.0 : double(settings.displaced_share);
    Sent out;
    if (all) {
      out.swe = double(f.pack.swe[k]);
      out.depth = double(d);
    } else {
      out.depth = share * double(d - kept);
      out.swe = std::min(out.depth * per, double(f.pack.swe[k]));
    }
    f.pack.swe[k] = float(double(f.pack.swe[k]) - out.swe);
    f.pack.depth[k] = all ? 0.0f : kept;
    sent[k] = out;
  }
  return sent;
}

/// A layer texel's column and layer.
struct Place {
  int l, i, j;
};
Place place_of(const SnowMaps& m, size_t k) {
  const size_t texels = m.grid.texels();
  const size_t rest = k % texels;
  return {int(k / texels), int(rest % size_t(m.grid.width)), int(rest / size_t(m.grid.width))};
}

/// Calls visit(k2, step) for the layer texels on the same surface as `k`
/// in its 8 neighbour columns (step: 1 or sqrt 2 texels).
template <class Visit>
void neighbours(const Field& f, size_t k, Visit&& visit) {
  const Place p = place_of(f.maps, k);
  for (int dj = -1; dj <= 1; ++dj) {
    for (int di = -1; di <= 1; ++di) {
      const int i = p.i + di, j = p.j + dj;
      if ((di == 0 && dj == 0) || i < 0 || j < 0 || i >= f.maps.grid.width ||
          j >= f.maps.grid.height) {
        continue;
      }
      const float step = di != 0 && dj != 0 ? float(M_SQRT2) : 1.0f;
      const int l = f.same_surface(f.maps.ground[k], i, j, step);
      if (l >= 0) visit(f.maps.index(l, i, j), step);
    }
  }
}

/// How a search reached a layer texel.
struct Reach {
  float distance = kInf;  // texels, straight, to the owner
  size_t owner = 0;       // the seed it was reached from
};
using Reached = std::unordered_map<size_t, Reach>;

/// A search over layer texels from `seeds`, in order of the straight
/// distance (texels) to the seed each is reached from (the owner): each
/// texel gets its nearest seed along paths on the same surface, as a
/// vector-propagating distance transform does. may(k, owner, distance)
/// says whether texel k may be reached so.
template <class May>
Reached search(const Field& f, const std::vector<std::pair<size_t, Reach>>& seeds, May&& may) {
  using Entry = std::pair<float, size_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  Reached reached;
  for (const auto& [k, r] : seeds) {
    Reach& to = reached[k];
    if (r.distance < to.distance) to = r, queue.push({r.distance, k});
  }
  while (!queue.empty()) {
    const auto [d, k] = queue.top();
    queue.pop();
    if (d > reached[k].distance) continue;
    const size_t owner = reached[k].owner;
    const Place from = place_of(f.maps, owner);
    neighbours(f, k, [&](size_t k2, float) {
      const Place at = place_of(f.maps, k2);
      const float d2 = std::hypot(float(at.i - from.i), float(at.j - from.j));
      if (!may(k2, owner, d2)) return;
      Reach& to = reached[k2];
      if (d2 < to.distance) to = {d2, owner}, queue.push({d2, k2});
    });
  }
  return reached;
}

/// The pile an edge texel spreads: its volume and profile.
struct Pile {
  double swe = 0.0, depth = 0.0;  // over one texel, as sent
  float width = 0.0f;             // m: a berm's width, or a pile's half base
  float peak = 0.0f;              // m
  size_t group = 0;               // its edge's piles (lay)
};

float profile(TrackMode mode, float from_edge, float width) {
  if (mode == TrackMode::Press) return std::max(0.0f, 1.0f - from_edge / width);
  return std::max(0.0f, 1.0f - std::abs(from_edge - width) / width);
}

/// Texels around an edge texel over which its pile's cross-section is
/// averaged (which edge texel is nearest to the snow inside a track, and so
/// takes it, alternates along a diagonal edge or a round end).
constexpr int kEdgeAverageTexels = 4;

/// Per pile, the cross-section (m^2 per metre of edge) its volume makes,
/// averaged over the piles of its layer within kEdgeAverageTexels.
std::map<size_t, float> edge_areas(const SnowMaps& maps, const std::map<size_t, Pile>& piles) {
  std::map<size_t, float> areas;
  const int r = kEdgeAverageTexels;
  for (const auto& entry : piles) {
    const Place at = place_of(maps, entry.first);
    double sum = 0.0;
    int n = 0;
    for (int j = std::max(at.j - r, 0); j <= std::min(at.j + r, maps.grid.height - 1); ++j) {
      for (int i = std::max(at.i - r, 0); i <= std::min(at.i + r, maps.grid.width - 1); ++i) {
        const auto it = piles.find(maps.index(at.l, i, j));
        if (it != piles.end()) sum += it->second.depth, ++n;
      }
    }
    areas[entry.first] = float(sum / double(n)) * maps.grid.texel;
  }
  return areas;
}

/// The piles' edge texels joined where they touch (8 neighbours): the piles
/// along one edge of a track. Sets each pile's group; returns their count.
size_t group_piles(const Field& f, std::map<size_t, Pile>& piles) {
  std::map<size_t, size_t> parent;
  for (const auto& entry : piles) parent[entry.first] = entry.first;
  const auto root = [&](size_t k) {
    while (parent[k] != k) k = parent[k] = parent[parent[k]];
    return k;
  };
  for (const auto& entry : piles) {
    neighbours(f, entry.first, [&](size_t n, float) {
      if (piles.count(n)) parent[root(n)] = root(entry.first);
    });
  }
  std::map<size_t, size_t> index;
  for (auto& [e, p] : piles) p.group = index.emplace(root(e), index.size()).first->second;
  return index.size();
}

/// A group that would lay its snow more than kMaxCrowding times as high as
/// its profile (a pocket between a track and a wall that the snow of a
/// track's end runs into) gives it to the nearest group with room, whose
/// piles grow by it; where none has room, it stays.
constexpr double kMaxCrowding = 2.0;

void merge_crowded(const SnowMaps& maps, std::map<size_t, Pile>& piles, std::vector<Sent>& held,
                   const std::vector<Sent>& shape) {
  const auto crowded = [&](size_t g) {
    return !(shape[g].depth > 0.0) || held[g].depth > kMaxCrowding * shape[g].depth;
  };
  std::vector<size_t> into(held.size());
  for (size_t g = 0; g < held.size(); ++g) into[g] = g;
  for (const auto& [e, p] : piles) {
    if (!crowded(p.group) || into[p.group] != p.group) continue;
    const Place at = place_of(maps, e);
    double nearest = INFINITY;
    for (const auto& [e2, p2] : piles) {
      if (crowded(p2.group)) continue;
      const Place to = place_of(maps, e2);
      const double d = std::hypot(double(to.i - at.i), double(to.j - at.j));
      if (d < nearest) nearest = d, into[p.group] = p2.group;
    }
  }
  for (size_t g = 0; g < held.size(); ++g) {
    if (into[g] == g) continue;
    held[into[g]].depth += held[g].depth, held[into[g]].swe += held[g].swe;
    held[g] = Sent();
  }
  for (auto& entry : piles) entry.second.group = into[entry.second.group];
}

/// Passes of a 3 x 3 mean over the laid heights (among the texels that lay
/// snow, on their layer): the profiles of neighbouring edge texels meet
/// without steps where a track bends or ends.
constexpr int kSmoothPasses = 2;

void smooth(const SnowMaps& maps, std::map<size_t, double>& height) {
  for (int pass = 0; pass < kSmoothPasses; ++pass) {
    std::map<size_t, double> out;
    for (const auto& [k, h] : height) {
      const Place at = place_of(maps, k);
      double sum = 0.0;
      int n = 0;
      for (int j = std::max(at.j - 1, 0); j <= std::min(at.j + 1, maps.grid.height - 1); ++j) {
        for (int i = std::max(at.i - 1, 0); i <= std::min(at.i + 1, maps.grid.width - 1); ++i) {
          const auto it = height.find(maps.index(at.l, i, j));
          if (it != height.end()) sum += it->second, ++n;
        }
      }
      out[k] = sum / double(n);
    }
    height = std::move(out);
  }
}

/// Lays the piles over the texels `outside` reached from their edge texels:
/// each texel takes its edge texel's profile (a berm or a pile of that
/// edge texel's width and peak) at its straight distance from that edge
/// texel (the search's path lengths step in eighths of a turn), scaled per
/// group so that each group lays exactly the depth and the water its edge
/// texels hold (the wedges a convex corner fans out into, or a concave one
/// squeezes, would otherwise lay more or less). A texel with no room under
/// its ceiling for the peak takes none; crowded groups go to others
/// (merge_crowded); a group with no room at all is laid on its edge texels.
void lay(Field& f, std::map<size_t, Pile>& piles, const Reached& outside, TrackMode mode) {
  const float texel = f.maps.grid.texel;
  std::vector<Sent> held(group_piles(f, piles));
  for (const auto& [e, p] : piles) held[p.group].swe += p.swe, held[p.group].depth += p.depth;
  const auto per = [](const Pile& p) { return p.swe / std::max(p.depth, 1e-12); };
  std::map<size_t, double> height;
  for (const auto& [k, r] : outside) {
    const Pile& p = piles.at(r.owner);
    const float room = f.maps.ceiling[k] - f.maps.ground[k] - f.pack.depth[k];
    if (k != r.owner && room < p.peak) continue;
    const Place a = place_of(f.maps, k), b = place_of(f.maps, r.owner);
    const float from_edge = (std::hypot(float(a.i - b.i), float(a.j - b.j)) + 0.5f) * texel;
    const double h = double(p.peak) * double(profile(mode, from_edge, p.width));
    if (h > 0.0) height[k] = h;
  }
  smooth(f.maps, height);
  const auto shapes = [&] {
    std::vector<Sent> shape(held.size());
    for (const auto& [k, h] : height) {
      const Pile& p = piles.at(outside.at(k).owner);
      shape[p.group].depth += h, shape[p.group].swe += h * per(p);
    }
    return shape;
  };
  merge_crowded(f.maps, piles, held, shapes());
  const std::vector<Sent> shape = shapes();
  const auto add = [&](size_t k, double depth, double swe) {
    f.pack.depth[k] = float(double(f.pack.depth[k]) + depth);
    f.pack.swe[k] = float(double(f.pack.swe[k]) + swe);
  };
  for (const auto& [k, h] : height) {
    const Pile& p = piles.at(outside.at(k).owner);
    const Sent& want = held[p.group];
    const Sent& has = shape[p.group];
    add(k, h * want.depth / has.depth, h * per(p) * want.swe / std::max(has.swe, 1e-300));
  }
  for (const auto& [e, p] : piles) {
    if (!(shape[p.group].depth > 0.0)) add(e, p.depth, p.swe);
  }
}

/// Spreads what the texels of `sent` send beside the tracks (above); where
/// no texel outside the tracks is reachable, puts it back.
void spread(Field& f, const std::map<size_t, Sent>& sent, TrackMode mode,
            const TrackSettings& settings) {
  const float texel = f.maps.grid.texel;
  // Each sending texel's nearest texel outside the tracks.
  std::vector<std::pair<size_t, Reach>> seeds;
  for (const auto& entry : sent) {
    neighbours(f, entry.first, [&](size_t k2, float step) {
      if (!sent.count(k2)) seeds.push_back({entry.first, {step, k2}});
    });
  }
  const Reached inside =
      search(f, seeds, [&](size_t k2, size_t, float) { return sent.count(k2) > 0; });
  std::map<size_t, Pile> piles;
  for (const auto& [k, out] : sent) {
    const auto it = inside.find(k);
    if (it == inside.end()) {  // walled in: keeps its snow
      f.pack.swe[k] += float(out.swe), f.pack.depth[k] += float(out.depth);
      continue;
    }
    Pile& p = piles[it->second.owner];
    p.swe += out.swe, p.depth += out.depth;
  }
  const float slope = std::tan(glm::radians(settings.repose_deg));
  std::vector<std::pair<size_t, Reach>> edges;
  float reach = 0.0f;  // texels
  const std::map<size_t, float> areas = edge_areas(f.maps, piles);
  for (auto& [e, p] : piles) {
    const float area = areas.at(e);  // m^2 of cross-section per metre of edge
    p.width =
        std::max(std::sqrt((mode == TrackMode::Press ? 2.0f : 1.0f) * area / slope), 0.5f * texel);
    p.peak = p.width * slope;
    reach = std::max(reach, (mode == TrackMode::Press ? 1.0f : 2.0f) * p.width / texel + 1.0f);
    edges.push_back({e, {0.0f, e}});
  }
  const Reached outside = search(f, edges, [&](size_t k2, size_t owner, float d) {
    return !sent.count(k2) && d <= reach &&
           d * texel <= (mode == TrackMode::Press ? 1.0f : 2.0f) * piles[owner].width + texel;
  });
  lay(f, piles, outside, mode);
}

void check(const TrackSource& s, const TrackSettings& settings) {
  if (s.triangles.empty() && s.segments.empty()) {
    throw InputError("tracks: '" + s.name + "' has no triangles or lines to press with");
  }
  if (!s.segments.empty() && !(s.width > 0.0f && std::isfinite(s.width))) {
    throw InputError("tracks: the lines of '" + s.name + "' need a width > 0 (--track-width)");
  }
  if (!(settings.pressure_kpa > 0.0f) || !std::isfinite(settings.pressure_kpa) ||
      !(settings.displaced_share >= 0.0f && settings.displaced_share <= 1.0f) ||
      !(settings.repose_deg >= 1.0f && settings.repose_deg <= 89.0f)) {
    throw InputError("tracks: settings out of range (load > 0 kPa, share 0..1, repose 1..89)");
  }
}

/// Presses (or clears) every source of `mode` as one: the lowest floor of
/// all their poses per texel, then the snow sent aside.
void make_group(Field& f, const std::vector<TrackSource>& sources, TrackMode mode,
                const TrackSettings& settings, TrackResult& result) {
  Floors floors;
  for (const TrackSource& s : sources) {
    if (s.mode != mode) continue;
    const std::vector<glm::mat4> rest{glm::mat4(1.0f)};
    for (const glm::mat4& pose : s.poses.empty() ? rest : s.poses) {
      press_pose(f, s, pose, settings, floors);
      ++result.poses;
    }
  }
  (mode == TrackMode::Press ? result.pressed : result.cleared) += floors.size();
  spread(f, lower(f, floors, mode, settings), mode, settings);
}

}  // namespace

float compacted_density(float density, float pressure_kpa) {
  if (!(density < kMaxCompactedDensity)) return density;
  return kMaxCompactedDensity -
         (kMaxCompactedDensity - density) * std::exp(-pressure_kpa / kCompactionPressure);
}

float pressed_depth(float depth, float density, float pressure_kpa, float displaced_share) {
  const float final_density = compacted_density(density, pressure_kpa);
  if (!(depth > 0.0f) || !(final_density > density)) return std::max(depth, 0.0f);
  const float s = displaced_share;
  return depth * density * (1.0f - s) / (final_density - s * density);
}

SnowPack settled_pack(const SnowMaps& maps, const std::vector<float>& depth) {
  SnowPack pack = SnowPack::empty(maps);
  if (depth.size() != pack.depth.size())
    throw InputError("tracks: the depth does not match the maps");
  const float per = kSettledSnowDensity / kWaterDensity;
  for (size_t k = 0; k < depth.size(); ++k) {
    const float d = std::isnan(maps.ground[k]) ? 0.0f : std::max(depth[k], 0.0f);
    pack.depth[k] = d;
    pack.swe[k] = d * per;
  }
  pack.fallen = pack.lying(maps);
  return pack;
}

std::vector<glm::mat4> track_poses(const std::vector<glm::mat4>& moves, const Bounds& bounds,
                                   float spacing, size_t max_poses, const std::string& name) {
  std::vector<glm::mat4> poses;
  if (moves.empty() || bounds.empty()) return poses;
  std::vector<glm::vec4> corners;
  for (int c = 0; c < 8; ++c) {
    corners.emplace_back(c & 1 ? bounds.max.x : bounds.min.x, c & 2 ? bounds.max.y : bounds.min.y,
                         c & 4 ? bounds.max.z : bounds.min.z, 1.0f);
  }
  const auto fail = [&] {
    throw InputError("tracks: '" + name + "' moves through more than " + std::to_string(max_poses) +
                     " poses at the maps' texel (shorten its animation)");
  };
  poses.push_back(moves.front());
  for (size_t n = 1; n < moves.size(); ++n) {
    float travel = 0.0f;
    for (const glm::vec4& c : corners)
      travel = std::max(travel, glm::distance(moves[n - 1] * c, moves[n] * c));
    if (!std::isfinite(travel)) fail();
    const double cuts = std::ceil(double(travel) / double(spacing));
    if (double(poses.size()) + cuts > double(max_poses)) fail();
    for (int cut = 1; cut <= int(std::max(cuts, 1.0)); ++cut) {
      const float t = float(cut) / float(std::max(cuts, 1.0));
      poses.push_back(moves[n - 1] * (1.0f - t) + moves[n] * t);
    }
  }
  return poses;
}

TrackResult make_tracks(const SnowMaps& maps, SnowPack& pack,
                        const std::vector<TrackSource>& sources, const TrackSettings& settings,
                        std::vector<float>* compaction) {
  if (pack.depth.size() != maps.ground.size() || pack.swe.size() != maps.ground.size()) {
    throw InputError("tracks: the snowpack does not match the maps");
  }
  Field f{maps, pack, {}};
  for (const TrackSource& s : sources) {
    check(s, settings);
    if (s.object >= 0) {
      f.skip.resize(std::max(f.skip.size(), size_t(s.object) + 1), 0);
      f.skip[size_t(s.object)] = 1;
    }
  }
  const std::vector<float> before = pack.depth, swe_before = pack.swe;
  TrackResult result;
  make_group(f, sources, TrackMode::Press, settings, result);
  make_group(f, sources, TrackMode::Clear, settings, result);
  const double area = double(maps.grid.texel) * double(maps.grid.texel);
  if (compaction) compaction->assign(before.size(), 0.0f);
  for (size_t k = 0; k < before.size(); ++k) {
    result.fallen += double(swe_before[k]) * area;
    const bool lowered = pack.depth[k] < before[k];
    if (lowered) {
      result.compacted += double(pack.swe[k]) * area;
      if (compaction) (*compaction)[k] = 1.0f - pack.depth[k] / before[k];
    } else {
      result.lying += double(swe_before[k]) * area;
      result.moved += (double(pack.swe[k]) - double(swe_before[k])) * area;
    }
  }
  return result;
}

}  // namespace snow
