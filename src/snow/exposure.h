#pragma once
// Exposure to the wind: Winstral, Elder and Davis (2002)'s maximum upwind
// slope Sx, the first measure the wind transport (issue 51) builds on. A
// column whose snow surface lies below the horizon that the surface upwind
// makes (Sx > 0) is sheltered, where drifting snow settles (the lee of a
// wall, behind a ridge); one that looks down on everything upwind (Sx < 0) is
// exposed, where the wind scours.
#include <vector>

#include <glm/glm.hpp>

#include "snow/maps.h"

namespace snow {

/// Distances (along the wind, metres) at which upwind_slope samples the
/// surface: from one texel, each kUpwindStep times the last, up to the
/// search distance.
constexpr float kUpwindStep = 1.25f;

/// Per column (j * width + i), Sx in degrees: the largest angle above the
/// horizontal at which the snow surface (the top layer's ground + depth) is
/// seen from the column's own surface, looking upwind (against `wind`, any
/// length > 0) out to `max_distance` metres (> 0), at distances from one
/// texel growing by kUpwindStep, as far as the maps reach (columns without a
/// surface are skipped; 0 where none is sampled). NaN where the column has
/// no surface. `depth` in
/// the maps' layout (metres; NaN or negative counts as none).
std::vector<float> upwind_slope(const SnowMaps& maps, const std::vector<float>& depth,
                                const glm::vec2& wind, float max_distance);

}  // namespace snow
