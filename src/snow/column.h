#pragma once
// The one rule that relates snow in neighbouring columns, shared by the
// stabilizer (CPU reference and GPU, mirrored in shaders/column.glsl) and by
// patch finding in polygonize: neighbours are found by height, not by layer
// index, as a surface continuous in the world (a floor running under a
// table) can be layer 0 in one column and layer 2 in the next (height spans
// after Onoue and Nishita).
//
// A column (i, j) holds up to L surfaces from the top down. Layer l's gap is
// the free space from its surface (ground) up to its ceiling (the surface
// above, ceiling[l] = ground[l-1]). Snow at height h coming from a
// neighbouring column comes to rest in this column on the highest layer whose
// snow top (ground + depth) lies at or below h and whose gap contains h.
//
// Solid gaps: crossing a surface from above enters a solid through its top
// (up-facing) or leaves one through its bottom (down-facing). So the gap of
// layer l is the inside of a closed solid when layer l faces down (a solid's
// bottom, the solid above it) or layer l-1 faces up (a solid's top, the solid
// below it). Either is enough: where two solids touch, or a box stands on
// the floor, the peel merges the coincident surfaces into one layer keeping
// one normal, and only the other side of the contact still tells. Snow never
// lands in a solid gap: at those heights the column is a wall. The price of
// "either": under a one-sided (open) canopy or a flipped-normal object the
// gap counts as solid too, so snow does not slump in under it; it never
// leaks into a closed thing. Coverage keeps falling snow out of closed things.
//
// Continuity: a thin one-sided surface (a roof plane without thickness) has
// no solid gap under it, and snow lying thinly on it would otherwise slip
// into the open gap under the same roof in the uphill column. A gap whose
// ceiling lies less than kSurfaceContinuityTexels texels above the support
// of the moving snow is under the continuation of that support and closed.
#include <cmath>
#include <cstddef>

#include "snow/maps.h"

namespace snow {

/// landing() results other than a layer index.
constexpr int kLandBlocked = -1;  // a wall (a solid, or snow lying higher) is in the way at h
constexpr int kLandVoid = -2;     // nothing below h in that column (empty, off the map, or
                                  // under a floating thing): snow going there leaves the scene

/// A surface rising less than this many texels of height per texel between
/// neighbouring columns is taken for one continuous surface (about 80
/// degrees; the same cut as coverage's snow surface, kSnowSurfaceCutTexels).
constexpr float kSurfaceContinuityTexels = 6.0f;

/// True when the gap of layer l of column (i, j) is the inside of a closed
/// solid: layer l faces down (normal.y < 0) or layer l-1 faces up
/// (normal.y > 0). Layer 0 (under open sky) is never solid. Needs a surface
/// on layer l.
inline bool gap_is_solid(const SnowMaps& maps, int l, int i, int j) {
  if (l <= 0) return false;
  return maps.normal[maps.index(l, i, j)].y < 0.0f || maps.normal[maps.index(l - 1, i, j)].y > 0.0f;
}

/// The landing rule over any column accessor `col` with has(l), ground(l),
/// ceiling(l), top(l) (= ground + snow depth), solid(l) and faces_down(l)
/// (normal.y < 0), for `layers`
/// layers packed from the top. Snow at height h comes from a neighbouring
/// column where it rests on a support at height `support`; a gap whose
/// ceiling lies less than `rise` (metres) above that support is closed to it:
/// the ceiling is then the continuation of the snow's own support (a thin,
/// one-sided roof), which the snow would have to pass through. Returns the
/// layer, kLandBlocked or kLandVoid. This is the loop that
/// shaders/column.glsl mirrors line by line.
template <class Column>
inline int land_in_column(const Column& col, int layers, float h, float support, float rise) {
  for (int l = 0; l < layers; ++l) {
    // Below the lowest surface: open void under a down-facing one (the
    // bottom of a floating thing); under an up-facing one, the ground's
    // inside (terrain, a one-sided floor): a wall.
    if (!col.has(l)) return l > 0 && !col.faces_down(l - 1) ? kLandBlocked : kLandVoid;
    if (h >= col.ceiling(l)) return kLandBlocked;  // inside the solid or snow above
    if (col.top(l) <= h) {
      if (col.solid(l) || col.ceiling(l) - support < rise) return kLandBlocked;
      return l;
    }
    if (h >= col.ground(l)) return kLandBlocked;  // inside the snow lying on this layer
  }
  // h is below the snow top of all L layers: the column may hold surfaces
  // that were not peeled (overflow), so snow does not go there.
  return kLandBlocked;
}

/// Where snow at height h (world y, m) arriving from a neighbour, where it
/// rests on a support at height `support` (m; -inf: no continuity check),
/// comes to rest in column (i, j): a layer index, kLandBlocked, or kLandVoid
/// (also for (i, j) off the map). `depth` has the maps' layer layout
/// (metres; null means no snow anywhere).
inline int landing(const SnowMaps& maps, const float* depth, int i, int j, float h,
                   float support = -kOpenSky) {
  if (i < 0 || j < 0 || i >= maps.grid.width || j >= maps.grid.height) return kLandVoid;
  struct MapsColumn {
    const SnowMaps& maps;
    const float* depth;
    int i, j;
    size_t k(int l) const { return maps.index(l, i, j); }
    bool has(int l) const { return !std::isnan(maps.ground[k(l)]); }
    float ground(int l) const { return maps.ground[k(l)]; }
    float ceiling(int l) const { return maps.ceiling[k(l)]; }
    float top(int l) const { return maps.ground[k(l)] + (depth ? depth[k(l)] : 0.0f); }
    bool solid(int l) const { return gap_is_solid(maps, l, i, j); }
    bool faces_down(int l) const { return maps.normal[k(l)].y < 0.0f; }
  };
  return land_in_column(MapsColumn{maps, depth, i, j}, maps.layers, h, support,
                        kSurfaceContinuityTexels * maps.grid.texel);
}

/// The layer of column (i, j) onto which snow at height h (world y, m) coming
/// from a neighbour comes to rest: the highest layer whose snow top
/// (ground + depth) lies at or below h and whose free gap (up to its ceiling,
/// not the inside of a solid) contains h. Returns -1 when there is none (a
/// wall is in the way, the column is empty or off the map). `depth` has the
/// maps' layer layout. With `support` (the ground under the snow that moves)
/// gaps under the continuation of that support are closed (see
/// land_in_column); the default -inf skips that check.
inline int landing_layer(const SnowMaps& maps, const float* depth, int i, int j, float h,
                         float support = -kOpenSky) {
  const int l = landing(maps, depth, i, j, h, support);
  return l >= 0 ? l : -1;
}

}  // namespace snow
