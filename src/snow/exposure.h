#pragma once
// Exposure to the wind, the measure the wind transport (snow/drift.h) reads
// the scene with. Winstral, Elder and Davis (2002) call a point sheltered
// where its maximum upwind slope Sx (the steepest angle at which it sees the
// surface upwind) is large. A fixed horizon angle turns that into one sweep
// over the maps instead of a search per column: the point is sheltered where
// some surface upwind rises above the line falling from the point upwind at
// `slope` (tan of the angle), i.e. where Sx > atan(slope), and the rise
// above that line (metres) says how deep in the shelter it lies. With slope
// 0.5 a step of height h shelters 2h downwind, EN 1991-1-3's drift length
// at a step (section 5.3.6). The same sweep looking downwind finds the
// windward faces of obstacles, and across the wind their sides.
#include <array>
#include <cstddef>
#include <vector>

#include <glm/glm.hpp>

#include "snow/maps.h"

namespace snow {

/// The map's columns as slabs across a direction `along` (x, z; any
/// nonzero length): slab s = 0, 1, ... in the order `along` points, lanes t
/// across it. One slab further moves one texel along the main axis (x where
/// |along.x| >= |along.y|, else z) and `shift` lanes across (|shift| <= 1).
/// A column (s, t) draws from the previous slab's lanes t - a (weight
/// 1 - f) and t - a - 1 (weight f), a = floor(shift), f = shift - a: a
/// semi-Lagrangian step whose weights each source also splits its own
/// value by, so what moves along the slabs is conserved.
struct Slabs {
  Slabs(const MapGrid& grid, const glm::vec2& along);
  int count = 0;       // slabs
  int lanes = 0;       // columns per slab
  float shift = 0.0f;  // lanes across per slab
  int lane_step = 0;   // a = floor(shift)
  float frac = 0.0f;   // f = shift - a
  float step = 0.0f;   // metres travelled along `along` per slab
  float width = 0.0f;  // metres across `along` per lane
  /// The column (j * width + i) of slab s, lane t (both in range).
  size_t column(int s, int t) const;
  /// A lane and its weight in a step between slabs (the lane may lie
  /// outside 0..lanes - 1; the weight may be 0).
  struct Link {
    int lane;
    float weight;
  };
  /// The lanes of the slab before that lane t draws from.
  std::array<Link, 2> sources(int t) const {
    return {{{t - lane_step, 1.0f - frac}, {t - lane_step - 1, frac}}};
  }
  /// The lanes of the slab after that lane t sends to.
  std::array<Link, 2> targets(int t) const {
    return {{{t + lane_step, 1.0f - frac}, {t + lane_step + 1, frac}}};
  }

 private:
  bool x_main_ = true;
  bool reversed_ = false;  // slabs run from the high index down
  int grid_width_ = 0;
};

/// Per column (j * width + i): the surface a sweep sees from there.
struct Horizon {
  /// Metres: the largest (z(p) - slope * d) - z(c) over the surfaces p at
  /// distance d > 0 in direction `look` from column c, z the top surface;
  /// -infinity where no surface lies that way (or c has none). > 0: c lies
  /// below the line at slope from some surface there, in its shelter.
  std::vector<float> rise;
  /// Metres: z(p) - z(c) of the surface p that gives rise (0 with none).
  std::vector<float> height;
};

/// The horizon of every column looking along `look` (x, z; nonzero) with
/// the decay `slope` (>= 0) over `top` (the top surface height per column,
/// metres; NaN where the column has no surface: the sweep passes over it).
/// Exact along the axes and the diagonals; between them the horizon is
/// interpolated between the two nearest lanes of the slab before, so it
/// blurs across the wind with distance. Throws InputError for a zero
/// direction, a bad slope or a size mismatch.
Horizon horizon_along(const MapGrid& grid, const std::vector<float>& top, const glm::vec2& look,
                      float slope);

/// The top surface of every column (j * width + i): layer 0's ground plus
/// its depth (`depth` in the maps' layout, metres; negative counts as 0),
/// NaN where it has no surface.
std::vector<float> top_surface(const SnowMaps& maps, const std::vector<float>& depth);

}  // namespace snow
