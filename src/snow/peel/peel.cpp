// Stage 1: snow amount maps by depth peeling from straight above (the
// stage's contract: snow/peel.h). This file checks the request and hands it
// to a backend: the GPU's depth-peeling passes (peel/gpu.cpp) or a vertical
// ray per texel on the CPU (snow/reference/peel_ref.h), as peels_on_cpu
// decides.
#include "snow/peel.h"

#include <algorithm>
#include <new>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "plan/rules.h"
#include "snow/bridge.h"
#include "snow/peel/internal.h"
#include "snow/reference/peel_ref.h"

namespace snow {
namespace {

// Texel centres that the triangles' xz boxes hold, summed (at most `cap`):
// a bound on the hits the CPU peel stores.
size_t box_texels(const Scene& scene, const MapGrid& grid, size_t cap) {
  size_t sum = 0;
  for (size_t t = 0; t < scene.triangle_count() && sum <= cap; ++t) {
    const glm::vec3* c = &scene.positions[3 * t];
    const double lo_x = std::min({c[0].x, c[1].x, c[2].x}),
                 hi_x = std::max({c[0].x, c[1].x, c[2].x});
    const double lo_z = std::min({c[0].z, c[1].z, c[2].z}),
                 hi_z = std::max({c[0].z, c[1].z, c[2].z});
    const double w = std::min(double(grid.width), (hi_x - lo_x) / grid.texel + 1.0);
    const double h = std::min(double(grid.height), (hi_z - lo_z) / grid.texel + 1.0);
    if (w > 0.0 && h > 0.0) sum += size_t(w * h);  // NaN boxes add nothing
  }
  return sum;
}

void warn_overflow(const SnowMaps& maps, int layers) {
  if (maps.overflow_columns > 0) {
    log_warn(std::to_string(maps.overflow_columns) + " map columns hold more than " +
             std::to_string(layers) +
             " surfaces; the lowest ones are dropped (raise --layers to keep them)");
  }
}

SnowMaps peel_checked(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                      const plan::GlFacts& gl) {
  peel::validate_settings(settings);
  if (grid.width < 1 || grid.height < 1 || !(grid.texel > 0.0f)) {
    throw InputError("peel: empty map grid");
  }
  const float scene_height = scene.bounds.empty() ? 0.0f : scene.bounds.size().y;
  check_memory_budget(grid, settings.layers, CoverageSettings{}, settings.memory_budget,
                      scene_height, scene.triangle_count());
  SnowMaps maps;
  if (peels_on_cpu(scene, grid, settings, gl)) {
    log_debug("peel: a vertical ray per texel on the CPU");
    Progress progress("peel", 1);
    maps = reference::peel_layers(scene, grid, settings.layers, settings.merge_distance);
    progress.finish();
  } else {
    maps = peel::peel_on_gpu(scene, grid, settings);
  }
  warn_overflow(maps, settings.layers);
  return maps;
}

}  // namespace

bool peels_on_cpu(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                  const plan::GlFacts& gl) {
  peel::validate_settings(settings);
  const plan::PeelChoice choice =
      plan::choose_peel(settings.device, gl, grid.texels() * size_t(settings.layers));
  if (choice.always_cpu || choice.cpu_box_texels == 0) return choice.always_cpu;
  return box_texels(scene, grid, choice.cpu_box_texels) <= choice.cpu_box_texels;
}

SnowMaps peel_layers(const Scene& scene, const PeelSettings& settings, const plan::GlFacts& gl) {
  return peel_layers(scene, make_grid(scene.bounds, settings), settings, gl);
}

SnowMaps peel_layers(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                     const plan::GlFacts& gl) {
  try {
    SnowMaps maps = peel_checked(scene, grid, settings, gl);
    bridge_gaps(maps, settings.bridge_width);
    return maps;
  } catch (const std::bad_alloc&) {
    throw InputError("peel: out of memory for maps of " + std::to_string(grid.width) + " x " +
                     std::to_string(grid.height) + " texels x " + std::to_string(settings.layers) +
                     " layers; use a coarser texel size");
  }
}

}  // namespace snow
