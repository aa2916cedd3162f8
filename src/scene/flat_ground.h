#pragma once
// Small objects on big grounds: a detailed building, car or set piece on a
// ground plane kilometres wide. Maps over the whole ground would make the
// detail texels metres wide; the run instead maps the detail and what lies
// around it, and lays the open ground beyond as an even snow cover.
#include <optional>

#include "scene/scene.h"

namespace snow {

/// A flat, level ground under the rest of the scene.
struct FlatGround {
  int object = -1;  // its object index
  float y = 0.0f;   // m, its height
  Bounds bounds;    // its bounds (y from `y` to `y`)
  Bounds detail;    // the bounds of every other object
};

/// The object of `scene` that is a flat, level ground under the rest: all
/// its triangles level (within a thousandth of its width) at one height, at
/// or below every other object, filling its horizontal bounds (a rectangle,
/// as a plane or a grid of quads), which hold every other object's. The one
/// of largest area where several are. nullopt where there is none, or no
/// other object.
std::optional<FlatGround> find_flat_ground(const Scene& scene);

/// `scene` with the ground's triangles replaced by one rectangle over
/// `region` (x, z; within the ground's bounds) at the ground's height,
/// facing up: the maps then cover the region alone. Other objects, the
/// lines and the motions are kept as they are; bounds recomputed.
Scene with_ground_clipped(const Scene& scene, const FlatGround& ground, const Bounds& region);

}  // namespace snow
