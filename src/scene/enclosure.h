#pragma once
// Sky enclosures: a sky dome, a sky box or an inverted sphere that a DCC
// tool exported with the scene. Seen from above it covers everything, so
// it would take all the snow and shelter the scene from all of it. They are
// found by their shape alone (not their names), so that the run can leave
// them out and say so.
#include <vector>

#include "scene/scene.h"

namespace snow {

/// The objects of `scene` that enclose the rest from above, outermost first:
/// an object whose horizontal bounds hold those of every other object left
/// (within a thousandth of their size), whose top is above theirs, and whose
/// triangles cover at least `min_cover` (0..1) of their horizontal
/// footprint from above, above their highest point (a dome, a box around
/// them, an inverted sphere; a ground under them does not cover them from
/// above). Once one is found, the search goes on without it (a box inside a
/// dome). Never returns every object. Deterministic; cost linear in the
/// candidates' triangles.
std::vector<int> find_sky_enclosures(const Scene& scene, double min_cover);

}  // namespace snow
