// Horizons along the wind (contract: snow/exposure.h).
#include "snow/exposure.h"

#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"

namespace snow {

Slabs::Slabs(const MapGrid& grid, const glm::vec2& along) {
  const float ax = std::abs(along.x), az = std::abs(along.y);
  if (!(ax + az > 0.0f) || !std::isfinite(ax + az))
    throw InputError("wind sweep: the direction must be finite and not zero");
  x_main_ = ax >= az;
  reversed_ = x_main_ ? along.x < 0.0f : along.y < 0.0f;
  count = x_main_ ? grid.width : grid.height;
  lanes = x_main_ ? grid.height : grid.width;
  shift = x_main_ ? along.y / ax : along.x / az;
  lane_step = int(std::floor(shift));
  frac = shift - float(lane_step);
  step = grid.texel * std::sqrt(1.0f + shift * shift);
  width = grid.texel / std::sqrt(1.0f + shift * shift);
  grid_width_ = grid.width;
}

size_t Slabs::column(int s, int t) const {
  const int main = reversed_ ? count - 1 - s : s;
  const int i = x_main_ ? main : t, j = x_main_ ? t : main;
  return size_t(j) * size_t(grid_width_) + size_t(i);
}

std::vector<float> top_surface(const SnowMaps& maps, const std::vector<float>& depth) {
  if (depth.size() != maps.ground.size())
    throw InputError("top surface: depth does not match the maps");
  std::vector<float> top(maps.grid.texels());
  parallel_for_ranges(top.size(), 1 << 16, [&](size_t begin, size_t end) {
    for (size_t c = begin; c < end; ++c) top[c] = maps.ground[c] + std::max(depth[c], 0.0f);
  });
  return top;
}

Horizon horizon_along(const MapGrid& grid, const std::vector<float>& top, const glm::vec2& look,
                      float slope) {
  if (top.size() != grid.texels()) throw InputError("horizon: the surface does not match the maps");
  if (!(slope >= 0.0f) || !std::isfinite(slope))
    throw InputError("horizon: the slope must be a finite number >= 0");
  // The sweep runs against `look`: each slab sees the one before it.
  const Slabs slabs(grid, -look);
  constexpr float kNone = -std::numeric_limits<float>::infinity();
  Horizon out;
  out.rise.assign(top.size(), kNone);
  out.height.assign(top.size(), 0.0f);
  // Per lane of the previous slab: the highest of its own surface and the
  // horizon it saw, decayed to it (kNone: nothing), and that surface's
  // height.
  std::vector<float> seen(size_t(slabs.lanes), kNone), seen_z(size_t(slabs.lanes), 0.0f);
  std::vector<float> next(seen.size()), next_z(seen.size());
  const float decay = slope * slabs.step;
  for (int s = 0; s < slabs.count; ++s) {
    for (int t = 0; t < slabs.lanes; ++t) {
      float h = kNone, hz = 0.0f;
      if (s > 0) {
        // The horizon between the two lanes it comes from, linearly; where
        // one of them saw nothing, the other's if it is the nearer.
        const int near = t - slabs.lane_step, far = near - 1;
        const float wn = 1.0f - slabs.frac, wf = slabs.frac;
        const bool has_near = near >= 0 && near < slabs.lanes && seen[size_t(near)] > kNone;
        const bool has_far = far >= 0 && far < slabs.lanes && seen[size_t(far)] > kNone;
        if (has_near && (has_far || !(wf > 0.0f))) {
          h = has_far ? wn * seen[size_t(near)] + wf * seen[size_t(far)] : seen[size_t(near)];
          hz =
              has_far ? wn * seen_z[size_t(near)] + wf * seen_z[size_t(far)] : seen_z[size_t(near)];
        } else if (has_near && wn >= 0.5f) {
          h = seen[size_t(near)];
          hz = seen_z[size_t(near)];
        } else if (has_far && (wf >= 0.5f || !(wn > 0.0f))) {
          h = seen[size_t(far)];
          hz = seen_z[size_t(far)];
        }
        h -= decay;
      }
      const size_t c = slabs.column(s, t);
      const float z = top[c];
      if (std::isnan(z)) {  // no surface: the horizon passes over
        next[size_t(t)] = h;
        next_z[size_t(t)] = hz;
        continue;
      }
      if (h > kNone) {
        out.rise[c] = h - z;
        out.height[c] = hz - z;
      }
      next[size_t(t)] = z >= h ? z : h;
      next_z[size_t(t)] = z >= h ? z : hz;
    }
    seen.swap(next);
    seen_z.swap(next_z);
  }
  return out;
}

}  // namespace snow
