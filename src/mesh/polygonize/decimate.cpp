// Edge-collapse decimation of polygonize's solids with OpenMesh's
// Decimater framework: the priority and bound are the quadric error of
// Garland and Heckbert (SIGGRAPH 1997) over unweighted planes, i.e. a sum of
// squared distances in metres; the topology test is Dey et al. (1999) as
// OpenMesh checks it.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

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

#include "mesh/polygonize/omesh.h"

namespace snow::poly {
namespace {

/// Decimation priority and bound: the quadric error of Garland and Heckbert
/// over the planes of the original faces, each with weight one (OpenMesh's
/// ModQuadricT weights them by area, which makes the bound unitless). The
/// error of a collapse is the sum of squared distances (m^2) of the kept
/// vertex to every plane merged into it, so a bound err^2 keeps every vertex
/// within err metres of each original plane around it. A collapse within the
/// bound must also not turn a face's normal by more than
/// set_max_normal_deviation: the test of OpenMesh's ModNormalFlippingT, here
/// rather than a module of its own, so that it runs only after the cheap
/// error bound (the same meshes either way). Decimater below asks
/// bounded_error() and flips_normal() itself.
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

/// Degrees a collapse may turn a face's normal at most: small enough that
/// the decimation keeps rounded shoulders and mounds round (within the error
/// bound alone, a gently curved strip collapses into long flat triangles
/// with a crease along them).
constexpr double kMaxNormalDeviationDeg = 15.0;

/// Greedy decimation with ModPlaneErrorT as OpenMesh's DecimaterT::decimate
/// runs it (each vertex in a heap keyed by its best collapse; after a
/// collapse, the vertices around it are keyed again), with the tests of a
/// candidate collapse in the order of their cost: the error bound (one
/// quadric) first, then OpenMesh's topology test (both one-rings), then the
/// normal test. DecimaterT asks the topology first, though most candidates
/// fail the bound (for the same reason the bound looks at the error before
/// the valences). Both keep the same candidates and pick the same best one,
/// so the meshes are the same.
class Decimater : public OpenMesh::Decimater::BaseDecimaterT<OMesh> {
 public:
  using Base = OpenMesh::Decimater::BaseDecimaterT<OMesh>;
  using PlaneError = ModPlaneErrorT<OMesh>;

  Decimater(OMesh& mesh, double max_error) : Base(mesh), mesh_(mesh) {
    add(module_);
    module(module_).set_max_err(max_error * max_error);
    module(module_).set_max_normal_deviation(kMaxNormalDeviationDeg);
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

}  // namespace

void decimate(OMesh& mesh, double max_error) {
  mesh.request_vertex_status();
  mesh.request_edge_status();
  mesh.request_face_status();
  mesh.request_face_normals();
  for (auto f : mesh.faces()) mesh.set_normal(f, mesh.face_normal(f));
  Decimater(mesh, max_error).decimate();
  mesh.garbage_collection();
}

}  // namespace snow::poly
