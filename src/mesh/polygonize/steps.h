#pragma once
// The steps of polygonize (mesh/polygonize.h), private to src/mesh/polygonize/:
// the data each step hands to the next and the step functions. OpenMesh
// stays out of this header (see omesh.h).
//
//   patches.cpp     find_patches: snowy layer texels into PatchTexels, one
//                   per patch
//   fields.cpp      build_field, smooth_field: a patch's PatchField
//                   (thickness and ground on texel centres)
//   top.cpp         triangulate_top, smooth_outline: the TopMesh (top
//                   surface, outline, the bottom's own triangles)
//   solid.cpp       build_decimated_solid: the closed, decimated Solid;
//                   to_trimesh: the Solid as a TriMesh
//   pieces.cpp      build_decimated_in_pieces: the same for a large top, in
//                   pieces on all cores
//   decimate.cpp    OpenMesh's edge-collapse decimation (omesh.h)
//   polygonize.cpp  polygonize(): the driver, patches meshed in parallel
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/parallel.h"
#include "core/trimesh.h"
#include "mesh/polygonize.h"
#include "scene/scene.h"
#include "snow/maps.h"

namespace snow::poly {

/// PatchField::drop_edge: the free edge drops onto a lower surface, or off
/// the scene (no surface below).
constexpr uint8_t kDropToSurface = 1;
constexpr uint8_t kDropToVoid = 2;

// ---------------------------------------------------------------------------
// Patches (patches.cpp)

/// Layer texels of one patch (indices into the maps' per-layer arrays).
struct PatchTexels {
  LayerArray<size_t> texels;  // (resized unwritten, then filled on all cores)
};

/// Layer l, column i (along +x) and row j (along +z) of a layer texel.
struct TexelCoord {
  int l, i, j;
};

inline TexelCoord coord_of(const SnowMaps& maps, size_t k) {
  const size_t per_layer = maps.grid.texels();
  const size_t rem = k % per_layer;
  return {int(k / per_layer), int(rem % size_t(maps.grid.width)),
          int(rem / size_t(maps.grid.width))};
}

/// coord_of for many texels: each is found from the last where they share a
/// row, as a patch's texels mostly do, so most take no division.
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

/// Connected components of snowy texels (depth > min_thickness, metres):
/// neighbours join by snow::landing_layer either way with snow tops at most
/// max_step (metres) apart, at most one layer per column and patch; see
/// polygonize()'s contract. Patches come in the order of their first texel
/// (layer, row, column).
std::vector<PatchTexels> find_patches(const SnowMaps& maps, const LayerArray<float>& depth,
                                      float min_thickness, float max_step);

// ---------------------------------------------------------------------------
// Per-patch fields on texel centres (fields.cpp)

/// The patch's window: its bounding box of columns plus one sample of margin
/// on every side, so every cell touching a patch sample exists.
struct PatchField {
  int i0 = 0, j0 = 0;  // map column of window sample (0, 0)
  int w = 0, h = 0;    // window size in samples
  // (resized unwritten, then filled on all cores)
  LayerArray<uint8_t> member;
  LayerArray<float> s;             // snow thickness, m (0 outside the patch)
  LayerArray<float> g;             // ground height, m (extrapolated outside; NaN far away)
  LayerArray<float> gx, gz;        // ground slope dy/dx, dy/dz (members)
  std::vector<uint8_t> shoulder;   // 1 on the members round_shoulders shaped (empty: none)
  std::vector<uint8_t> drop_edge;  // on the members at a free edge (a drop): kDropToSurface or
                                   // kDropToVoid, else 0 (empty: none)

  size_t at(int wi, int wj) const { return size_t(wj) * size_t(w) + size_t(wi); }
};

/// Texels per task of the parallel loops over a patch's texels (and of
/// polygonize's depth cleaning).
constexpr size_t kFieldChunk = 1 << 14;
/// Patches are meshed on all cores already: a loop inside one (build_field,
/// smooth_field, the top's error pass) starts threads of its own only from
/// this many samples on, where the work outweighs starting them.
constexpr size_t kParallelSamples = 1 << 16;
/// parallel_for's thread count for a loop over `samples` samples of a patch.
inline unsigned threads_for(size_t samples) { return samples >= kParallelSamples ? 0u : 1u; }

/// Calls fn(wi, wj, sample) for every window sample of f, rows on `threads`
/// threads (parallel_for's count).
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

/// Rounds the snow over a shoulder of `radius` metres (> 0) along the
/// patch's free edges: where a member's 4-neighbour column is not in the
/// patch and the snow would drop there (into the void, or onto a top lower by
/// more than half the member's depth: a table's or a wall cap's edge, not a
/// wall). At distance x (m) from such an edge the thickness s becomes
/// s - r + sqrt(r^2 - (r - x)^2) with r = min(radius, s), for x < r: the snow
/// stands vertical for s - r and rounds over a quarter circle, a pillow's
/// shoulder. x is measured from the outline rounded by r in plan (convex
/// corners round off; members beyond it keep no snow): the shoulder's width
/// less the Euclidean distance over members to the core, the members at
/// least that far from every free edge, with the outline about a texel
/// beyond the edge members' centres. Marks them in f.shoulder: the smoothing
/// leaves them as shaped.
/// Neighbour columns whose centre lies outside `open_beyond` (x, z; empty:
/// none) are not drops: the snow goes on there.
void round_shoulders(PatchField& f, const SnowMaps& maps, const LayerArray<float>& depth,
                     const PatchTexels& patch, float radius, const Bounds& open_beyond);

/// The patch's window with thickness `depth` and the maps' ground on its
/// texels, the ground slope there, and the ground extrapolated one sample out.
PatchField build_field(const SnowMaps& maps, const LayerArray<float>& depth,
                       const PatchTexels& patch);

/// Mass-conserving smoothing of the snow surface g + s (`iterations` passes):
/// explicit diffusion between 4-neighbour members, each flux limited so no
/// member falls under min_thickness (metres). Same result on any number of
/// threads.
void smooth_field(PatchField& f, int iterations, float min_thickness);

// ---------------------------------------------------------------------------
// Top surface (top.cpp)

struct TopMesh {
  std::vector<glm::dvec3> positions;
  std::vector<int32_t> sample;  // window sample of a member vertex, -1 for outline vertices
  std::vector<uint32_t> tris;   // counter-clockwise seen from above (+Y normals)
  // The bottom's triangles, wound as tris, where it has its own (empty:
  // the top's); over the top's vertices, with the same outline.
  std::vector<uint32_t> bottom;
  bool in_pieces = false;  // to be decimated in pieces (triangulate_top)
};

/// Twice the signed area in the (z, x) plane: positive when the triangle's
/// normal points up (+Y) in a right-handed frame.
inline double plan_area2(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  return (b.z - a.z) * (c.x - a.x) - (b.x - a.x) * (c.z - a.z);
}

/// The top surface: vertices at patch samples (height g + s) and on the
/// outline, the marching-squares contour of s at min_thickness (height g).
/// Inside the outline, a right-triangulated irregular network keeps a
/// triangle whole while top and ground stay within `tolerance` (metres) of
/// every sample it covers. tolerance < 0: every cell at full resolution.
/// cut (a power of two >= 2, or 0): no triangle crosses a window sample
/// column k * cut, so the top splits into strips of columns along edges (see
/// top_pieces).
/// With tolerance >= 0 the bottom is triangulated on its own
/// (TopMesh::bottom), within the tolerance of the ground alone: the same
/// network, split only where the ground needs it, so a coarsening of the
/// top's with the same outline cells. On flat ground it is a few large
/// triangles and the outline's ring, which the decimation then need not
/// collapse. A top cut into strips with more than piece_triangles triangles
/// is to be decimated in pieces (TopMesh::in_pieces), and its bottom keeps
/// the cut.
TopMesh triangulate_top(const PatchField& f, const MapGrid& grid, float min_thickness,
                        double tolerance, int cut = 0, size_t piece_triangles = SIZE_MAX);

/// Laplacian smoothing of the outline polylines (x, y, z of outline vertices
/// move halfway to the mean of their two outline neighbours); a move that
/// would fold a triangle in plan is skipped.
void smooth_outline(TopMesh& top, int iterations, double texel);

/// The plan (x, z) area of the top's triangles, m^2.
double top_plan_area(const TopMesh& top);

// ---------------------------------------------------------------------------
// Solids and decimation (solid.cpp, pieces.cpp, decimate.cpp)

/// A decimated solid: shared vertices, faces, and which faces are top ones.
struct Solid {
  std::vector<glm::dvec3> positions;
  std::vector<uint32_t> tris;
  std::vector<uint8_t> top;  // per face
};

/// The closed solid of `top` (an open one when it does not close) into
/// `out`: the top, the bottom bottom_offset (metres) under the ground,
/// sharing the outline vertices, then decimated within max_error (metres;
/// <= 0: not decimated). Returns the number of faces that would not form a
/// manifold mesh; when it is not 0, `out` is left as it was.
size_t build_decimated_solid(const TopMesh& top, const PatchField& field, float bottom_offset,
                             double max_error, Solid& out);

/// The snow bulges past its free edges, as cohesive snow does (Fearing
/// 2000): every outline vertex of `solid` within a sample of a free-edge
/// member (f.drop_edge) splits in two, the bottom's staying where it is and
/// the top's moving out (away from the top, horizontally) by
/// min(overhang, kOverhangShare * thickness nearby) and up by half that;
/// at lee edges over a lower surface (not off the scene's end; outward
/// direction d, d . cornice.direction > 0) a
/// cornice reaches out further, up to cornice.length * (d . direction)
/// and kCorniceShare * thickness, level with the lip; a
/// band of faces joins the two outlines, the lip's underside. The solid stays
/// a closed 2-manifold; there it is no longer a height field. `texel`,
/// `origin`: the maps' grid (metres).
void add_lips(Solid& solid, const PatchField& f, float texel, const glm::vec2& origin,
              float overhang, const Cornice& cornice);
/// The lip reaches out at most this share of the snow's thickness.
constexpr float kOverhangShare = 0.25f;
/// A cornice reaches out at most this share of the snow's thickness.
constexpr float kCorniceShare = 1.5f;

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
                  size_t& pieces);

/// The closed solid of a large top, built and decimated in pieces (those of
/// top_pieces, `count` of them) on all cores and joined into `out`
/// (PolygonizeSettings::piece_triangles). The vertices a piece shares with
/// another are locked, so every piece keeps the seam edges as they are and
/// the pieces join into a closed solid. Returns false when the top does not
/// split into pieces that each form a manifold mesh.
bool build_decimated_in_pieces(const TopMesh& top, const Pieces& pieces, size_t count,
                               const PatchField& field, float bottom_offset, double max_error,
                               Solid& out);

/// Signed volume enclosed by the triangles of m (m^3; positive for a closed
/// mesh with outward faces).
double signed_volume(const TriMesh& m);

/// Whether the face (a, b, c) is degenerate as glTF readers (snowmodel's
/// loader, Blender's importer) take it once its corners are rounded to
/// float: its height is under kDegenerateHeight of its longest edge.
constexpr double kDegenerateHeight = 1e-7;
bool degenerate_face(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c);

/// Flips the longest edge of each degenerate face (a sliver whose corners
/// lie on a line) with the face across it, so no reader drops a face and
/// opens the closed solid; faces whose flip would make an edge twice stay.
/// Returns the degenerate faces left.
size_t flip_degenerate_faces(Solid& solid);

/// Copies the faces of `solid` (all, or only top ones) into a TriMesh with
/// area-weighted vertex normals and planar world UVs (u = x, v = z).
TriMesh to_trimesh(const Solid& solid, bool top_only);

}  // namespace snow::poly
