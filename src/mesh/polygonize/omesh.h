#pragma once
// The OpenMesh side of polygonize, private to src/mesh/polygonize/: the mesh
// type that solids are built in and decimated (decimate.cpp), and building
// a solid from a top (solid.cpp).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

// OpenMesh's properties copy default-constructed (uninitialized) vectors,
// which GCC flags inside its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#pragma GCC diagnostic pop

#include "mesh/polygonize/steps.h"

namespace snow::poly {

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
/// call, and the decimation asks it for every candidate collapse; the
/// Decimater calls is_collapse_ok on the mesh type it is instantiated with,
/// so this one, which hides it, is used. Same conditions (Dey et al. 1999,
/// as OpenMesh checks them).
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
  // handles in calls of their own.

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

/// Greedy edge-collapse decimation of `mesh` (Garland and Heckbert 1997,
/// quadric error over the unweighted planes of the original faces) until no
/// collapse keeps every vertex within max_error (metres) of the original
/// planes around it; collapses that turn a face's normal by more than 60
/// degrees, break the topology (Dey et al. 1999) or move locked vertices
/// are not made. Deleted elements are removed.
void decimate(OMesh& mesh, double max_error);

/// The mesh vertices build_solid made for each top vertex: its top vertex
/// and its bottom one (the same for an outline vertex).
struct SolidVertices {
  std::vector<OMesh::VertexHandle> top, bottom;
};

/// Builds the closed solid of `top` into `mesh` (an open one for a piece of
/// a top), the bottom bottom_offset (metres) under the ground of `f`; marks
/// top faces in is_top. Returns the number of faces that would not form a
/// manifold mesh and were left out (0: all built).
size_t build_solid(const TopMesh& top, const PatchField& f, float bottom_offset, OMesh& mesh,
                   OpenMesh::FPropHandleT<bool> is_top, SolidVertices* vertices = nullptr);

/// Appends the faces of `m` to `solid`, m's vertex v being
/// solid.positions[to[v]].
void add_faces(Solid& solid, const OMesh& m, OpenMesh::FPropHandleT<bool> is_top,
               const std::vector<uint32_t>& to);

/// Appends point p to solid.positions; returns its index.
uint32_t add_point(Solid& solid, const OMesh::Point& p);

}  // namespace snow::poly
