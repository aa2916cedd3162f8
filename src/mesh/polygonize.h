#pragma once
// Polygonize: fallen snow (SnowMaps + per-layer-texel depth) as closed,
// UV-mapped, decimated triangle meshes, one per connected snow patch. The
// steps (patches, fields, top triangulation, solids, decimation) live in
// src/mesh/polygonize/, their overview in polygonize/polygonize.cpp.
#include <cstddef>
#include <vector>

#include "core/trimesh.h"
#include "plan/plan.h"
#include "scene/scene.h"
#include "snow/maps.h"

namespace snow {

/// Cornices: snow blown over the lee edges of roofs and walls grows out over
/// the air there (poly::add_lips).
struct Cornice {
  glm::vec2 direction{1.0f, 0.0f};  // where the wind blew to (x, z), unit length
  float length = 0.0f;              // metres, the farthest reach at an edge facing
                                    // straight downwind (>= 0; 0: none)
};

struct PolygonizeSettings {
  /// Snow thinner than this is no snow (metres). The outline of every patch
  /// is the marching-squares contour of the thickness field at this level.
  float min_thickness = 0.005f;
  /// Decimation error bound (metres). Negative: half a texel. Zero: no
  /// simplification (every texel cell kept). Half of it goes to the adaptive
  /// grid triangulation (vertical error at texel centres), half to OpenMesh's
  /// quadric edge collapses (distance of kept vertices to the planes they
  /// replace). Lowered to a quarter of the patch's median snow depth so
  /// thin snow keeps its volume.
  float decimate_error = -1.0f;
  /// The snow rounds over a shoulder of this radius (metres, >= 0; 0:
  /// square) where it ends at a free edge (a table top's, a wall cap's), as
  /// fresh snow forms a pillow (poly::round_shoulders).
  float shoulder_radius = 0.15f;
  /// With shoulders, the snow bulges past a free edge by up to this much
  /// (metres, >= 0; at most poly::kOverhangShare of its thickness there):
  /// a lip over the air, the closed solid no longer a height field there.
  float overhang = 0.03f;
  /// With shoulders, cornices at the edges facing downwind (set from the
  /// wind by the planner: plan::cornice_length).
  Cornice cornice;
  /// The snow goes on past the border of this rectangle (x, z; empty:
  /// nowhere), as an even cover laid around the maps (mesh/far_ground.h):
  /// free edges there get no shoulder.
  Bounds open_beyond;
  /// Smoothing passes (count) over the snow top (mass-conserving diffusion of
  /// the snow surface height) and over the outline. 0: none.
  int smooth_iterations = 8;
  /// Patches whose top covers less ground than this (square metres, plan
  /// area) are dropped.
  float min_patch_area = 0.01f;
  /// true: closed solids (top, tapered edges, bottom). false: open top
  /// surfaces only, their boundary lying on the supporting surface.
  bool closed = true;
  /// The bottom lies this far (metres, >= 0) under the surface the snow
  /// rests on.
  float bottom_offset = 0.001f;
  /// Snow in neighbouring columns belongs to one patch when
  /// snow::landing_layer links them (either way) and their snow tops differ
  /// by at most texel * tan(connect_slope) (degrees, 0 to 89).
  float connect_slope = 70.0f;
  /// A patch whose top has more triangles than this (count) before
  /// decimation is decimated in pieces of about this many, side by side
  /// along x, on all cores; the seams between pieces keep their full-grid
  /// vertices. 0: never split. Same patch, same pieces on any machine.
  /// Smaller pieces decimate faster and spread over more cores, for a few
  /// per cent more triangles out (--piece-triangles; the default is the
  /// planner's).
  size_t piece_triangles = plan::kPieceTriangles;
};

/// One connected snow patch as a mesh.
struct SnowPatch {
  /// World-space metres, +Y up, counter-clockwise outward faces. Named
  /// "snow/<object name>" (unique among the returned patches); normals (one
  /// per position) and planar UVs in world metres (u = x, v = z) filled;
  /// material 0. Closed 2-manifold when PolygonizeSettings::closed.
  TriMesh mesh;
  int object = -1;            // scene object most of the patch rests on, -1 none
  double volume = 0.0;        // m^3 enclosed by the closed mesh (also for open output)
  double area = 0.0;          // m^2, plan (x, z) area covered by the top surface
  double depth_volume = 0.0;  // m^3, sum of depth * texel^2 over the patch's texels
  size_t texels = 0;          // layer texels in the patch (count)
};

/// Turns the snow lying on `maps` into meshes.
///
/// `depth` holds the snow depth (metres, >= 0) of every layer texel in the
/// maps' layout (maps.layers * maps.grid.texels() entries; otherwise
/// InputError); NaN or negative depths count as no snow, and depth on a
/// texel without a surface is ignored. Texels with more than
/// `min_thickness` of snow are joined into patches across layers by
/// snow::landing_layer (column.h) plus the height step bound of
/// `connect_slope`, so a floor running under a table is one patch; a patch
/// holds at most one layer per column (a second layer of the same column
/// starts another patch). Each patch becomes a mesh: the top at ground +
/// depth over texel centres, the outline from marching squares on the
/// thickness field (snow tapers to zero thickness there), the bottom
/// `bottom_offset` under the ground, decimated within `decimate_error`.
/// `scene` is only read for object names (maps.object indexes
/// scene.objects; out-of-range indices give "snow/patch"). Patches come in a
/// deterministic order (by their first texel in layer, row, column order).
/// Patches under `min_patch_area` are dropped (logged at debug level).
/// Cost: linear in the patches' bounding boxes plus the decimation of what
/// the adaptive triangulation leaves, which dominates on large patches of
/// uneven snow. Reports progress; throws InputError on inconsistent maps.
std::vector<SnowPatch> polygonize(const SnowMaps& maps, const std::vector<float>& depth,
                                  const Scene& scene, PolygonizeSettings settings);

}  // namespace snow
