#pragma once
// The snow on the open ground beyond the maps (scene/flat_ground.h,
// plan::detail_margin): an even cover, as a closed mesh with a hole where
// the maps' snow lies.
#include <string>

#include "mesh/polygonize.h"
#include "scene/flat_ground.h"

namespace snow {

/// How much lower (m) the far cover lies than the maps' snow where they
/// overlap: no two surfaces on one plane (z-fighting), too little to see.
constexpr float kFarGroundSeam = 1e-3f;

/// `depth` metres of snow (> 0) on the ground's rectangle outside `region`
/// (x, z; inside the ground's bounds by more than `overlap` on every side),
/// reaching `overlap` metres (>= 0) into the region, under the tapered
/// border of the maps' snow there, and lying `seam` metres (>= 0) lower so
/// that the two never draw on one plane. A closed 2-manifold box with a
/// rectangular hole (world metres, +Y up, counter-clockwise outward faces,
/// normals and planar UVs in metres), its bottom `bottom_offset` under the
/// ground, named `name`, on the ground's object.
SnowPatch far_ground_snow(const FlatGround& ground, const Bounds& region, float depth,
                          float overlap, float seam, float bottom_offset, const std::string& name);

}  // namespace snow
