// Polygonize fallen snow (DESIGN.md, "Polygonize").
//
// 1. Patches: snowy layer texels joined across layers by the stabilizer's
//    landing rule (snow::landing_layer; height spans after Onoue and
//    Nishita), so a floor running under a table is one patch.
// 2. Per patch, a thickness field s and a ground field g on texel centres;
//    the top is g + s, the outline the marching-squares contour of s at
//    min_thickness (Lorensen and Cline 1987, the 2D case; saddles resolved by
//    the cell average), where the snow tapers to zero thickness; the bottom
//    is g - bottom_offset. Top and bottom share the outline vertices, so the
//    result is a closed 2-manifold by construction.
//    Inside the outline the grid is triangulated adaptively as a right-
//    triangulated irregular network (Evans, Kirkpatrick and Townsend 2001,
//    error pass after mapbox/martini) within half the error budget, so that
//    large flat snow fields never reach the decimator at full resolution.
// 3. Edge-collapse decimation with OpenMesh's Decimater within the other
//    half, the priority and bound being the quadric error of Garland and
//    Heckbert (SIGGRAPH 1997) over unweighted planes, i.e. a sum of squared
//    distances in metres.
#include "mesh/polygonize.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <mutex>
#include <numeric>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>

// OpenMesh's properties copy default-constructed (uninitialized) vectors,
// which GCC flags inside its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
// QuadricT needs vector_traits from the mesh headers above.
#include <OpenMesh/Core/Geometry/QuadricT.hh>
#include <OpenMesh/Tools/Decimater/BaseDecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModBaseT.hh>
#include <OpenMesh/Tools/Utils/HeapT.hh>
#pragma GCC diagnostic pop

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/zeroed.h"
#include "snow/column.h"

namespace snow {
namespace {

// ---------------------------------------------------------------------------
// OpenMesh types

struct SnowMeshTraits : public OpenMesh::DefaultTraits {
  typedef OpenMesh::Vec3d Point;
  typedef OpenMesh::Vec3d Normal;
  VertexAttributes(OpenMesh::Attributes::Status);
  FaceAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::Normal);
  EdgeAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::PrevHalfedge);
};

/// OpenMesh's triangle mesh with a collapse test that allocates nothing.
/// OpenMesh 9's TriConnectivity::is_collapse_ok allocates and frees on every
/// call, a fifth of the decimation's time; the Decimater calls
/// is_collapse_ok on the mesh type it is instantiated with, so this one,
/// which hides it, is used. Same conditions (Dey et al. 1999, as OpenMesh
/// checks them).
struct OMesh : OpenMesh::TriMesh_ArrayKernelT<SnowMeshTraits> {
  bool is_collapse_ok(HalfedgeHandle v0v1) const {
    if (status(edge_handle(v0v1)).deleted()) return false;
    const HalfedgeHandle v1v0 = opposite_halfedge_handle(v0v1);
    const VertexHandle v0 = to_vertex_handle(v1v0);
    const VertexHandle v1 = to_vertex_handle(v0v1);
    if (status(v0).deleted() || status(v1).deleted()) return false;
    // The far vertex of the face on each side of the edge; that face must
    // keep an inner edge, or the collapse leaves a dangling one.
    const auto side = [&](HalfedgeHandle h, VertexHandle& apex) {
      if (is_boundary(h)) return true;
      const HalfedgeHandle h1 = next_halfedge_handle(h);
      const HalfedgeHandle h2 = next_halfedge_handle(h1);
      apex = to_vertex_handle(h1);
      return !(is_boundary(opposite_halfedge_handle(h1)) &&
               is_boundary(opposite_halfedge_handle(h2)));
    };
    VertexHandle vl, vr;
    if (!side(v0v1, vl) || !side(v1v0, vr)) return false;
    if (vl == vr) return false;  // a lone edge, or both sides the same vertex
    // Link condition: the one-rings of v0 and v1 share only vl and vr
    // (v1's marked, then v0's looked up).
    if (ring_mark_.size() != n_vertices()) ring_mark_.assign(n_vertices(), 0);
    if (++ring_stamp_ == 0) {
      std::fill(ring_mark_.begin(), ring_mark_.end(), 0u);
      ring_stamp_ = 1;
    }
    for_ring(v1, [&](VertexHandle b) {
      ring_mark_[size_t(b.idx())] = ring_stamp_;
      return false;
    });
    if (for_ring(v0, [&](VertexHandle a) {
          return a != vl && a != vr && ring_mark_[size_t(a.idx())] == ring_stamp_;
        })) {
      return false;
    }
    // An edge between two boundary vertices must be a boundary edge.
    return !(is_boundary(v0) && is_boundary(v1) && !is_boundary(v0v1) && !is_boundary(v1v0));
  }

  // The queries below are OpenMesh's, inline: OpenMesh 9 compiles valence and
  // find_halfedge into its library, where each circulator step checks its
  // handles in calls of their own (a fifth of polygonize on a small scene).

  /// fn(w) for each vertex w at the end of an outgoing halfedge of v (the
  /// vertices cvv_iter visits, in PolyConnectivity::valence's order) until
  /// fn returns true; whether one did.
  template <class Fn>
  bool for_ring(VertexHandle v, Fn fn) const {
    const HalfedgeHandle start = halfedge_handle(v);
    for (HalfedgeHandle h = start; h.is_valid();) {
      if (fn(to_vertex_handle(h))) return true;
      h = cw_rotated_halfedge_handle(h);
      if (h == start) break;
    }
    return false;
  }
  /// Outgoing halfedges of v, as PolyConnectivity::valence counts them.
  unsigned valence(VertexHandle v) const {
    unsigned count = 0;
    for_ring(v, [&](VertexHandle) {
      ++count;
      return false;
    });
    return count;
  }
  /// Whether a halfedge runs from a to b (PolyConnectivity::find_halfedge).
  bool has_halfedge(VertexHandle a, VertexHandle b) const {
    return for_ring(a, [&](VertexHandle w) { return w == b; });
  }
  /// TriMeshT::calc_face_normal(f) (the same corners into the same
  /// arithmetic, so the same bits), with vertex `moved`, if it is a corner,
  /// at `p` instead of its point.
  Normal face_normal(FaceHandle f, VertexHandle moved = VertexHandle(),
                     const Point& p = Point(0.0)) const {
    const HalfedgeHandle h0 = halfedge_handle(f);
    const HalfedgeHandle h1 = next_halfedge_handle(h0);
    const VertexHandle c[3] = {to_vertex_handle(h0), to_vertex_handle(h1),
                               to_vertex_handle(next_halfedge_handle(h1))};
    const auto at = [&](VertexHandle v) -> const Point& { return v == moved ? p : point(v); };
    return PolyMesh::calc_face_normal(at(c[0]), at(c[1]), at(c[2]));
  }

 private:
  // Scratch of is_collapse_ok: a stamp per vertex.
  mutable std::vector<uint32_t> ring_mark_;
  mutable uint32_t ring_stamp_ = 0;
};

/// Decimation priority and bound: the quadric error of Garland and Heckbert
/// over the planes of the original faces, each with weight one (OpenMesh's
/// ModQuadricT weights them by area, which makes the bound unitless). The
/// error of a collapse is the sum of squared distances (m^2) of the kept
/// vertex to every plane merged into it, so a bound err^2 keeps every vertex
/// within err metres of each original plane around it. A collapse within the
/// bound must also not turn a face's normal by more than
/// set_max_normal_deviation: the test of OpenMesh's ModNormalFlippingT, here
/// rather than a module of its own, so that it runs only after the cheap
/// error bound (10k terrain at 2048: decimation 10.7 -> 9.7 s of thread
/// time, the same meshes). Decimater below asks bounded_error() and
/// flips_normal() itself.
template <class MeshT>
class ModPlaneErrorT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModPlaneErrorT, MeshT, PlaneError);

  explicit ModPlaneErrorT(MeshT& mesh) : Base(mesh, false) { mesh.add_property(quadrics_); }
  ~ModPlaneErrorT() override { Base::mesh().remove_property(quadrics_); }

  void set_max_err(double max_err_m2) { max_err_ = max_err_m2; }
  /// Degrees; as ModNormalFlippingT::set_max_normal_deviation.
  void set_max_normal_deviation(double degrees) { min_cos_ = std::cos(degrees / 180.0 * M_PI); }

  void initialize() override {
    Mesh& m = Base::mesh();
    for (auto v : m.vertices()) m.property(quadrics_, v).clear();
    for (auto f : m.faces()) {
      auto fv = m.fv_iter(f);
      const auto v0 = *fv++;
      const auto v1 = *fv++;
      const auto v2 = *fv;
      const OpenMesh::Vec3d p0 = m.point(v0);
      OpenMesh::Vec3d n = (m.point(v1) - p0) % (m.point(v2) - p0);
      const double len = n.norm();
      if (!(len > 1e-300)) continue;  // degenerate face: no plane
      n /= len;
      const OpenMesh::Geometry::Quadricd q(n[0], n[1], n[2], -(p0 | n));
      m.property(quadrics_, v0) += q;
      m.property(quadrics_, v1) += q;
      m.property(quadrics_, v2) += q;
    }
  }

  /// The error of the collapse (m^2), or ILLEGAL_COLLAPSE where it is over
  /// the bound or the two vertices' valences (`valence`, by vertex index)
  /// add up to too much; no normal test.
  float bounded_error(const CollapseInfo& ci, const std::vector<unsigned>& valence) {
    OpenMesh::Geometry::Quadricd q = Base::mesh().property(quadrics_, ci.v0);
    q += Base::mesh().property(quadrics_, ci.v1);
    const double err = q(ci.p1);
    if (!(err < max_err_)) return float(Base::ILLEGAL_COLLAPSE);
    // Flat regions would otherwise collapse into a few vertices of huge
    // valence, which makes every later collapse test slow and the
    // triangles needle-thin.
    if (valence[size_t(ci.v0.idx())] + valence[size_t(ci.v1.idx())] > kMaxValence + 4) {
      return float(Base::ILLEGAL_COLLAPSE);
    }
    return float(err);
  }

  void postprocess_collapse(const CollapseInfo& ci) override {
    Base::mesh().property(quadrics_, ci.v1) += Base::mesh().property(quadrics_, ci.v0);
  }

  // Whether moving v0 to p1 turns a face around it (other than the two that
  // go) by more than the deviation, as ModNormalFlippingT::collapse_priority
  // computes it (the face normals are kept up to date by the Decimater).
  bool flips_normal(const CollapseInfo& ci) {
    const Mesh& m = Base::mesh();
    for (auto vf = m.cvf_iter(ci.v0); vf.is_valid(); ++vf) {
      const auto f = *vf;
      if (f == ci.fl || f == ci.fr) continue;
      if ((m.normal(f) | m.face_normal(f, ci.v0, ci.p1)) < min_cos_) return true;
    }
    return false;
  }

 private:
  static constexpr unsigned kMaxValence = 12;
  double max_err_ = 0.0;
  double min_cos_ = -1.0;  // no normal test
  OpenMesh::VPropHandleT<OpenMesh::Geometry::Quadricd> quadrics_;
};

/// Greedy decimation with ModPlaneErrorT as OpenMesh's DecimaterT::decimate
/// runs it (each vertex in a heap keyed by its best collapse; after a
/// collapse, the vertices around it are keyed again), with the tests of a
/// candidate collapse in the order of their cost: the error bound (one
/// quadric) first, then OpenMesh's topology test (both one-rings), then the
/// normal test. DecimaterT asks the topology first, though most candidates
/// fail the bound (for the same reason the bound looks at the error before
/// the valences). Both keep the same candidates and pick the same best one,
/// so the meshes are the same (10k terrain at 2048: decimation 7.0-9.5 ->
/// 3.7-4.0 s of thread time, the same GLB).
class Decimater : public OpenMesh::Decimater::BaseDecimaterT<OMesh> {
 public:
  using Base = OpenMesh::Decimater::BaseDecimaterT<OMesh>;
  using PlaneError = ModPlaneErrorT<OMesh>;

  Decimater(OMesh& mesh, double max_error) : Base(mesh), mesh_(mesh) {
    add(module_);
    module(module_).set_max_err(max_error * max_error);
    module(module_).set_max_normal_deviation(60.0);
    mesh_.add_property(target_);
    mesh_.add_property(priority_);
    mesh_.add_property(position_);
  }
  ~Decimater() {
    mesh_.remove_property(target_);
    mesh_.remove_property(priority_);
    mesh_.remove_property(position_);
  }

  /// Collapses until no collapse within the bound is left.
  void decimate() {
    if (!initialize()) return;
    PlaneError& plane_error = module(module_);
    Heap heap(HeapInterface{mesh_, priority_, position_});
    heap.reserve(mesh_.n_vertices());
    // The best collapse of v, if any, keyed in the heap. Its candidates
    // within the bound are tested in order of their error (ties in
    // circulation order), so the first that passes the topology and normal
    // tests is the best, the one that testing each in circulation order
    // keeps.
    std::vector<std::pair<float, OMesh::HalfedgeHandle>> candidates;  // key's scratch
    const auto key = [&](OMesh::VertexHandle v) {
      float best = std::numeric_limits<float>::max();
      OMesh::HalfedgeHandle target;
      candidates.clear();
      for (auto h : mesh_.voh_range(v)) {
        const float err = plane_error.bounded_error(CollapseInfo(mesh_, h), valence_);
        if (err >= 0.0f) candidates.emplace_back(err, h);
      }
      std::stable_sort(candidates.begin(), candidates.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
      for (const auto& [err, h] : candidates) {
        const CollapseInfo ci(mesh_, h);
        if (!collapse_legal(ci) || plane_error.flips_normal(ci)) continue;
        best = err;
        target = h;
        break;
      }
      mesh_.property(target_, v) = target;
      if (target.is_valid()) {
        mesh_.property(priority_, v) = best;
        if (heap.is_stored(v))
          heap.update(v);
        else
          heap.insert(v);
      } else {
        if (heap.is_stored(v)) heap.remove(v);
        mesh_.property(priority_, v) = -1.0f;
      }
    };
    valence_.assign(mesh_.n_vertices(), 0);
    for (auto v : mesh_.vertices()) valence_[size_t(v.idx())] = mesh_.valence(v);
    for (auto v : mesh_.vertices()) {
      heap.reset_heap_position(v);
      if (!mesh_.status(v).deleted()) key(v);
    }
    std::vector<OMesh::VertexHandle> around;
    while (!heap.empty()) {
      const OMesh::VertexHandle v = heap.front();
      heap.pop_front();
      CollapseInfo ci(mesh_, mesh_.property(target_, v));
      if (!collapse_legal(ci)) continue;
      around.assign(mesh_.vv_begin(ci.v0), mesh_.vv_end(ci.v0));
      preprocess_collapse(ci);
      mesh_.collapse(ci.v0v1);
      for (auto f : mesh_.vf_range(ci.v1)) {
        if (!mesh_.status(f).deleted()) mesh_.set_normal(f, mesh_.face_normal(f));
      }
      postprocess_collapse(ci);
      // Only v0's neighbours change valence: v1 takes v0's edges, and the
      // two apexes lose one.
      for (auto w : around) valence_[size_t(w.idx())] = mesh_.valence(w);
      for (auto w : around) key(w);
    }
  }

 private:
  /// BaseDecimaterT::is_collapse_legal with the mesh's inline queries.
  bool collapse_legal(const CollapseInfo& ci) const {
    if (mesh_.status(ci.v0).locked()) return false;
    if (!mesh_.is_collapse_ok(ci.v0v1)) return false;
    if (ci.vl.is_valid() && ci.vr.is_valid() && mesh_.has_halfedge(ci.vl, ci.vr) &&
        valence_[size_t(ci.vl.idx())] == 3 && valence_[size_t(ci.vr.idx())] == 3) {
      return false;
    }
    if (mesh_.status(ci.v0).feature() && !mesh_.status(mesh_.edge_handle(ci.v0v1)).feature())
      return false;
    if (mesh_.is_boundary(ci.v0)) {
      // No boundary vertex into an inner one, and only one one-ring
      // intersection.
      if (!mesh_.is_boundary(ci.v1)) return false;
      if (ci.vl.is_valid() && ci.vr.is_valid()) return false;
    }
    // At least two faces at v0.
    return mesh_.cw_rotated_halfedge_handle(mesh_.cw_rotated_halfedge_handle(ci.v0v1)) != ci.v0v1;
  }

  struct HeapInterface {
    OMesh& mesh;
    OpenMesh::VPropHandleT<float> priority;
    OpenMesh::VPropHandleT<int> position;
    bool less(OMesh::VertexHandle a, OMesh::VertexHandle b) {
      return mesh.property(priority, a) < mesh.property(priority, b);
    }
    bool greater(OMesh::VertexHandle a, OMesh::VertexHandle b) {
      return mesh.property(priority, a) > mesh.property(priority, b);
    }
    int get_heap_position(OMesh::VertexHandle v) { return mesh.property(position, v); }
    void set_heap_position(OMesh::VertexHandle v, int p) { mesh.property(position, v) = p; }
  };
  using Heap = OpenMesh::Utils::HeapT<OMesh::VertexHandle, HeapInterface>;

  OMesh& mesh_;
  PlaneError::Handle module_;
  OpenMesh::VPropHandleT<OMesh::HalfedgeHandle> target_;
  OpenMesh::VPropHandleT<float> priority_;
  OpenMesh::VPropHandleT<int> position_;
  std::vector<unsigned> valence_;  // by vertex index, kept up to date by decimate()
};

// ---------------------------------------------------------------------------
// Patch finding

/// Layer texels of one patch (indices into the maps' per-layer arrays).
struct PatchTexels {
  LayerArray<size_t> texels;  // (resized unwritten, then filled on all cores)
};

struct TexelCoord {
  int l, i, j;
};

TexelCoord coord_of(const SnowMaps& maps, size_t k) {
  const size_t per_layer = maps.grid.texels();
  const size_t rem = k % per_layer;
  return {int(k / per_layer), int(rem % size_t(maps.grid.width)),
          int(rem / size_t(maps.grid.width))};
}

/// coord_of for many texels: each is found from the last where they share a
/// row, as a patch's texels mostly do, so most take no division. With the
/// bounds found on all cores, build_field of the 1M terrain's ground at
/// 2048 (3.9M texels, 2 cores): bounds 0.026 -> 0.013 s, members 0.027-0.030
/// -> 0.010-0.014 s.
class TexelRows {
 public:
  explicit TexelRows(const SnowMaps& maps)
      : per_layer_(maps.grid.texels()), width_(size_t(maps.grid.width)) {}
  TexelCoord operator()(size_t k) {
    if (k < row_ || k - row_ >= width_) {
      const size_t rem = k % per_layer_;
      row_ = k - rem % width_;
      l_ = int(k / per_layer_);
      j_ = int(rem / width_);
    }
    return {l_, int(k - row_), j_};
  }

 private:
  size_t per_layer_, width_;
  size_t row_ = SIZE_MAX;  // the first texel of the row of the last texel
  int l_ = 0, j_ = 0;
};

/// Connected components of snowy texels; see polygonize()'s contract.
///
/// Patches grow breadth first from seeds in index order, and take at most
/// one layer per column. Most texels of a terrain, a floor or a roof lie on
/// the top surface of a column, under the open sky, with no snow on the
/// surfaces below it (a slab's underside, the floor under a roof): "single"
/// texels. Between two of them the landing rule reduces to "tops within
/// max_step" (snow that does not land on a column's top lands lower, where
/// there is no snow to join), which is symmetric and never meets the
/// one-layer rule. So those are first joined
/// into clusters on all cores (union-find over strips of rows), and a patch
/// that reaches a cluster takes all of it; only the texels of other columns,
/// and the cluster texels beside them, are walked one by one. The patches
/// hold the texels the walk of every texel would give them (an order of
/// their texels aside), but where two layers of one column could both join
/// a patch, the one reached first may differ from that walk's.
std::vector<PatchTexels> find_patches(const SnowMaps& maps, const LayerArray<float>& depth,
                                      float min_thickness, float max_step) {
  const size_t n = depth.size();
  const size_t per_layer = maps.grid.texels();
  const int w = maps.grid.width;
  const int h = maps.grid.height;
  auto snowy = [&](size_t k) { return depth[k] > min_thickness; };
  auto top = [&](size_t k) { return maps.ground[k] + depth[k]; };
  static const int kDi[4] = {1, -1, 0, 0};
  static const int kDj[4] = {0, 0, 1, -1};

  // Single snowy texels (layer 0; their index is their column's).
  // (These arrays over every column are written on all cores; root and
  // cluster only where a texel is clustered, the only entries read.)
  const auto snow_below = [&](size_t c) {
    for (size_t k = c + per_layer; k < n && !std::isnan(maps.ground[k]); k += per_layer) {
      if (snowy(k)) return true;
    }
    return false;
  };
  LayerArray<uint8_t> single(per_layer), clustered(per_layer);
  parallel_for(size_t(h), [&](size_t j) {
    for (size_t c = j * size_t(w); c < (j + 1) * size_t(w); ++c) {
      single[c] = !std::isnan(maps.ground[c]) && std::isinf(maps.ceiling[c]) &&
                  maps.ceiling[c] > 0.0f && !snow_below(c);
      clustered[c] = single[c] && snowy(c);
    }
  });
  auto joined = [&](size_t a, size_t b) {
    return clustered[a] && clustered[b] && std::abs(top(b) - top(a)) <= max_step;
  };
  // Union-find, each cluster's root its lowest index: strips of rows on all
  // cores, then the rows where strips meet.
  LayerArray<uint32_t> root(per_layer);
  auto find = [&](uint32_t a) {
    while (root[a] != a) a = root[a] = root[root[a]];
    return a;
  };
  auto unite = [&](uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) root[std::max(a, b)] = std::min(a, b);
  };
  const size_t strips = std::min<size_t>(size_t(h), 4 * size_t(default_threads()));
  auto strip_row = [&](size_t s) { return int(s * size_t(h) / strips); };
  parallel_for(strips, [&](size_t s) {
    for (int j = strip_row(s); j < strip_row(s + 1); ++j) {
      for (int i = 0; i < w; ++i) {
        const uint32_t c = uint32_t(j) * uint32_t(w) + uint32_t(i);
        if (!clustered[c]) continue;
        root[c] = c;
        if (i > 0 && joined(c, c - 1)) unite(c, c - 1);
        if (j > strip_row(s) && joined(c, c - uint32_t(w))) unite(c, c - uint32_t(w));
      }
    }
  });
  for (size_t s = 1; s < strips; ++s) {
    const uint32_t row = uint32_t(strip_row(s)) * uint32_t(w);
    for (uint32_t c = row; c < row + uint32_t(w); ++c) {
      if (joined(c, c - uint32_t(w))) unite(c, c - uint32_t(w));
    }
  }
  LayerArray<uint32_t> cluster(per_layer);  // each clustered texel's root
  parallel_for(size_t(h), [&](size_t j) {
    for (size_t c = j * size_t(w); c < (j + 1) * size_t(w); ++c) {
      if (!clustered[c]) continue;
      uint32_t r = uint32_t(c);
      while (root[r] != r) r = root[r];
      cluster[c] = r;
    }
  });
  root = LayerArray<uint32_t>();
  // The cluster texels beside a column that is not single, by cluster: the
  // only ones a walk must visit.
  std::vector<std::pair<uint32_t, uint32_t>> edge;  // (root, texel)
  {
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> rows(static_cast<size_t>(h));
    parallel_for(size_t(h), [&](size_t j) {
      for (int i = 0; i < w; ++i) {
        const size_t c = j * size_t(w) + size_t(i);
        if (!clustered[c]) continue;
        for (int d = 0; d < 4; ++d) {
          const int ni = i + kDi[d], nj = int(j) + kDj[d];
          if (ni < 0 || nj < 0 || ni >= w || nj >= h) continue;
          if (!single[size_t(nj) * size_t(w) + size_t(ni)]) {
            rows[j].emplace_back(cluster[c], uint32_t(c));
            break;
          }
        }
      }
    });
    size_t count = 0;
    for (const auto& row : rows) count += row.size();
    edge.reserve(count);
    for (const auto& row : rows) edge.insert(edge.end(), row.begin(), row.end());
    std::sort(edge.begin(), edge.end());
  }

  // Patch p is stamped p + 1: these start as zero pages, which only the
  // texels a walk visits fault in (three filled arrays over every texel were
  // 0.018 s on one core for the 1M-triangle terrain at 2048).
  ZeroedArray<uint8_t> claimed(n);                // texels outside clusters
  ZeroedArray<int32_t> cluster_patch(per_layer);  // by root
  ZeroedArray<int32_t> column_stamp(per_layer);
  std::vector<PatchTexels> patches;
  constexpr size_t kClusterItem = size_t(1) << 63;  // a queue item that is a cluster's root
  std::vector<size_t> queue;
  for (size_t seed = 0; seed < n; ++seed) {
    if (!snowy(seed)) continue;
    const bool in_cluster = seed < per_layer && clustered[seed];
    if (in_cluster ? cluster_patch[cluster[seed]] != 0 : claimed[seed] != 0) continue;
    const int32_t id = int32_t(patches.size()) + 1;  // the stamp
    patches.emplace_back();
    PatchTexels& patch = patches.back();
    auto claim = [&](size_t k) {
      if (k < per_layer && clustered[k]) {
        cluster_patch[cluster[k]] = id;
        queue.push_back(kClusterItem | cluster[k]);
        return;
      }
      claimed[k] = 1;
      column_stamp[k % per_layer] = id;
      patch.texels.push_back(k);
      queue.push_back(k);
    };
    auto unclaimed = [&](size_t k) {
      return k < per_layer && clustered[k] ? cluster_patch[cluster[k]] == 0 : claimed[k] == 0;
    };
    // The walk from texel a: the neighbours it joins by the landing rule.
    auto walk = [&](size_t a) {
      const TexelCoord ca = coord_of(maps, a);
      const bool a_clustered = a < per_layer && clustered[a];
      const float ha = top(a);
      for (int d = 0; d < 4; ++d) {
        const int ni = ca.i + kDi[d];
        const int nj = ca.j + kDj[d];
        if (ni < 0 || nj < 0 || ni >= w || nj >= h) continue;
        const size_t col = size_t(nj) * size_t(w) + size_t(ni);
        if (a_clustered && single[col]) continue;  // its cluster, or not joined
        if (column_stamp[col] == id) continue;     // one layer per column and patch
        auto consider = [&](size_t b) {
          if (unclaimed(b) && snowy(b) && column_stamp[col] != id) claim(b);
        };
        // Snow leaving a lands on b (b lies at most max_step lower) ...
        const int lb = landing_layer(maps, depth.data(), ni, nj, ha);
        if (lb >= 0) {
          const size_t b = maps.index(lb, ni, nj);
          if (ha - top(b) <= max_step) consider(b);
        }
        // ... or snow leaving b lands on a (b lies at most max_step higher).
        for (int l = 0; l < maps.layers; ++l) {
          const size_t b = maps.index(l, ni, nj);
          if (std::isnan(maps.ground[b])) break;
          const float hb = top(b);
          if (hb < ha || hb - ha > max_step || !snowy(b)) continue;
          if (landing_layer(maps, depth.data(), ca.i, ca.j, hb) == ca.l) consider(b);
        }
      }
    };
    queue.clear();
    claim(seed);
    for (size_t next = 0; next < queue.size(); ++next) {
      const size_t item = queue[next];
      if (!(item & kClusterItem)) {
        walk(item);
        continue;
      }
      const uint32_t r = uint32_t(item & ~kClusterItem);
      for (auto e = std::lower_bound(edge.begin(), edge.end(), std::make_pair(r, uint32_t(0)));
           e != edge.end() && e->first == r; ++e) {
        walk(e->second);
      }
    }
  }
  // The clusters' texels join their patches in index order, each patch's
  // list grown once (a 4M-texel ground grown by doubling: 0.13-0.16 s of
  // copies and fresh pages on 2 cores), on all cores: each strip of rows
  // counts its texels per patch, then writes them from its offsets (it took
  // 0.033 s on one core for the 1M-triangle terrain at 2048; with the zero
  // pages above, patches found 0.145 -> 0.106-0.114 s on 2 cores). With very
  // many patches, whose counts per strip would take much memory, on one core.
  const auto patch_of = [&](size_t c) { return size_t(cluster_patch[cluster[c]] - 1); };
  const auto strip_texels = [&](size_t s, auto&& fn) {
    const size_t end = size_t(strip_row(s + 1)) * size_t(w);
    for (size_t c = size_t(strip_row(s)) * size_t(w); c < end; ++c) {
      if (clustered[c]) fn(c);
    }
  };
  const bool apart = strips * patches.size() <= (size_t(1) << 20);
  std::vector<std::vector<size_t>> lists(apart ? strips : 1,
                                         std::vector<size_t>(patches.size(), 0));
  const auto each_strip = [&](auto&& fn) {  // fn(strip, its list of counts or offsets)
    if (apart) {
      parallel_for(strips, [&](size_t s) { fn(s, lists[s]); });
    } else {
      for (size_t s = 0; s < strips; ++s) fn(s, lists[0]);
    }
  };
  each_strip([&](size_t s, std::vector<size_t>& counts) {
    strip_texels(s, [&](size_t c) { ++counts[patch_of(c)]; });
  });
  for (size_t p = 0; p < patches.size(); ++p) {
    size_t end = patches[p].texels.size();
    for (std::vector<size_t>& list : lists) {
      const size_t count = list[p];
      list[p] = end;
      end += count;
    }
    patches[p].texels.resize(end);
  }
  each_strip([&](size_t s, std::vector<size_t>& at) {
    strip_texels(s, [&](size_t c) {
      const size_t p = patch_of(c);
      patches[p].texels[at[p]++] = c;
    });
  });
  return patches;
}

// ---------------------------------------------------------------------------
// Per-patch fields on texel centres

/// The patch's window: its bounding box of columns plus one sample of margin
/// on every side, so every cell touching a patch sample exists.
struct PatchField {
  int i0 = 0, j0 = 0;  // map column of window sample (0, 0)
  int w = 0, h = 0;    // window size in samples
  // (resized unwritten, then filled on all cores)
  LayerArray<uint8_t> member;
  LayerArray<float> s;       // snow thickness, m (0 outside the patch)
  LayerArray<float> g;       // ground height, m (extrapolated outside; NaN far away)
  LayerArray<float> gx, gz;  // ground slope dy/dx, dy/dz (members)

  size_t at(int wi, int wj) const { return size_t(wj) * size_t(w) + size_t(wi); }
};

// Texels per task of build_field's parallel loops.
constexpr size_t kFieldChunk = 1 << 14;
// Patches are meshed on all cores already: a loop inside one (build_field,
// smooth_field) starts threads of its own, which pays only for large
// patches (a building's hundreds of single-texel patches: 0.05 -> 0.08 s).
constexpr size_t kParallelSamples = 1 << 16;
unsigned threads_for(size_t samples) { return samples >= kParallelSamples ? 0u : 1u; }

// Calls fn(wi, wj, sample) for every window sample of f, rows on `threads`
// threads (parallel_for's count).
template <class Fn>
void each_sample(const PatchField& f, unsigned threads, const Fn& fn) {
  parallel_for(
      size_t(f.h),
      [&](size_t row) {
        const int wj = int(row);
        for (int wi = 0; wi < f.w; ++wi) fn(wi, wj, f.at(wi, wj));
      },
      threads);
}

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

/// Mass-conserving smoothing of the snow surface g + s: explicit diffusion
/// between 4-neighbour members, each flux limited so no member falls under
/// min_thickness.
///
/// Each sample gathers its four fluxes, on all cores, in the order a serial
/// sweep over the rows would add them: from the member above, from the one
/// to the left, then its own to the right and down.
void smooth_field(PatchField& f, int iterations, float min_thickness) {
  const float kRate = 0.125f;
  // The flux from member a to member b.
  auto flux = [&](size_t a, size_t b) {
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

// ---------------------------------------------------------------------------
// Top surface by marching squares

struct TopMesh {
  std::vector<glm::dvec3> positions;
  std::vector<int32_t> sample;  // window sample of a member vertex, -1 for outline vertices
  std::vector<uint32_t> tris;   // counter-clockwise seen from above (+Y normals)
  // The bottom's triangles, wound as tris, where it has its own (empty:
  // the top's); over the top's vertices, with the same outline.
  std::vector<uint32_t> bottom;
  bool in_pieces = false;  // to be decimated in pieces (triangulate_top)
};

double plan_area2(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  // Twice the signed area in the (z, x) plane: positive when the triangle's
  // normal points up (+Y) in a right-handed frame.
  return (b.z - a.z) * (c.x - a.x) - (b.x - a.x) * (c.z - a.z);
}

/// The top surface: vertices at patch samples (height g + s) and on the
/// outline (height g); see the comments inside for the two triangulations.
/// tolerance < 0: every cell at full resolution. cut (a power of two >= 2,
/// or 0): no triangle crosses a window sample column k * cut, so the top
/// splits into strips of columns along edges (see top_pieces).
/// With tolerance >= 0 the bottom is triangulated on its own
/// (TopMesh::bottom), within the tolerance of the ground alone: the same
/// network, split only where the ground needs it, so a coarsening of the
/// top's with the same outline cells. On flat ground it is a few large
/// triangles and the outline's ring, which the decimation no longer has to
/// collapse (Kenney tiles at 0.3 m: the largest patch's solid 25-27 ->
/// 19-24 ms; the courtyard's house roof 0.133-0.142 -> 0.079-0.102 s;
/// triangles out within 1 %, the same volumes). A top cut into strips with
/// more than piece_triangles triangles is to be decimated in pieces
/// (TopMesh::in_pieces), and its bottom keeps the cut.
TopMesh triangulate_top(const PatchField& f, const MapGrid& grid, float min_thickness,
                        double tolerance, int cut = 0, size_t piece_triangles = SIZE_MAX) {
  std::vector<uint32_t>* out = nullptr;  // where emit() puts triangles: top.tris, then top.bottom
  TopMesh top;
  std::vector<int32_t> sample_vertex(f.member.size(), -1);
  std::unordered_map<uint64_t, int32_t> edge_vertex;
  const double texel = grid.texel;
  auto sample_pos = [&](size_t a) {
    const int wi = int(a % size_t(f.w)), wj = int(a / size_t(f.w));
    return glm::dvec2(grid.origin.x + (double(f.i0 + wi) + 0.5) * texel,
                      grid.origin.y + (double(f.j0 + wj) + 0.5) * texel);
  };
  auto vertex_at_sample = [&](size_t a) {
    if (sample_vertex[a] < 0) {
      const glm::dvec2 p = sample_pos(a);
      sample_vertex[a] = int32_t(top.positions.size());
      top.positions.emplace_back(p.x, double(f.g[a]) + double(f.s[a]), p.y);
      top.sample.push_back(int32_t(a));
    }
    return uint32_t(sample_vertex[a]);
  };
  auto vertex_on_edge = [&](size_t in, size_t out) {
    const uint64_t key =
        (uint64_t(std::min(in, out)) << 1) | (std::max(in, out) - std::min(in, out) == 1 ? 0u : 1u);
    auto it = edge_vertex.find(key);
    if (it != edge_vertex.end()) return uint32_t(it->second);
    const double si = f.s[in], so = f.s[out];
    const double t = std::clamp((si - min_thickness) / std::max(si - so, 1e-12), 0.01, 0.99);
    const glm::dvec2 p = glm::mix(sample_pos(in), sample_pos(out), t);
    const double y = double(f.g[in]) + (double(f.g[out]) - double(f.g[in])) * t;
    const int32_t v = int32_t(top.positions.size());
    top.positions.emplace_back(p.x, y, p.y);
    top.sample.push_back(-1);
    edge_vertex.emplace(key, v);
    return uint32_t(v);
  };
  auto emit = [&](const std::vector<uint32_t>& poly) {
    // poly is convex and runs counter-clockwise in (x, z), i.e. clockwise
    // seen from above. Fan out from a patch sample: a diagonal between two
    // outline vertices would be shared by top and bottom, four faces at
    // one edge.
    size_t first = 0;
    while (top.sample[poly[first]] < 0) ++first;
    const size_t n = poly.size();
    for (size_t k = 1; k + 1 < n; ++k) {
      out->insert(out->end(), {poly[first], poly[(first + k + 1) % n], poly[(first + k) % n]});
    }
  };

  // Marching squares on one cell that has patch samples at some corners only.
  std::vector<uint32_t> poly;
  auto march_cell = [&](int ci, int cj) {
    const size_t c[4] = {f.at(ci, cj), f.at(ci + 1, cj), f.at(ci + 1, cj + 1), f.at(ci, cj + 1)};
    const bool in[4] = {f.member[c[0]] != 0, f.member[c[1]] != 0, f.member[c[2]] != 0,
                        f.member[c[3]] != 0};
    const int inside = int(in[0]) + int(in[1]) + int(in[2]) + int(in[3]);
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
    if (saddle && mean <= min_thickness) {
      // Two separate corners: each inside sample with its two crossings.
      for (size_t k = 0; k < poly.size(); ++k) {
        if (top.sample[poly[k]] < 0) continue;
        emit({poly[(k + poly.size() - 1) % poly.size()], poly[k], poly[(k + 1) % poly.size()]});
      }
    } else {
      emit(poly);
    }
  };
  auto emit_oriented = [&](uint32_t a, uint32_t b, uint32_t c) {
    if (plan_area2(top.positions[a], top.positions[b], top.positions[c]) < 0.0) std::swap(b, c);
    out->insert(out->end(), {a, b, c});
  };

  // Right-triangulated irregular network over the window padded to a
  // (2^k + 1)^2 grid (Evans, Kirkpatrick and Townsend 2001; the error pass
  // follows mapbox/martini): a triangle stays whole while top and ground
  // interpolate every sample it holds within `tolerance`. Corners of cells
  // with patch samples at some corners only get an infinite error, so
  // those cells (and their neighbours) are refined to single cells and
  // take the marching-squares outline; the shared per-vertex errors keep
  // the triangulation free of T-junctions.
  int tile = 1;
  while (tile + 1 < std::max(f.w, f.h)) tile *= 2;
  const int n = tile + 1;
  // The errors of the top and ground together (error), and of the ground
  // alone (ground_error), the bottom's.
  std::vector<float> error(size_t(n) * size_t(n), 0.0f);
  std::vector<float> ground_error(tolerance >= 0.0 ? error.size() : 0, 0.0f);
  auto member = [&](int x, int y) { return x < f.w && y < f.h && f.member[f.at(x, y)] != 0; };
  const float kForce = std::numeric_limits<float>::infinity();
  // Split every triangle whose hypotenuse midpoint lies on the grid of half
  // the cut: down to the triangles inside one cut x cut square, whose legs
  // lie on its sides, centre lines and diagonals. Those midpoints are the
  // ones of the triangles with hypotenuses `cut` samples long or longer,
  // their ancestors' included: forced after the errors are worked out, they
  // split the same triangles as forced before.
  const auto force_cut = [&](std::vector<float>& e) {
    for (int y = 0; y <= tile; y += cut / 2) {
      for (int x = 0; x <= tile; x += cut / 2) e[size_t(y) * size_t(n) + size_t(x)] = kForce;
    }
  };
  const auto compute_errors = [&] {
    for (int cj = 0; cj + 1 < f.h; ++cj) {
      for (int ci = 0; ci + 1 < f.w; ++ci) {
        const int inside = int(member(ci, cj)) + int(member(ci + 1, cj)) + int(member(ci, cj + 1)) +
                           int(member(ci + 1, cj + 1));
        if (inside == 0 || inside == 4) continue;
        for (int q = 0; q < 4; ++q) {
          const size_t k = size_t(cj + (q >> 1)) * size_t(n) + size_t(ci + (q & 1));
          error[k] = kForce;
          if (!ground_error.empty()) ground_error[k] = kForce;
        }
      }
    }
    if (tolerance >= 0.0 && cut >= 2) force_cut(error);
    if (tolerance < 0.0) return;
    // A triangle's error takes in its own (how far top and ground at its
    // hypotenuse midpoint lie from the hypotenuse's) and its children's,
    // kept at that midpoint, which the two triangles sharing a hypotenuse
    // share. So each midpoint is worked out once, level by level, finest
    // first, from its two triangles: a square's centre is the midpoint of
    // its diagonal, whose children's midpoints are the square's edge
    // midpoints; an edge midpoint (hypotenuse of length 2h) is the midpoint
    // of the triangles with right angles h to either side, whose children's
    // midpoints are the centres of the four squares of side h around it.
    // The diagonal of a square runs through its parent square's centre: from
    // its own top-left corner to its bottom-right one where the square's
    // column and row (in squares of its size) add up to an even number.
    // These are the errors of a recursive descent over the triangles from
    // the two roots, bit for bit, without a descent per level, and each
    // midpoint written by one task, rows in parallel (the 1M terrain at
    // 2048: triangulate_top 0.21-0.35 -> 0.07-0.08 s on 2 cores).
    //
    // own: the error of triangle (a, b) with its right angle at c. Every
    // triangle turns the same way from a to b to c, and its sums run in that
    // order, so the two that share a hypotenuse may round apart.
    const auto own = [&](int ax, int ay, int bx, int by, int cx, int cy, float& e, float& eg) {
      if ((bx - ax) * (cy - ay) - (by - ay) * (cx - ax) > 0) {
        std::swap(ax, bx);
        std::swap(ay, by);
      }
      const int mx = (ax + bx) >> 1, my = (ay + by) >> 1;
      if (!(member(ax, ay) && member(bx, by) && member(mx, my))) return;
      const size_t a = f.at(ax, ay), b = f.at(bx, by), m = f.at(mx, my);
      const float dg = std::abs(0.5f * (f.g[a] + f.g[b]) - f.g[m]);
      const float dt = std::abs(0.5f * (f.g[a] + f.s[a] + f.g[b] + f.s[b]) - (f.g[m] + f.s[m]));
      e = std::max(e, std::max(dg, dt));
      eg = std::max(eg, dg);
    };
    const auto at = [&](int x, int y) { return size_t(y) * size_t(n) + size_t(x); };
    // Both errors at midpoint k take in those at its children's midpoints.
    const auto take = [&](size_t k, std::initializer_list<size_t> children) {
      for (size_t c : children) {
        error[k] = std::max(error[k], error[c]);
        ground_error[k] = std::max(ground_error[k], ground_error[c]);
      }
    };
    const unsigned threads = threads_for(error.size());
    for (int side = 2; side <= tile; side *= 2) {
      const int h = side / 2;
      const bool parent = side > 2;
      // Edge midpoints of squares of this side (hypotenuses of length side).
      parallel_for(
          size_t(tile / h + 1),
          [&](size_t row) {
            const int y = int(row) * h;
            for (int x = (y % side == 0) ? h : 0; x <= tile; x += side) {
              const size_t k = at(x, y);
              const bool horizontal = y % side == 0;
              const int dx = horizontal ? h : 0, dy = horizontal ? 0 : h;
              for (int sgn = -1; sgn <= 1; sgn += 2) {
                const int cx = x + sgn * dy, cy = y + sgn * dx;  // right angle
                if (cx < 0 || cy < 0 || cx > tile || cy > tile) continue;
                own(x - dx, y - dy, x + dx, y + dy, cx, cy, error[k], ground_error[k]);
                if (!parent) continue;
                take(k, {at((x - dx + cx) >> 1, (y - dy + cy) >> 1),
                         at((x + dx + cx) >> 1, (y + dy + cy) >> 1)});
              }
            }
          },
          threads);
      // Centres of squares of this side (diagonals), whose children are the
      // edge midpoints just done.
      parallel_for(
          size_t(tile / side),
          [&](size_t qy) {
            const int y = int(qy) * side + h;
            for (int qx = 0; qx * side < tile; ++qx) {
              const int x = qx * side + h;
              const size_t k = at(x, y);
              float &e = error[k], &eg = ground_error[k];
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
  };
  compute_errors();
  std::vector<uint8_t> cell_done(f.member.size(), 0);
  const float split_above = tolerance >= 0.0 ? float(tolerance) : -1.0f;
  const float* split_error = error.data();  // the top's, then the bottom's
  // Triangle (a, b, c): hypotenuse a-b, right angle at c.
  const auto visit = [&](const auto& self, int ax, int ay, int bx, int by, int cx, int cy) -> void {
    const int mx = (ax + bx) >> 1, my = (ay + by) >> 1;
    const bool leaf = std::abs(ax - cx) + std::abs(ay - cy) <= 1;
    if (!leaf && split_error[size_t(my) * size_t(n) + size_t(mx)] > split_above) {
      self(self, cx, cy, ax, ay, mx, my);
      self(self, bx, by, cx, cy, mx, my);
      return;
    }
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
    uint8_t& done = cell_done[f.at(ci, cj)];
    if (done ||
        !(member(ci, cj) || member(ci + 1, cj) || member(ci, cj + 1) || member(ci + 1, cj + 1))) {
      return;
    }
    done = 1;
    march_cell(ci, cj);
  };
  out = &top.tris;
  visit(visit, 0, 0, tile, tile, tile, 0);
  visit(visit, tile, tile, 0, 0, 0, tile);
  top.in_pieces = tolerance >= 0.0 && cut >= 2 && top.tris.size() / 3 > piece_triangles;
  if (tolerance >= 0.0) {
    if (top.in_pieces) force_cut(ground_error);
    split_error = ground_error.data();
    out = &top.bottom;
    std::fill(cell_done.begin(), cell_done.end(), uint8_t(0));
    visit(visit, 0, 0, tile, tile, tile, 0);
    visit(visit, tile, tile, 0, 0, 0, tile);
  }
  return top;
}

/// Laplacian smoothing of the outline polylines (x, y, z of outline vertices
/// move halfway to the mean of their two outline neighbours); a move that
/// would fold a triangle in plan is skipped.
void smooth_outline(TopMesh& top, int iterations, double texel) {
  if (iterations <= 0) return;
  const size_t nv = top.positions.size();
  // Only edges at an outline vertex (sample < 0) are counted: smoothing
  // moves only those, along their boundary edges (the edges without a
  // reverse twin). All edges of a 4M-texel patch took 0.9 s, these 0.04 s.
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

// ---------------------------------------------------------------------------
// Closed mesh, decimation, output

/// The mesh vertices build_solid made for each top vertex: its top vertex
/// and its bottom one (the same for an outline vertex).
struct SolidVertices {
  std::vector<OMesh::VertexHandle> top, bottom;
};

/// Builds the closed solid into `mesh` (an open one for a piece of a top);
/// returns the number of faces that would not form a manifold mesh and
/// were left out (0: all built).
size_t build_solid(const TopMesh& top, const PatchField& f, float bottom_offset, OMesh& mesh,
                   OpenMesh::FPropHandleT<bool> is_top, SolidVertices* vertices = nullptr) {
  std::vector<OMesh::VertexHandle> top_v(top.positions.size());
  std::vector<OMesh::VertexHandle> bottom_v(top.positions.size());
  // Room for the whole solid at once: grown an element at a time, OpenMesh's
  // arrays were a twentieth of polygonize on a small scene (edges: 3 per 2 faces).
  const size_t inner =
      size_t(std::count_if(top.sample.begin(), top.sample.end(), [](int32_t a) { return a >= 0; }));
  const std::vector<uint32_t>& bottom_tris = top.bottom.empty() ? top.tris : top.bottom;
  const size_t faces = (top.tris.size() + bottom_tris.size()) / 3;
  mesh.reserve(top.positions.size() + inner, faces * 3 / 2 + 3, faces);
  for (size_t v = 0; v < top.positions.size(); ++v) {
    const glm::dvec3& p = top.positions[v];
    top_v[v] = mesh.add_vertex(OMesh::Point(p.x, p.y, p.z));
  }
  // Where the bottom has triangles of its own, a bottom vertex is made for
  // the inner vertices they use only.
  std::vector<uint8_t> on_bottom(top.bottom.empty() ? 0 : top.positions.size(), 0);
  for (uint32_t v : top.bottom) on_bottom[v] = 1;
  for (size_t v = 0; v < top.positions.size(); ++v) {
    if (top.sample[v] < 0) {
      bottom_v[v] = top_v[v];  // outline: shared by top and bottom
    } else if (top.bottom.empty() || on_bottom[v]) {
      const glm::dvec3& p = top.positions[v];
      const double y = double(f.g[size_t(top.sample[v])]) - double(bottom_offset);
      bottom_v[v] = mesh.add_vertex(OMesh::Point(p.x, y, p.z));
    }
  }
  size_t failed = 0;
  const auto add = [&](const std::vector<OMesh::VertexHandle>& corner, uint32_t a, uint32_t b,
                       uint32_t c, bool face_top) {
    const auto face = mesh.add_face(corner[a], corner[b], corner[c]);
    if (face.is_valid()) mesh.property(is_top, face) = face_top;
    failed += size_t(!face.is_valid());
  };
  for (size_t t = 0; t < top.tris.size(); t += 3) {
    const auto a = top.tris[t], b = top.tris[t + 1], c = top.tris[t + 2];
    add(top_v, a, b, c, true);
    if (top.bottom.empty()) add(bottom_v, a, c, b, false);
  }
  for (size_t t = 0; t < top.bottom.size(); t += 3) {
    add(bottom_v, top.bottom[t], top.bottom[t + 2], top.bottom[t + 1], false);
  }
  if (vertices) {
    vertices->top = std::move(top_v);
    vertices->bottom = std::move(bottom_v);
  }
  return failed;
}

void decimate(OMesh& mesh, double max_error) {
  mesh.request_vertex_status();
  mesh.request_edge_status();
  mesh.request_face_status();
  mesh.request_face_normals();
  for (auto f : mesh.faces()) mesh.set_normal(f, mesh.face_normal(f));
  Decimater(mesh, max_error).decimate();
  mesh.garbage_collection();
}

/// The top triangles of one piece of a large top, reindexed, with each
/// vertex's index in the whole top.
struct TopPiece {
  TopMesh top;
  std::vector<uint32_t> origin;
};

/// Narrowest strip of window columns (samples) a top is cut into for
/// decimation in pieces.
constexpr int kMinCut = 16;

/// The piece of each top triangle (top) and of each bottom one (bottom,
/// where the bottom has triangles of its own).
struct Pieces {
  std::vector<uint32_t> top, bottom;
};

/// The strip of window columns [k * cut, (k + 1) * cut] each triangle of a
/// top (and of its bottom) triangulated with that cut lies in, grouped into
/// at most `pieces` runs of whole strips with about equally many top
/// triangles; returns the run of each triangle, and in `pieces` the number
/// of runs that got top triangles.
Pieces top_pieces(const TopMesh& top, const PatchField& f, const MapGrid& grid, int cut,
                  size_t& pieces) {
  const auto strips_of = [&](const std::vector<uint32_t>& tris) {
    std::vector<uint32_t> strip(tris.size() / 3);
    for (size_t t = 0; t < strip.size(); ++t) {
      double x = 0.0;
      for (int e = 0; e < 3; ++e) x += top.positions[tris[3 * t + size_t(e)]].x;
      const double column = (x / 3.0 - double(grid.origin.x)) / double(grid.texel) - 0.5 - f.i0;
      strip[t] = uint32_t(std::clamp(std::floor(column / double(cut)), 0.0, 1e9));
    }
    return strip;
  };
  Pieces out{strips_of(top.tris), strips_of(top.bottom)};
  const size_t n = out.top.size();
  size_t strips = 0;
  for (uint32_t k : out.top) strips = std::max(strips, size_t(k) + 1);
  for (uint32_t k : out.bottom) strips = std::max(strips, size_t(k) + 1);
  std::vector<size_t> count(strips, 0);
  for (uint32_t k : out.top) ++count[k];
  std::vector<uint32_t> run(strips, 0);
  uint32_t p = 0;
  size_t before = 0, used = 0;
  for (size_t k = 0; k < strips; ++k) {
    if (count[k] > 0 && used > 0 && p + 1 < pieces && before * pieces >= (p + 1) * n) ++p;
    run[k] = p;
    if (count[k] > 0) used = size_t(p) + 1;
    before += count[k];
  }
  pieces = used;
  for (uint32_t& k : out.top) k = run[k];
  for (uint32_t& k : out.bottom) k = run[k];
  return out;
}

/// The triangles around each vertex of a mesh of nv vertices, in index
/// order: vertex v's are around[first[v], first[v + 1]) (one array, not a
/// vector per vertex: 0.03-0.04 -> 0.013 s for the 1M-triangle terrain's
/// ground at 2048).
struct Around {
  std::vector<uint32_t> first, around;
  Around(const std::vector<uint32_t>& tris, size_t nv) : first(nv + 1, 0), around(tris.size()) {
    for (uint32_t v : tris) ++first[v + 1];
    for (size_t v = 0; v < nv; ++v) first[v + 1] += first[v];
    std::vector<uint32_t> next(first.begin(), first.end() - 1);
    for (size_t c = 0; c < tris.size(); ++c) around[next[tris[c]]++] = uint32_t(c / 3);
  }
  const uint32_t* begin(size_t v) const { return around.data() + first[v]; }
  size_t count(size_t v) const { return first[v + 1] - first[v]; }
};

/// The top triangles of each piece (pieces.top[t] of triangle t, below
/// `count`), and its bottom ones where the bottom has its own. Where a
/// piece's top triangles around a vertex form several fans (the outline
/// comes in between them), each fan gets a vertex of its own, so every piece
/// is a manifold mesh; they share the origin. A bottom triangle takes the
/// vertices of its piece's top there (the bottom is a coarsening of the
/// top); empty where its piece's top has no fan or several at a corner of
/// it (never seen: the outline's cells are whole in both).
std::vector<TopPiece> split_top(const TopMesh& top, const Pieces& pieces, size_t count) {
  const size_t nv = top.positions.size();
  const Around tops(top.tris, nv), bottoms(top.bottom, nv);
  std::vector<TopPiece> out(count);
  std::vector<uint32_t> local(top.tris.size());           // piece vertex of each corner
  std::vector<uint32_t> local_bottom(top.bottom.size());  // the same for the bottom's
  std::vector<uint32_t> fan;
  struct FanVertex {
    uint32_t root, piece, vertex;  // fan root (an index around v), its piece and piece vertex
  };
  std::vector<FanVertex> fan_vertex;
  for (size_t v = 0; v < nv; ++v) {
    // The triangles around v of each piece, joined into fans by the edges
    // (v, w) they share.
    const uint32_t* const around = tops.begin(v);
    const size_t around_count = tops.count(v);
    fan.resize(around_count);
    std::iota(fan.begin(), fan.end(), 0u);
    const auto root = [&](uint32_t a) {
      while (fan[a] != a) a = fan[a] = fan[fan[a]];
      return a;
    };
    for (size_t a = 0; a < around_count; ++a) {
      for (size_t b = a + 1; b < around_count; ++b) {
        const uint32_t ta = around[a], tb = around[b];
        if (pieces.top[ta] != pieces.top[tb]) continue;
        int shared = 0;
        for (int ea = 0; ea < 3; ++ea) {
          for (int eb = 0; eb < 3; ++eb) {
            shared +=
                int(top.tris[3 * size_t(ta) + size_t(ea)] == top.tris[3 * size_t(tb) + size_t(eb)]);
          }
        }
        if (shared >= 2) fan[root(uint32_t(a))] = root(uint32_t(b));
      }
    }
    fan_vertex.clear();
    for (size_t a = 0; a < around_count; ++a) {
      const uint32_t p = pieces.top[around[a]];
      TopPiece& part = out[p];
      const uint32_t r = root(uint32_t(a));
      auto it = std::find_if(fan_vertex.begin(), fan_vertex.end(),
                             [&](const FanVertex& fv) { return fv.root == r; });
      if (it == fan_vertex.end()) {
        fan_vertex.push_back({r, p, uint32_t(part.origin.size())});
        it = fan_vertex.end() - 1;
        part.origin.push_back(uint32_t(v));
        part.top.positions.push_back(top.positions[v]);
        part.top.sample.push_back(top.sample[v]);
      }
      const size_t t = around[a];
      for (size_t e = 0; e < 3; ++e) {
        if (top.tris[3 * t + e] == v) local[3 * t + e] = it->vertex;
      }
    }
    // A bottom triangle at v takes the vertex of its piece's one fan there.
    for (size_t k = 0; k < bottoms.count(v); ++k) {
      const uint32_t b = bottoms.begin(v)[k], p = pieces.bottom[b];
      const FanVertex* found = nullptr;
      for (const FanVertex& fv : fan_vertex) {
        if (fv.piece != p) continue;
        if (found) return {};
        found = &fv;
      }
      if (!found) return {};
      for (size_t e = 0; e < 3; ++e) {
        if (top.bottom[3 * size_t(b) + e] == v) local_bottom[3 * size_t(b) + e] = found->vertex;
      }
    }
  }
  for (size_t t = 0; t < pieces.top.size(); ++t) {
    for (size_t e = 0; e < 3; ++e) out[pieces.top[t]].top.tris.push_back(local[3 * t + e]);
  }
  for (size_t t = 0; t < pieces.bottom.size(); ++t) {
    for (size_t e = 0; e < 3; ++e) {
      out[pieces.bottom[t]].top.bottom.push_back(local_bottom[3 * t + e]);
    }
  }
  return out;
}

/// A decimated solid: shared vertices, faces, and which faces are top ones.
struct Solid {
  std::vector<glm::dvec3> positions;
  std::vector<uint32_t> tris;
  std::vector<uint8_t> top;  // per face

  /// Appends the faces of `m`, its vertex v being positions[to[v]].
  void add_faces(const OMesh& m, OpenMesh::FPropHandleT<bool> is_top,
                 const std::vector<uint32_t>& to) {
    for (auto f : m.faces()) {
      for (auto v : m.fv_range(f)) tris.push_back(to[size_t(v.idx())]);
      top.push_back(uint8_t(m.property(is_top, f)));
    }
  }
  /// Appends all of `m` (vertices unshared).
  void add(const OMesh& m, OpenMesh::FPropHandleT<bool> is_top) {
    std::vector<uint32_t> to(m.n_vertices());
    for (auto v : m.vertices()) to[size_t(v.idx())] = add_point(m.point(v));
    add_faces(m, is_top, to);
  }
  uint32_t add_point(const OMesh::Point& p) {
    positions.emplace_back(p[0], p[1], p[2]);
    return uint32_t(positions.size() - 1);
  }
};

/// The closed solid of a large top, built and decimated in pieces (those of
/// top_pieces, `count` of them) on all cores and joined into `out`
/// (PolygonizeSettings::piece_triangles). The vertices a piece shares with
/// another are locked, so every piece keeps the seam edges as they are and
/// the pieces join into a closed solid. Returns false when the top does not
/// split into pieces that each form a manifold mesh.
bool build_decimated_in_pieces(const TopMesh& top, const Pieces& pieces, size_t count,
                               const PatchField& field, float bottom_offset, double max_error,
                               Solid& out) {
  const std::vector<TopPiece> parts = split_top(top, pieces, count);
  if (parts.empty()) return false;
  std::vector<uint8_t> users(top.positions.size(), 0);
  for (const TopPiece& part : parts) {
    for (uint32_t v : part.origin) users[v] = uint8_t(std::min(users[v] + 1, 2));
  }
  std::vector<OMesh> meshes(parts.size());
  std::vector<OpenMesh::FPropHandleT<bool>> tops(parts.size());
  // Per piece vertex: 2 * top index (+ 1 for a bottom vertex) of a seam
  // vertex, -1 for the others; a property, so it survives the garbage
  // collection.
  std::vector<OpenMesh::VPropHandleT<int64_t>> keys(parts.size());
  std::vector<uint8_t> built(parts.size(), 0);
  parallel_for(parts.size(), [&](size_t p) {
    OMesh& m = meshes[p];
    m.add_property(tops[p]);
    m.add_property(keys[p]);
    SolidVertices solid;
    if (build_solid(parts[p].top, field, bottom_offset, m, tops[p], &solid) > 0) return;
    m.request_vertex_status();
    for (auto v : m.vertices()) m.property(keys[p], v) = -1;
    std::vector<OMesh::VertexHandle> seam;
    for (size_t v = 0; v < solid.top.size(); ++v) {
      const int64_t o = int64_t(parts[p].origin[v]);
      if (users[size_t(o)] < 2) continue;
      m.property(keys[p], solid.top[v]) = 2 * o;
      seam.push_back(solid.top[v]);
      if (solid.bottom[v].is_valid() && solid.bottom[v] != solid.top[v]) {
        m.property(keys[p], solid.bottom[v]) = 2 * o + 1;
        seam.push_back(solid.bottom[v]);
      }
    }
    // The seam vertices and their neighbours stay, so the faces at the seam
    // stay as they are: a collapse next to the seam could join two seam
    // vertices across a third, from both sides, into an edge of four faces.
    for (auto v : seam) {
      m.status(v).set_locked(true);
      for (auto w : m.vv_range(v)) m.status(w).set_locked(true);
    }
    decimate(m, max_error);
    built[p] = 1;
  });
  if (std::count(built.begin(), built.end(), 0) > 0) return false;
  std::unordered_map<int64_t, uint32_t> seam;
  for (size_t p = 0; p < parts.size(); ++p) {
    const OMesh& m = meshes[p];
    std::vector<uint32_t> to(m.n_vertices());
    for (auto v : m.vertices()) {
      const int64_t key = m.property(keys[p], v);
      if (key < 0) {
        to[size_t(v.idx())] = out.add_point(m.point(v));
        continue;
      }
      const auto [it, fresh] = seam.try_emplace(key, 0u);
      if (fresh) it->second = out.add_point(m.point(v));
      to[size_t(v.idx())] = it->second;
    }
    out.add_faces(m, tops[p], to);
  }
  return true;
}

double signed_volume(const TriMesh& m) {
  double v6 = 0.0;
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const glm::dvec3 a = m.positions[m.indices[t]];
    const glm::dvec3 b = m.positions[m.indices[t + 1]];
    const glm::dvec3 c = m.positions[m.indices[t + 2]];
    v6 += glm::dot(a, glm::cross(b, c));
  }
  return v6 / 6.0;
}

/// Copies the faces of `solid` (all, or only top ones) into a TriMesh with
/// area-weighted vertex normals and planar world UVs.
TriMesh to_trimesh(const Solid& solid, bool top_only) {
  TriMesh out;
  std::vector<int64_t> remap(solid.positions.size(), -1);
  for (size_t f = 0; f < solid.top.size(); ++f) {
    if (top_only && !solid.top[f]) continue;
    for (size_t e = 0; e < 3; ++e) {
      const size_t vi = solid.tris[3 * f + e];
      if (remap[vi] < 0) {
        remap[vi] = int64_t(out.positions.size());
        out.positions.emplace_back(solid.positions[vi]);
      }
      out.indices.push_back(uint32_t(remap[vi]));
    }
  }
  std::vector<glm::dvec3> normals(out.positions.size(), glm::dvec3(0.0));
  for (size_t t = 0; t < out.indices.size(); t += 3) {
    const glm::dvec3 a = out.positions[out.indices[t]];
    const glm::dvec3 b = out.positions[out.indices[t + 1]];
    const glm::dvec3 c = out.positions[out.indices[t + 2]];
    const glm::dvec3 n = glm::cross(b - a, c - a);
    for (int e = 0; e < 3; ++e) normals[out.indices[t + e]] += n;
  }
  out.normals.reserve(normals.size());
  out.uvs.reserve(normals.size());
  for (size_t v = 0; v < normals.size(); ++v) {
    const double len = glm::length(normals[v]);
    out.normals.push_back(len > 0.0 ? glm::vec3(normals[v] / len) : glm::vec3(0, 1, 0));
    out.uvs.emplace_back(out.positions[v].x, out.positions[v].z);
  }
  return out;
}

std::string unique_name(const std::string& base, std::set<std::string>& used) {
  std::string name = base;
  for (int k = 2; used.count(name); ++k) name = base + "_" + std::to_string(k);
  used.insert(name);
  return name;
}

// Meshes one patch: its top surface, the closed solid, decimation; nullopt
// when it is degenerate, or too small (its plan area then in *small_area).
// Named after its object in mesh.name, made unique by the caller. Safe to
// run for several patches at once.
std::optional<SnowPatch> mesh_patch(const SnowMaps& maps, const LayerArray<float>& d,
                                    const Scene& scene, const PolygonizeSettings& settings,
                                    float min_thickness, const PatchTexels& texels,
                                    double* small_area) {
  const auto start = std::chrono::steady_clock::now();
  auto lap = start;
  const auto seconds = [&lap] {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - lap).count();
    lap = now;
    return s;
  };
  const float texel = maps.grid.texel;
  SnowPatch patch;
  patch.texels = texels.texels.size();
  // Texels of each object: [o + 1] for object o, [0] for none (or one not in the scene).
  std::vector<size_t> votes(scene.objects.size() + 1, 0);
  std::vector<float> thickness;
  thickness.reserve(texels.texels.size());
  for (size_t k : texels.texels) {
    patch.depth_volume += double(d[k]) * double(texel) * double(texel);
    const int32_t o = maps.object[k];
    ++votes[o >= 0 && size_t(o) < scene.objects.size() ? size_t(o) + 1 : 0];
    thickness.push_back(d[k]);
  }
  size_t best = 0;
  for (size_t v = 0; v < votes.size(); ++v) {
    if (votes[v] > best) {
      best = votes[v];
      patch.object = int(v) - 1;
    }
  }
  const bool named = patch.object >= 0 && size_t(patch.object) < scene.objects.size();
  const std::string base =
      named ? "snow/" + scene.objects[size_t(patch.object)].name : std::string("snow/patch");

  // Error budget: half for the grid-level triangulation, half for the
  // OpenMesh decimation that follows.
  double error =
      settings.decimate_error < 0.0f ? 0.5 * double(texel) : double(settings.decimate_error);
  std::nth_element(thickness.begin(), thickness.begin() + thickness.size() / 2, thickness.end());
  error = std::min(error, 0.25 * double(thickness[thickness.size() / 2]));

  PatchField field = build_field(maps, d, texels);
  smooth_field(field, settings.smooth_iterations, min_thickness);
  const double field_seconds = seconds();
  const double tolerance = error > 0.0 ? 0.5 * error : -1.0;
  // A wide window is triangulated with cuts between strips of columns (16
  // strips or more, each at least kMinCut wide, so the cuts only split a few
  // large triangles), and a top with many triangles is decimated in pieces
  // of whole strips.
  int cut = 0;
  if (error > 0.0 && settings.piece_triangles > 0) {
    for (int c = kMinCut; c * 16 <= field.w; c *= 2) cut = c;
  }
  // The bottom keeps the cut where the top is decimated in pieces (its own
  // bottom there: the courtyard's ground, 4 pieces, solid 0.28 -> 0.17 s;
  // grass at --depth 0.05, 6 pieces, 0.33 -> 0.19 s).
  TopMesh top =
      triangulate_top(field, maps.grid, min_thickness, tolerance, cut, settings.piece_triangles);
  size_t pieces = 1;
  Pieces piece;
  if (top.in_pieces) {
    pieces = (top.tris.size() / 3 + settings.piece_triangles - 1) / settings.piece_triangles;
    piece = top_pieces(top, field, maps.grid, cut, pieces);
  }
  smooth_outline(top, settings.smooth_iterations, texel);
  patch.area = top_plan_area(top);
  if (patch.area < double(settings.min_patch_area)) {
    *small_area = patch.area;
    return std::nullopt;
  }
  const double top_seconds = seconds();

  const float bottom_offset = std::max(settings.bottom_offset, 0.0f);
  Solid solid;
  if (pieces > 1 &&
      !build_decimated_in_pieces(top, piece, pieces, field, bottom_offset, 0.5 * error, solid)) {
    log_debug("polygonize: " + base + " does not split into " + std::to_string(pieces) +
              " manifold pieces; decimating it whole");
    solid = Solid();
    pieces = 1;
  }
  if (pieces == 1) {
    OMesh mesh;
    OpenMesh::FPropHandleT<bool> is_top;
    mesh.add_property(is_top);
    const size_t failed = build_solid(top, field, bottom_offset, mesh, is_top);
    if (failed > 0) {
      log_warn("polygonize: dropping snow patch " + base + ": " + std::to_string(failed) +
               " faces would not form a manifold mesh");
      return std::nullopt;
    }
    if (error > 0.0) decimate(mesh, 0.5 * error);
    solid.add(mesh, is_top);
  }

  const double solid_seconds = seconds();
  const TriMesh closed = to_trimesh(solid, false);
  patch.volume = signed_volume(closed);
  patch.mesh = settings.closed ? closed : to_trimesh(solid, true);
  patch.mesh.name = base;
  patch.mesh.material = 0;
  if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >= 0.05) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "polygonize: %s, %zu texels, %zu top triangles in %zu pieces: field %.3f s, top "
                  "%.3f s, solid %.3f s, mesh %.3f s",
                  base.c_str(), patch.texels, top.tris.size() / 3, pieces, field_seconds,
                  top_seconds, solid_seconds, seconds());
    log_debug(line);
  }
  return patch;
}

}  // namespace

std::vector<SnowPatch> polygonize(const SnowMaps& maps, const std::vector<float>& depth,
                                  const Scene& scene, PolygonizeSettings settings) {
  const size_t n = size_t(std::max(maps.layers, 0)) * maps.grid.texels();
  if (maps.layers < 0 || maps.grid.width < 0 || maps.grid.height < 0 || !(maps.grid.texel > 0.0f) ||
      !std::isfinite(maps.grid.texel)) {
    throw InputError("polygonize: snow maps have an invalid grid (texel " +
                     std::to_string(maps.grid.texel) + " m)");
  }
  if (maps.ground.size() != n || maps.ceiling.size() != n || maps.normal.size() != n ||
      maps.object.size() != n) {
    throw InputError("polygonize: snow maps arrays do not match " + std::to_string(maps.layers) +
                     " layers of " + std::to_string(maps.grid.width) + "x" +
                     std::to_string(maps.grid.height) + " texels");
  }
  if (depth.size() != n) {
    throw InputError("polygonize: snow depth has " + std::to_string(depth.size()) +
                     " values, the maps have " + std::to_string(n) + " layer texels");
  }
  if (maps.grid.texels() >= size_t(std::numeric_limits<uint32_t>::max())) {
    throw InputError(
        "polygonize: maps of 2^32 texels or more are not supported; use a coarser "
        "texel size");
  }
  const float texel = maps.grid.texel;
  const float min_thickness = std::max(settings.min_thickness, 0.0f);
  const float connect = std::clamp(settings.connect_slope, 0.0f, 89.0f);
  const float max_step = texel * std::tan(glm::radians(connect));

  // Clean depth: NaN, negative or surface-less snow is no snow. Written
  // once, on all cores (a zero-filled vector was 50 MB on one core first on
  // the 1M-triangle terrain at 2048).
  const auto t0 = std::chrono::steady_clock::now();
  LayerArray<float> d(n);
  parallel_for_ranges(n, kFieldChunk, [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) {
      const float v = depth[k];
      d[k] = !std::isnan(maps.ground[k]) && std::isfinite(v) && v > 0.0f ? v : 0.0f;
    }
  });

  const std::vector<PatchTexels> found = find_patches(maps, d, min_thickness, max_step);
  char found_line[96];
  std::snprintf(found_line, sizeof found_line, "polygonize: %zu patches found in %.3f s",
                found.size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  log_debug(found_line);
  // Patches are meshed in parallel, largest first (the ground often outweighs
  // the rest), then named and kept in their found order.
  std::vector<size_t> order(found.size());
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return found[a].texels.size() > found[b].texels.size();
  });
  std::vector<std::optional<SnowPatch>> meshed(found.size());
  std::vector<double> small_area(found.size(), -1.0);  // of each patch dropped as too small
  Progress progress("polygonize", double(found.size()));
  std::mutex progress_mutex;
  size_t done = 0;
  parallel_for(order.size(), [&](size_t q) {
    const size_t p = order[q];
    meshed[p] = mesh_patch(maps, d, scene, settings, min_thickness, found[p], &small_area[p]);
    std::lock_guard<std::mutex> lock(progress_mutex);
    progress.update(double(++done));
  });
  // One line for all the small patches (a building's fringe can leave
  // hundreds of single texels).
  size_t small = 0;
  double largest_small = 0.0;
  for (const double area : small_area) {
    if (area < 0.0) continue;
    ++small;
    largest_small = std::max(largest_small, area);
  }
  if (small > 0) {
    char line[160];
    std::snprintf(line, sizeof line,
                  "polygonize: dropped %zu snow patches under the smallest area kept, %.3g m^2 "
                  "(the largest %.3g m^2)",
                  small, double(settings.min_patch_area), largest_small);
    log_debug(line);
  }
  std::vector<SnowPatch> out;
  std::set<std::string> used_names;
  for (std::optional<SnowPatch>& patch : meshed) {
    if (!patch) continue;
    patch->mesh.name = unique_name(patch->mesh.name, used_names);
    out.push_back(std::move(*patch));
  }
  progress.finish();
  return out;
}

}  // namespace snow
