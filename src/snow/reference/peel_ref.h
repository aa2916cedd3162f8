#pragma once
// CPU reference of the depth-peeling pass (snow/peel.h): the tests check the
// GPU pass against it, and "auto" peels with it where that is faster
// (snow::peels_on_cpu).
#include "scene/scene.h"
#include "snow/maps.h"

namespace snow::reference {

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
