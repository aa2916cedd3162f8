#pragma once
// CPU reference of the depth-peeling pass (snow/peel.h): the tests check the
// GPU pass against it, and "auto" peels with it where that is faster
// (snow::peels_on_cpu).
#include "scene/scene.h"
#include "snow/maps.h"

namespace snow::reference {

/// A vertical ray at (px, pz) against triangle (a, b, c), whose xz
/// projection has the doubled signed area `area` (non-zero): the edge
/// functions, which are barycentric weights times area.
struct ColumnWeights {
  double wa, wb, wc;

  /// The doubled signed area of the triangle's xz projection (0: seen
  /// edge-on from above).
  static double area(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    return (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
  }

  ColumnWeights(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, double px, double pz)
      : wa((b.x - px) * (c.z - pz) - (c.x - px) * (b.z - pz)),
        wb((c.x - px) * (a.z - pz) - (a.x - px) * (c.z - pz)),
        wc((a.x - px) * (b.z - pz) - (b.x - px) * (a.z - pz)) {}
  /// Whether the ray crosses the triangle (its edges count).
  bool inside(double area) const {
    return area > 0 ? (wa >= 0 && wb >= 0 && wc >= 0) : (wa <= 0 && wb <= 0 && wc <= 0);
  }
  /// The height of the triangle's plane on the ray.
  double height(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, double area) const {
    return (wa * a.y + wb * b.y + wc * c.y) / area;
  }
};

/// Shoots a vertical ray through every texel centre of `grid` and collects
/// every triangle it crosses (either winding; triangles seen edge-on are
/// missed, as by a rasterizer). Hits are ordered from the top down (ties by
/// triangle index); a hit less than merge_distance (metres) below the
/// current layer's surface merges into it. Keeps up to `layers` layers with
/// the same fields and rules as snow::peel_layers (ground, ceiling, unit
/// geometric normal as wound, object index; trailing empty layers dropped)
/// and counts overflow columns.
/// Exact up to ties on triangle edges, which the GPU resolves by its fill
/// rule. Runs on all cores, in bands of rows; the maps are the same on any
/// number. Throws InputError for layers outside 1..64 or an empty grid.
SnowMaps peel_layers(const Scene& scene, const MapGrid& grid, int layers,
                     float merge_distance = 1e-3f);

}  // namespace snow::reference
