#pragma once
// Snow bridges (Fearing 2000, section 6: cohesive snow spans small gaps):
// fresh snow spans gaps narrower than a few centimetres (bench slats, grates,
// the crack between two roofs) instead of falling through them. On the
// maps, a column that lies in such a gap gets a surface across it, at the
// height of the gap's rims: it receives the snow that falls into the gap,
// and the columns under it receive none (mask_coverage, snow/coverage.h).
#include <cstddef>

#include "snow/maps.h"

namespace snow {

/// The gaps bridge_gaps spans have rims whose heights differ by at most
/// this many metres per metre across (45 degrees).
constexpr float kBridgeMaxSlope = 1.0f;

/// Gaps wider than this many texels are not bridged (on maps whose texels
/// are this much finer than the bridge width).
constexpr int kBridgeMaxTexels = 64;

/// Adds a bridge surface to every column of `maps` that lies in a gap at
/// most `width` metres wide (> 0; 0: none) along x, z or a diagonal, between
/// two up-facing surfaces (the rims) that stand more than half a texel above
/// a surface of the column, inside that surface's gap (below its ceiling),
/// with heights within kBridgeMaxSlope of each other. The bridge lies at the
/// rims' heights interpolated across the gap, faces up, belongs to the
/// nearer rim's object, and is inserted into the column's layers by height
/// (a layer is added to the maps where the column has no room; a column of
/// 64 layers is not bridged). maps.bridge records it. Returns the columns
/// bridged. Rims and gaps are found on the maps as they were on entry.
size_t bridge_gaps(SnowMaps& maps, float width);

}  // namespace snow
