// The top surface of a patch: the marching-squares contour of the thickness
// field at min_thickness (Lorensen and Cline 1987, the 2D case; saddles
// resolved by the cell average) is the outline, where the snow tapers to
// zero thickness. Inside it the grid is triangulated adaptively as a
// right-triangulated irregular network (Evans, Kirkpatrick and Townsend
// 2001, error pass after mapbox/martini) within half the error budget, so
// that large flat snow fields never reach the decimator at full resolution.
// The bottom shares the outline vertices, so top and bottom close into a
// 2-manifold by construction (solid.cpp).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "core/parallel.h"
#include "mesh/polygonize/steps.h"

namespace snow::poly {
namespace {

/// One triangulate_top call.
///
/// Right-triangulated irregular network over the window padded to a
/// (2^k + 1)^2 grid (Evans, Kirkpatrick and Townsend 2001; the error pass
/// follows mapbox/martini): a triangle stays whole while top and ground
/// interpolate every sample it holds within `tolerance`. Corners of cells
/// with patch samples at some corners only get an infinite error, so those
/// cells (and their neighbours) are refined to single cells and take the
/// marching-squares outline; the shared per-vertex errors keep the
/// triangulation free of T-junctions.
class TopTriangulator {
 public:
  TopTriangulator(const PatchField& f, const MapGrid& grid, float min_thickness, double tolerance,
                  int cut)
      : f_(f),
        grid_(grid),
        min_thickness_(min_thickness),
        tolerance_(tolerance),
        cut_(cut),
        texel_(grid.texel),
        sample_vertex_(f.member.size(), -1) {
    tile_ = 1;
    while (tile_ + 1 < std::max(f.w, f.h)) tile_ *= 2;
    n_ = tile_ + 1;
    error_.assign(size_t(n_) * size_t(n_), 0.0f);
    ground_error_.assign(tolerance >= 0.0 ? error_.size() : 0, 0.0f);
  }

  TopMesh run(size_t piece_triangles) {
    compute_errors();
    cell_done_.assign(f_.member.size(), 0);
    split_above_ = tolerance_ >= 0.0 ? float(tolerance_) : -1.0f;
    triangulate(error_.data(), &top_.tris);
    top_.in_pieces = tolerance_ >= 0.0 && cut_ >= 2 && top_.tris.size() / 3 > piece_triangles;
    if (tolerance_ >= 0.0) {
      if (top_.in_pieces) force_cut(ground_error_);
      std::fill(cell_done_.begin(), cell_done_.end(), uint8_t(0));
      triangulate(ground_error_.data(), &top_.bottom);
    }
    return std::move(top_);
  }

 private:
  static constexpr float kForce = std::numeric_limits<float>::infinity();

  // Vertices, shared by the top's and the bottom's triangles.
  glm::dvec2 sample_pos(size_t a) const;
  uint32_t vertex_at_sample(size_t a);
  uint32_t vertex_on_edge(size_t in, size_t out);
  // Triangles, into *out_.
  void emit(const std::vector<uint32_t>& poly);
  void emit_oriented(uint32_t a, uint32_t b, uint32_t c);
  void march_cell(int ci, int cj);
  // The network's errors.
  bool member(int x, int y) const { return x < f_.w && y < f_.h && f_.member[f_.at(x, y)] != 0; }
  size_t at(int x, int y) const { return size_t(y) * size_t(n_) + size_t(x); }
  void force_cut(std::vector<float>& e) const;
  void compute_errors();
  void force_outline_cells();
  void own(int ax, int ay, int bx, int by, int cx, int cy, float& e, float& eg) const;
  void take(size_t k, std::initializer_list<size_t> children);
  void edge_midpoint_errors(int side, unsigned threads);
  void centre_errors(int side, unsigned threads);
  // The network's triangles.
  void triangulate(const float* split_error, std::vector<uint32_t>* out);
  void visit(int ax, int ay, int bx, int by, int cx, int cy);

  const PatchField& f_;
  const MapGrid& grid_;
  const float min_thickness_;
  const double tolerance_;
  const int cut_;
  const double texel_;

  TopMesh top_;
  std::vector<int32_t> sample_vertex_;  // top_ vertex of each window sample, -1 none yet
  std::unordered_map<uint64_t, int32_t> edge_vertex_;  // outline vertex of each cell edge
  // Where emit() puts triangles: top_.tris, then top_.bottom.
  std::vector<uint32_t>* out_ = nullptr;
  std::vector<uint32_t> poly_;  // march_cell's scratch

  int tile_ = 1;  // the padded grid has tile_ + 1 = n_ samples a side
  int n_ = 2;
  // The errors of the top and ground together (error_), and of the ground
  // alone (ground_error_), the bottom's; at the hypotenuse midpoints.
  std::vector<float> error_, ground_error_;
  std::vector<uint8_t> cell_done_;  // cells marched, by window sample of their corner
  float split_above_ = -1.0f;
  const float* split_error_ = nullptr;  // error_, then ground_error_
};

glm::dvec2 TopTriangulator::sample_pos(size_t a) const {
  const int wi = int(a % size_t(f_.w)), wj = int(a / size_t(f_.w));
  return glm::dvec2(grid_.origin.x + (double(f_.i0 + wi) + 0.5) * texel_,
                    grid_.origin.y + (double(f_.j0 + wj) + 0.5) * texel_);
}

uint32_t TopTriangulator::vertex_at_sample(size_t a) {
  if (sample_vertex_[a] < 0) {
    const glm::dvec2 p = sample_pos(a);
    sample_vertex_[a] = int32_t(top_.positions.size());
    top_.positions.emplace_back(p.x, double(f_.g[a]) + double(f_.s[a]), p.y);
    top_.sample.push_back(int32_t(a));
  }
  return uint32_t(sample_vertex_[a]);
}

/// The outline vertex on the cell edge from member sample `in` to
/// non-member `out`, where the thickness crosses min_thickness.
uint32_t TopTriangulator::vertex_on_edge(size_t in, size_t out) {
  const uint64_t key =
      (uint64_t(std::min(in, out)) << 1) | (std::max(in, out) - std::min(in, out) == 1 ? 0u : 1u);
  auto it = edge_vertex_.find(key);
  if (it != edge_vertex_.end()) return uint32_t(it->second);
  const double si = f_.s[in], so = f_.s[out];
  const double t = std::clamp((si - min_thickness_) / std::max(si - so, 1e-12), 0.01, 0.99);
  const glm::dvec2 p = glm::mix(sample_pos(in), sample_pos(out), t);
  const double y = double(f_.g[in]) + (double(f_.g[out]) - double(f_.g[in])) * t;
  const int32_t v = int32_t(top_.positions.size());
  top_.positions.emplace_back(p.x, y, p.y);
  top_.sample.push_back(-1);
  edge_vertex_.emplace(key, v);
  return uint32_t(v);
}

void TopTriangulator::emit(const std::vector<uint32_t>& poly) {
  // poly is convex and runs counter-clockwise in (x, z), i.e. clockwise
  // seen from above. Fan out from a patch sample: a diagonal between two
  // outline vertices would be shared by top and bottom, four faces at
  // one edge.
  size_t first = 0;
  while (top_.sample[poly[first]] < 0) ++first;
  const size_t n = poly.size();
  for (size_t k = 1; k + 1 < n; ++k) {
    out_->insert(out_->end(), {poly[first], poly[(first + k + 1) % n], poly[(first + k) % n]});
  }
}

void TopTriangulator::emit_oriented(uint32_t a, uint32_t b, uint32_t c) {
  if (plan_area2(top_.positions[a], top_.positions[b], top_.positions[c]) < 0.0) std::swap(b, c);
  out_->insert(out_->end(), {a, b, c});
}

/// Marching squares on one cell that has patch samples at some corners only.
void TopTriangulator::march_cell(int ci, int cj) {
  const PatchField& f = f_;
  const size_t c[4] = {f.at(ci, cj), f.at(ci + 1, cj), f.at(ci + 1, cj + 1), f.at(ci, cj + 1)};
  const bool in[4] = {f.member[c[0]] != 0, f.member[c[1]] != 0, f.member[c[2]] != 0,
                      f.member[c[3]] != 0};
  const int inside = int(in[0]) + int(in[1]) + int(in[2]) + int(in[3]);
  std::vector<uint32_t>& poly = poly_;
  poly.clear();
  for (int q = 0; q < 4; ++q) {
    const int nq = (q + 1) & 3;
    if (in[q]) poly.push_back(vertex_at_sample(c[q]));
    if (in[q] != in[nq]) {
      poly.push_back(in[q] ? vertex_on_edge(c[q], c[nq]) : vertex_on_edge(c[nq], c[q]));
    }
  }
  const bool saddle = inside == 2 && in[0] == in[2];
  const double mean = 0.25 * (double(f.s[c[0]]) + f.s[c[1]] + f.s[c[2]] + f.s[c[3]]);
  if (saddle && mean <= min_thickness_) {
    // Two separate corners: each inside sample with its two crossings.
    for (size_t k = 0; k < poly.size(); ++k) {
      if (top_.sample[poly[k]] < 0) continue;
      emit({poly[(k + poly.size() - 1) % poly.size()], poly[k], poly[(k + 1) % poly.size()]});
    }
  } else {
    emit(poly);
  }
}

/// Split every triangle whose hypotenuse midpoint lies on the grid of half
/// the cut: down to the triangles inside one cut x cut square, whose legs
/// lie on its sides, centre lines and diagonals. Those midpoints are the
/// ones of the triangles with hypotenuses `cut` samples long or longer,
/// their ancestors' included: forced after the errors are worked out, they
/// split the same triangles as forced before.
void TopTriangulator::force_cut(std::vector<float>& e) const {
  for (int y = 0; y <= tile_; y += cut_ / 2) {
    for (int x = 0; x <= tile_; x += cut_ / 2) e[size_t(y) * size_t(n_) + size_t(x)] = kForce;
  }
}

/// The corners of every cell with patch samples at some corners only.
void TopTriangulator::force_outline_cells() {
  for (int cj = 0; cj + 1 < f_.h; ++cj) {
    for (int ci = 0; ci + 1 < f_.w; ++ci) {
      const int inside = int(member(ci, cj)) + int(member(ci + 1, cj)) + int(member(ci, cj + 1)) +
                         int(member(ci + 1, cj + 1));
      if (inside == 0 || inside == 4) continue;
      for (int q = 0; q < 4; ++q) {
        const size_t k = size_t(cj + (q >> 1)) * size_t(n_) + size_t(ci + (q & 1));
        error_[k] = kForce;
        if (!ground_error_.empty()) ground_error_[k] = kForce;
      }
    }
  }
}

// A triangle's error takes in its own (how far top and ground at its
// hypotenuse midpoint lie from the hypotenuse's) and its children's, kept at
// that midpoint, which the two triangles sharing a hypotenuse share. So each
// midpoint is worked out once, level by level, finest first, from its two
// triangles: a square's centre is the midpoint of its diagonal, whose
// children's midpoints are the square's edge midpoints; an edge midpoint
// (hypotenuse of length 2h) is the midpoint of the triangles with right
// angles h to either side, whose children's midpoints are the centres of the
// four squares of side h around it. The diagonal of a square runs through
// its parent square's centre: from its own top-left corner to its
// bottom-right one where the square's column and row (in squares of its
// size) add up to an even number. These are the errors of a recursive
// descent over the triangles from the two roots, bit for bit, without a
// descent per level, and each midpoint is written by one task, rows in
// parallel.
void TopTriangulator::compute_errors() {
  force_outline_cells();
  if (tolerance_ >= 0.0 && cut_ >= 2) force_cut(error_);
  if (tolerance_ < 0.0) return;
  const unsigned threads = threads_for(error_.size());
  for (int side = 2; side <= tile_; side *= 2) {
    edge_midpoint_errors(side, threads);
    centre_errors(side, threads);
  }
}

/// The own error of triangle (a, b) with its right angle at c into e (top
/// and ground) and eg (ground). Every triangle turns the same way from a to
/// b to c, and its sums run in that order, so the two that share a
/// hypotenuse may round apart.
void TopTriangulator::own(int ax, int ay, int bx, int by, int cx, int cy, float& e,
                          float& eg) const {
  if ((bx - ax) * (cy - ay) - (by - ay) * (cx - ax) > 0) {
    std::swap(ax, bx);
    std::swap(ay, by);
  }
  const int mx = (ax + bx) >> 1, my = (ay + by) >> 1;
  if (!(member(ax, ay) && member(bx, by) && member(mx, my))) return;
  const PatchField& f = f_;
  const size_t a = f.at(ax, ay), b = f.at(bx, by), m = f.at(mx, my);
  const float dg = std::abs(0.5f * (f.g[a] + f.g[b]) - f.g[m]);
  const float dt = std::abs(0.5f * (f.g[a] + f.s[a] + f.g[b] + f.s[b]) - (f.g[m] + f.s[m]));
  e = std::max(e, std::max(dg, dt));
  eg = std::max(eg, dg);
}

/// Both errors at midpoint k take in those at its children's midpoints.
void TopTriangulator::take(size_t k, std::initializer_list<size_t> children) {
  for (size_t c : children) {
    error_[k] = std::max(error_[k], error_[c]);
    ground_error_[k] = std::max(ground_error_[k], ground_error_[c]);
  }
}

/// Edge midpoints of squares of this side (hypotenuses of length side).
void TopTriangulator::edge_midpoint_errors(int side, unsigned threads) {
  const int h = side / 2;
  const bool parent = side > 2;
  parallel_for(
      size_t(tile_ / h + 1),
      [&](size_t row) {
        const int y = int(row) * h;
        for (int x = (y % side == 0) ? h : 0; x <= tile_; x += side) {
          const size_t k = at(x, y);
          const bool horizontal = y % side == 0;
          const int dx = horizontal ? h : 0, dy = horizontal ? 0 : h;
          for (int sgn = -1; sgn <= 1; sgn += 2) {
            const int cx = x + sgn * dy, cy = y + sgn * dx;  // right angle
            if (cx < 0 || cy < 0 || cx > tile_ || cy > tile_) continue;
            own(x - dx, y - dy, x + dx, y + dy, cx, cy, error_[k], ground_error_[k]);
            if (!parent) continue;
            take(k, {at((x - dx + cx) >> 1, (y - dy + cy) >> 1),
                     at((x + dx + cx) >> 1, (y + dy + cy) >> 1)});
          }
        }
      },
      threads);
}

/// Centres of squares of this side (diagonals), whose children are the edge
/// midpoints edge_midpoint_errors(side) did.
void TopTriangulator::centre_errors(int side, unsigned threads) {
  const int h = side / 2;
  parallel_for(
      size_t(tile_ / side),
      [&](size_t qy) {
        const int y = int(qy) * side + h;
        for (int qx = 0; qx * side < tile_; ++qx) {
          const int x = qx * side + h;
          const size_t k = at(x, y);
          float &e = error_[k], &eg = ground_error_[k];
          if ((qx + int(qy)) % 2 == 0) {
            own(x - h, y - h, x + h, y + h, x + h, y - h, e, eg);
            own(x - h, y - h, x + h, y + h, x - h, y + h, e, eg);
          } else {
            own(x + h, y - h, x - h, y + h, x - h, y - h, e, eg);
            own(x + h, y - h, x - h, y + h, x + h, y + h, e, eg);
          }
          take(k, {at(x - h, y), at(x + h, y), at(x, y - h), at(x, y + h)});
        }
      },
      threads);
}

/// The network split where split_error exceeds split_above_, its triangles
/// into *out, from the two roots.
void TopTriangulator::triangulate(const float* split_error, std::vector<uint32_t>* out) {
  split_error_ = split_error;
  out_ = out;
  visit(0, 0, tile_, tile_, tile_, 0);
  visit(tile_, tile_, 0, 0, 0, tile_);
}

/// Triangle (a, b, c): hypotenuse a-b, right angle at c.
void TopTriangulator::visit(int ax, int ay, int bx, int by, int cx, int cy) {
  const int mx = (ax + bx) >> 1, my = (ay + by) >> 1;
  const bool leaf = std::abs(ax - cx) + std::abs(ay - cy) <= 1;
  if (!leaf && split_error_[size_t(my) * size_t(n_) + size_t(mx)] > split_above_) {
    visit(cx, cy, ax, ay, mx, my);
    visit(bx, by, cx, cy, mx, my);
    return;
  }
  const PatchField& f = f_;
  const bool in_a = member(ax, ay), in_b = member(bx, by), in_c = member(cx, cy);
  if (!leaf) {
    // Unsplit: wholly inside the patch or wholly outside it.
    if (in_a) {
      emit_oriented(vertex_at_sample(f.at(ax, ay)), vertex_at_sample(f.at(bx, by)),
                    vertex_at_sample(f.at(cx, cy)));
    }
    return;
  }
  const int ci = std::min({ax, bx, cx}), cj = std::min({ay, by, cy});
  if (ci + 1 >= f.w || cj + 1 >= f.h) return;  // padding
  if (in_a && in_b && in_c &&
      member(ci, cj) + member(ci + 1, cj) + member(ci, cj + 1) + member(ci + 1, cj + 1) == 4) {
    emit_oriented(vertex_at_sample(f.at(ax, ay)), vertex_at_sample(f.at(bx, by)),
                  vertex_at_sample(f.at(cx, cy)));
    return;
  }
  uint8_t& done = cell_done_[f.at(ci, cj)];
  if (done ||
      !(member(ci, cj) || member(ci + 1, cj) || member(ci, cj + 1) || member(ci + 1, cj + 1))) {
    return;
  }
  done = 1;
  march_cell(ci, cj);
}

}  // namespace

TopMesh triangulate_top(const PatchField& f, const MapGrid& grid, float min_thickness,
                        double tolerance, int cut, size_t piece_triangles) {
  return TopTriangulator(f, grid, min_thickness, tolerance, cut).run(piece_triangles);
}

void smooth_outline(TopMesh& top, int iterations, double texel) {
  if (iterations <= 0) return;
  const size_t nv = top.positions.size();
  // Only edges at an outline vertex (sample < 0) are counted: smoothing
  // moves only those, along their boundary edges (the edges without a
  // reverse twin).
  std::unordered_map<uint64_t, uint32_t> directed;  // edge (u, v) -> count
  auto key = [](uint32_t u, uint32_t v) { return (uint64_t(u) << 32) | v; };
  for (size_t t = 0; t < top.tris.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      const uint32_t u = top.tris[t + e], v = top.tris[t + (e + 1) % 3];
      if (top.sample[u] < 0 || top.sample[v] < 0) ++directed[key(u, v)];
    }
  }
  std::vector<int64_t> next(nv, -1), prev(nv, -1);
  for (const auto& [k, count] : directed) {
    const uint32_t u = uint32_t(k >> 32), v = uint32_t(k & 0xffffffffu);
    if (directed.count(key(v, u))) continue;
    next[u] = v;
    prev[v] = u;
  }
  std::vector<std::vector<uint32_t>> vertex_tris(nv);
  for (size_t t = 0; t < top.tris.size(); t += 3) {
    for (int e = 0; e < 3; ++e) {
      if (next[top.tris[t + e]] >= 0) vertex_tris[top.tris[t + e]].push_back(uint32_t(t));
    }
  }
  const double min_area2 = 1e-6 * texel * texel;
  for (int it = 0; it < iterations; ++it) {
    for (size_t v = 0; v < nv; ++v) {
      if (next[v] < 0 || prev[v] < 0 || top.sample[v] >= 0) continue;
      const glm::dvec3 old = top.positions[v];
      const glm::dvec3 mean =
          0.5 * (top.positions[size_t(next[v])] + top.positions[size_t(prev[v])]);
      top.positions[v] = old + 0.5 * (mean - old);
      for (uint32_t t : vertex_tris[v]) {
        const auto& p = top.positions;
        if (plan_area2(p[top.tris[t]], p[top.tris[t + 1]], p[top.tris[t + 2]]) < min_area2) {
          top.positions[v] = old;
          break;
        }
      }
    }
  }
}

double top_plan_area(const TopMesh& top) {
  double area2 = 0.0;
  for (size_t t = 0; t < top.tris.size(); t += 3) {
    area2 += plan_area2(top.positions[top.tris[t]], top.positions[top.tris[t + 1]],
                        top.positions[top.tris[t + 2]]);
  }
  return 0.5 * area2;
}

}  // namespace snow::poly
