// Winstral's maximum upwind slope (contract: snow/exposure.h).
#include "snow/exposure.h"

#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"

namespace snow {

std::vector<float> upwind_slope(const SnowMaps& maps, const std::vector<float>& depth,
                                const glm::vec2& wind, float max_distance) {
  const float length = glm::length(wind);
  if (!(length > 0.0f) || !std::isfinite(length))
    throw InputError("upwind slope: the wind needs a direction");
  if (!(max_distance > 0.0f) || !std::isfinite(max_distance))
    throw InputError("upwind slope: the search distance must be a finite number > 0 m");
  if (depth.size() != maps.ground.size())
    throw InputError("upwind slope: depth does not match the maps");
  const MapGrid& g = maps.grid;
  const glm::vec2 upwind = -wind / length;
  // The top surface of a column, NaN where it has none.
  const auto top = [&](int i, int j) {
    const size_t k = maps.index(0, i, j);
    const float s = depth[k];
    return maps.ground[k] + (s > 0.0f ? s : 0.0f);
  };
  std::vector<float> out(g.texels(), std::numeric_limits<float>::quiet_NaN());
  parallel_for(size_t(g.height), [&](size_t row) {
    const int j = int(row);
    for (int i = 0; i < g.width; ++i) {
      const float h = top(i, j);
      if (std::isnan(h)) continue;
      const glm::vec2 at = g.center(i, j);
      float best = -std::numeric_limits<float>::infinity();
      for (float d = g.texel; d <= max_distance; d *= kUpwindStep) {
        const glm::vec2 p = at + upwind * d;
        const int pi = int(std::floor((p.x - g.origin.x) / g.texel));
        const int pj = int(std::floor((p.y - g.origin.y) / g.texel));
        if (pi < 0 || pj < 0 || pi >= g.width || pj >= g.height) break;  // the maps end
        const float hu = top(pi, pj);
        if (!std::isnan(hu)) best = std::max(best, std::atan2(hu - h, d));
      }
      if (!std::isfinite(best)) best = 0.0f;  // no surface upwind within reach: level
      out[size_t(j) * size_t(g.width) + size_t(i)] = best * float(180.0 / M_PI);
    }
  });
  return out;
}

}  // namespace snow
