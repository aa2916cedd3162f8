// The peel stage's map grid and memory bound (snow/peel.h): where the maps
// lie, how many texels they have, and what they will cost before anything is
// allocated. CPU only.
#include "snow/peel.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "core/error.h"
#include "snow/peel/internal.h"

namespace snow {
namespace {

constexpr double kPiDouble = 3.14159265358979323846;
constexpr double kMaxSide = double(1 << 30);  // texels; beyond this a grid is absurd

std::string format_gib(double bytes) {
  char text[64];
  const double gib = bytes / double(1ull << 30);
  if (gib >= 1e5) {
    std::snprintf(text, sizeof text, "%.3g GiB", gib);
  } else if (gib == std::floor(gib)) {
    std::snprintf(text, sizeof text, "%.0f GiB", gib);
  } else {
    std::snprintf(text, sizeof text, "%.1f GiB", gib);
  }
  return text;
}

// Bytes per unit, see estimate_memory's contract.
constexpr double kMapsPerLayerTexel = 24 + 4;              // SnowMaps + coverage
constexpr double kPeelPerTexel = 2 * 20 + 4 + 16;          // ping-pong targets, depth, readback
constexpr double kCoveragePerLayerTexel = 16 + 4 + 8 + 8;  // receivers, counts, snow, queue
constexpr double kPerTriangle = 140;        // GPU copies, BVH nodes and build scratch
constexpr double kLaterPerLayerTexel = 48;  // stabilizer, depth, polygonize scratch

}  // namespace

namespace peel {

std::string format_metres(double m) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", m);
  return text;
}

double nice_ceil(double x) {
  if (!(x > 0) || !std::isfinite(x)) return x;
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= x * (1 - 1e-9)) return m * p;
  }
  return 10 * p;
}

void validate_settings(const PeelSettings& s) {
  if (s.layers < 1 || s.layers > 64) {
    throw InputError("layers must be in 1..64, got " + std::to_string(s.layers));
  }
  if (!(s.merge_distance >= 0.0f) || !std::isfinite(s.merge_distance)) {
    throw InputError("merge distance must be a finite number >= 0 m, got " +
                     format_metres(s.merge_distance));
  }
  if (s.device != "auto" && s.device != "gpu" && s.device != "cpu") {
    throw InputError("peel device must be auto, gpu or cpu, got '" + s.device + "'");
  }
}

}  // namespace peel

MapGrid make_grid(const Bounds& bounds, const PeelSettings& settings) {
  peel::validate_settings(settings);
  if (bounds.empty()) throw InputError("the scene is empty: there is nothing to make maps of");
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(bounds.min[a]) || !std::isfinite(bounds.max[a])) {
      throw InputError("the scene's bounds are not finite (a vertex is NaN or infinite)");
    }
  }
  if (!(settings.texel >= 0.0f) || !std::isfinite(settings.texel)) {
    throw InputError("texel size must be a finite number > 0 m (or 0 for automatic), got " +
                     peel::format_metres(settings.texel));
  }
  if (!std::isfinite(settings.margin)) throw InputError("margin must be finite");
  const double ex = double(bounds.max.x) - bounds.min.x;
  const double ez = double(bounds.max.z) - bounds.min.z;
  double longest = std::max(ex, ez);
  if (!(longest > 0)) longest = 1.0;  // a scene with no horizontal extent: 1 m around it
  double texel = settings.texel;
  double margin = settings.margin;
  if (texel == 0) {
    if (settings.max_side < 1 || settings.max_side > 65536) {
      throw InputError("maximum map side must be in 1..65536 texels, got " +
                       std::to_string(settings.max_side));
    }
    if (margin < 0) margin = 0.02 * longest;
    texel = (longest + 2 * margin) / settings.max_side;
    if (!(texel > 0)) texel = 1e-3;
  } else if (margin < 0) {
    margin = std::max(0.02 * longest, 2 * texel);
  }
  const double w = std::ceil((ex + 2 * margin) / texel * (1 - 1e-6));
  const double h = std::ceil((ez + 2 * margin) / texel * (1 - 1e-6));
  if (!(w <= kMaxSide) || !(h <= kMaxSide)) {
    throw InputError("a map of " + peel::format_metres(ex + 2 * margin) + " x " +
                     peel::format_metres(ez + 2 * margin) + " m at texel " +
                     peel::format_metres(texel) + " m is absurdly large; use a coarser texel size");
  }
  MapGrid grid;
  grid.texel = float(texel);
  grid.width = std::max(1, int(w));
  grid.height = std::max(1, int(h));
  const double cx = 0.5 * (double(bounds.min.x) + bounds.max.x);
  const double cz = 0.5 * (double(bounds.min.z) + bounds.max.z);
  grid.origin =
      glm::vec2(float(cx - 0.5 * grid.width * texel), float(cz - 0.5 * grid.height * texel));
  return grid;
}

plan::SceneStats scene_stats(const Scene& scene, const PeelSettings& settings,
                             const plan::Settings& wanted, uint64_t input_bytes) {
  plan::SceneStats stats;
  stats.input_bytes = input_bytes;
  stats.triangles = scene.triangle_count();
  PeelSettings asked = settings;
  if (asked.texel <= 0.0f && asked.max_side == 0) asked.max_side = wanted.auto_side;
  MapGrid grid = make_grid(scene.bounds, asked);
  stats.asked_grid_side = std::max(grid.width, grid.height);
  stats.asked_grid_texel = grid.texel;
  const plan::MapPlan maps = plan::plan_maps(wanted, stats.asked_grid_side, grid.texel);
  if (maps.max_side != asked.max_side) {
    asked.max_side = maps.max_side;
    grid = make_grid(scene.bounds, asked);
  }
  stats.grid_columns = grid.texels();
  return stats;
}

uint64_t estimate_memory(const MapGrid& grid, int layers, const CoverageSettings& coverage,
                         float scene_height, uint64_t triangles) {
  const double texels = double(std::max(grid.width, 0)) * double(std::max(grid.height, 0));
  const double layer_texels = texels * std::max(layers, 1);
  // Shadow map: the grid grown by the shear of the steepest direction.
  const double angle = std::min(
      double(kMaxFallAngleDeg),
      std::atan2(double(glm::length(coverage.wind)), std::max(1e-6f, coverage.fall_speed)) * 180.0 /
              kPiDouble +
          std::max(0.0f, coverage.flutter_deg));
  const double grow = grid.texel > 0 ? std::max(0.0f, scene_height) *
                                           std::tan(angle * kPiDouble / 180.0) / grid.texel
                                     : 0.0;
  const double shadow_texels =
      (double(grid.width) + 2 * grow + 2) * (double(grid.height) + 2 * grow + 2);
  const double batch = shadow_batch(coverage, shadow_texels);
  const double bytes =
      layer_texels * (kMapsPerLayerTexel + kCoveragePerLayerTexel + kLaterPerLayerTexel) +
      texels * kPeelPerTexel + batch * shadow_texels * 4 + double(triangles) * kPerTriangle;
  if (!(bytes < 1.8e19)) return std::numeric_limits<uint64_t>::max();
  return uint64_t(bytes);
}

void check_memory_budget(const MapGrid& grid, int layers, const CoverageSettings& coverage,
                         uint64_t budget, float scene_height, uint64_t triangles) {
  const uint64_t need = estimate_memory(grid, layers, coverage, scene_height, triangles);
  if (need <= budget) return;
  // Memory grows with 1 / texel^2: suggest a texel that fits.
  const double ratio = double(need) / double(std::max<uint64_t>(budget, 1));
  const double suggest = peel::nice_ceil(grid.texel * std::sqrt(ratio) * 1.05);
  throw InputError("maps of " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                   " texels x " + std::to_string(layers) + " layers need " +
                   format_gib(double(need)) + ", over the " + format_gib(double(budget)) +
                   " budget; use a coarser texel size, e.g. --texel " +
                   peel::format_metres(suggest) + ", or raise --memory-budget");
}

}  // namespace snow
