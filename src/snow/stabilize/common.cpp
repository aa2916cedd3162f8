// What both stabilizers share (the stage's contract: snow/stabilize.h): the
// settings' checks, the per-texel cells and their repose jitter, the stride
// schedule, when to drain and when to pour pressed snow, and the snow volume.
// CPU only.
#include "snow/stabilize.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "core/parallel.h"
#include "snow/column.h"

namespace snow {

void check_stabilize_settings(const StabilizeSettings& s) {
  auto bad = [](const std::string& what) { throw InputError("stabilize: " + what); };
  if (!(s.repose_deg >= 5.0f && s.repose_deg <= 85.0f)) {
    bad("repose_deg must be in 5..85 degrees, got " + std::to_string(s.repose_deg));
  }
  if (!(s.repose_jitter_deg >= 0.0f) || s.repose_deg - s.repose_jitter_deg < 1.0f ||
      s.repose_deg + s.repose_jitter_deg > 89.0f) {
    bad("repose_jitter_deg must be >= 0 with repose +- jitter in 1..89 degrees, got " +
        std::to_string(s.repose_jitter_deg));
  }
  if (!(s.tolerance >= 0.0f) || !std::isfinite(s.tolerance)) {
    bad("tolerance must be a finite number >= 0 metres, got " + std::to_string(s.tolerance));
  }
  if (!std::isfinite(s.min_move)) {
    bad("min_move must be a finite number of metres (negative: automatic), got " +
        std::to_string(s.min_move));
  }
  if (s.max_iterations < 0) bad("max_iterations must be >= 0");
  if (s.check_every < 1) bad("check_every must be >= 1");
  if (s.device != "auto" && s.device != "gpu" && s.device != "cpu") {
    bad("device must be auto, gpu or cpu, got '" + s.device + "'");
  }
  if (s.max_stride < 1 || s.max_stride > 64 || (s.max_stride & (s.max_stride - 1)) != 0) {
    bad("max_stride must be a power of two in 1..64, got " + std::to_string(s.max_stride));
  }
  check_cohesion(s.cohesion);
  for (float g : s.grip) {
    if (!(g > 0.0f) || !std::isfinite(g)) bad("every object's grip must be a finite number > 0");
  }
}

namespace {

void check_maps(const SnowMaps& maps) {
  const size_t n = size_t(maps.layers) * maps.grid.texels();
  if (maps.layers < 1 || maps.layers > 64) {
    throw InputError("stabilize: maps must have 1..64 layers, got " + std::to_string(maps.layers));
  }
  if (maps.grid.width < 1 || maps.grid.height < 1 || !(maps.grid.texel > 0.0f)) {
    throw InputError("stabilize: empty map grid or non-positive texel");
  }
  if (maps.ground.size() != n || maps.ceiling.size() != n || maps.normal.size() != n) {
    throw InputError("stabilize: map arrays do not hold layers * width * height entries");
  }
  if (double(n) >= double(0xffffffffu)) {
    throw InputError("stabilize: maps of " + std::to_string(n) + " layer texels are too large");
  }
}

// 32-bit integer hash (lowbias32 by C. Wellons).
uint32_t hash32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

}  // namespace

float texel_repose_deg(const StabilizeSettings& settings, int l, int i, int j) {
  uint32_t h = hash32(settings.seed ^ 0x9e3779b9u);
  h = hash32(h ^ uint32_t(i));
  h = hash32(h ^ uint32_t(j));
  h = hash32(h ^ uint32_t(l));
  const double u = double(h >> 8) / double(1u << 24);  // [0, 1)
  return float(double(settings.repose_deg) + (2.0 * u - 1.0) * double(settings.repose_jitter_deg));
}

void StrideSchedule::restart() {
  cap_ = adaptive_ ? 1 : max_;
  cycle_ = 0;
  since_ = 0;
  last_ = -1.0;
  creeping_ = false;
}

int StrideSchedule::next() {
  int levels = 1;
  while ((1 << levels) <= cap_) ++levels;  // cap_ = 2^(levels-1)
  ++since_;
  ++since_pressed_;
  ++passes_;
  return cap_ >> (cycle_++ % levels);
}

void StrideSchedule::checked(int stride, float residual) {
  creeping_before_ = creeping_;
  residual_before_ = residual_now_;
  residual_now_ = residual;
  creeping_ = false;
  if (stride != 1 || since_ < every_) return;
  // Fell by less than half per check_every passes: creeping, longer moves.
  creeping_ =
      last_ >= 0.0 && double(residual) > last_ * std::pow(0.5, double(since_) / double(every_));
  if (creeping_ && adaptive_ && cap_ < max_) {
    cap_ *= 2;
    cycle_ = 0;
  }
  last_ = double(residual);
  since_ = 0;
}

bool drain_due(const StabilizeSettings& settings, const StrideSchedule& schedule, float residual,
               float residual_void) {
  return settings.drain_edges && settings.route_steep && schedule.creeping() &&
         residual >= settings.tolerance && residual_void >= kDrainShare * residual;
}

bool creep_route_due(const StabilizeSettings& settings, StrideSchedule& schedule, bool late) {
  if (!schedule.creep_point()) return false;
  schedule.creep_next_ = (schedule.passes_ / kCreepRouteEvery + 1) * kCreepRouteEvery;
  const bool creeping = late ? schedule.creeping_ : schedule.creeping_before_;
  const float residual = late ? schedule.residual_now_ : schedule.residual_before_;
  return settings.route_creep && settings.route_steep && creeping && residual >= settings.tolerance;
}

bool pressed_snow_due(const StabilizeSettings& settings, const StrideSchedule& schedule,
                      float residual) {
  return settings.route_steep && settings.deposit_piles && schedule.creeping() &&
         residual >= settings.tolerance && schedule.since_pressed() >= kPressedEvery;
}

namespace {

// The cell of layer texel k = (l, i, j), which has a finite ground.
glm::vec4 surface_cell(const SnowMaps& maps, const StabilizeSettings& settings, int l, int i,
                       int j) {
  const size_t k = maps.index(l, i, j);
  const float g = maps.ground[k];
  glm::vec4 cell;
  const double angle = double(texel_repose_deg(settings, l, i, j)) * M_PI / 180.0;
  cell.z = float(std::tan(angle));
  int flags = kCellSurface;
  if (gap_is_solid(maps, l, i, j)) flags |= kCellSolid;
  if (maps.normal[k].y < 0.0f) flags |= kCellDown;
  cell.x = g;
  // +inf (open sky) -> 3e38; a ceiling below the ground (inconsistent
  // maps) -> no gap.
  cell.y = std::min(maps.ceiling[k], kCellOpenSky);
  if (std::isnan(maps.ceiling[k])) cell.y = kCellOpenSky;
  cell.y = std::max(cell.y, g);
  cell.w = float(flags);
  return cell;
}

// Calls fn(k, cell) for every layer texel with a surface, rows on all
// cores (a tangent per texel).
template <class Fn>
void for_surface_cells(const SnowMaps& maps, const StabilizeSettings& settings, Fn fn) {
  const size_t rows = size_t(maps.layers) * size_t(maps.grid.height);
  parallel_for(rows, [&](size_t row) {
    const int l = int(row / size_t(maps.grid.height)), j = int(row % size_t(maps.grid.height));
    for (int i = 0; i < maps.grid.width; ++i) {
      const size_t k = maps.index(l, i, j);
      if (std::isfinite(maps.ground[k])) fn(k, surface_cell(maps, settings, l, i, j));
    }
  });
}

}  // namespace

std::vector<glm::vec4> stabilize_cells(const SnowMaps& maps, const StabilizeSettings& settings) {
  check_stabilize_settings(settings);
  check_maps(maps);
  std::vector<glm::vec4> cells(maps.ground.size(), glm::vec4(0.0f, kCellOpenSky, 0.0f, 0.0f));
  for_surface_cells(maps, settings, [&](size_t k, const glm::vec4& cell) { cells[k] = cell; });
  return cells;
}

ZeroedArray<glm::vec4> stabilize_surface_cells(const SnowMaps& maps,
                                               const StabilizeSettings& settings) {
  check_stabilize_settings(settings);
  check_maps(maps);
  ZeroedArray<glm::vec4> cells(maps.ground.size());
  for_surface_cells(maps, settings, [&](size_t k, const glm::vec4& cell) { cells[k] = cell; });
  return cells;
}

ZeroedArray<float> stabilize_holds(const SnowMaps& maps, const StabilizeSettings& settings) {
  check_stabilize_settings(settings);
  check_maps(maps);
  ZeroedArray<float> holds(maps.ground.size());
  const size_t rows = size_t(maps.layers) * size_t(maps.grid.height);
  parallel_for(rows, [&](size_t row) {
    const int l = int(row / size_t(maps.grid.height)), j = int(row % size_t(maps.grid.height));
    for (int i = 0; i < maps.grid.width; ++i) {
      const size_t k = maps.index(l, i, j);
      if (!std::isfinite(maps.ground[k])) continue;
      const glm::vec3 n = maps.normal[k];
      const float length = glm::length(n);
      const double up = length > 0.0f ? std::min(1.0, std::abs(double(n.y)) / double(length)) : 1.0;
      const float slope_deg = float(std::acos(up) * 180.0 / M_PI);
      const int object = k < maps.object.size() ? maps.object[k] : -1;
      const float grip = object >= 0 && size_t(object) < settings.grip.size()
                             ? settings.grip[size_t(object)]
                             : kGripNormal;
      holds[k] = holding_depth(settings.cohesion, slope_deg, grip);
    }
  });
  return holds;
}

void StabilizeResult::add(const StabilizeResult& later) {
  const int passes = iterations + later.iterations;
  tile_share = passes > 0 ? (tile_share * iterations + later.tile_share * later.iterations) / passes
                          : later.tile_share;
  iterations = passes;
  residual = later.residual;
  converged = later.converged;
  route_passes += later.route_passes;
  routed_volume += later.routed_volume;
  drains += later.drains;
  creep_routes += later.creep_routes;
  pours += later.pours;
  lost_volume += later.lost_volume;
  volume = later.volume;
  route_seconds += later.route_seconds;
}

double snow_volume(const SnowMaps& maps, const std::vector<float>& depth) {
  const size_t n = std::min(depth.size(), maps.ground.size());
  const double sum = parallel_sum(n, kSumChunk, [&](size_t begin, size_t end) {
    double part = 0.0;
    for (size_t k = begin; k < end; ++k) {
      if (!std::isnan(maps.ground[k]) && depth[k] > 0.0f) part += double(depth[k]);
    }
    return part;
  });
  return sum * double(maps.grid.texel) * double(maps.grid.texel);
}

}  // namespace snow
