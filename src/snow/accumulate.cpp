// Time-stepped accumulation: coverage (Tokoi 2006, section 4) times fresh
// snow per step, stabilized after each step (docs/ARCHITECTURE.md,
// "Stabilizer").
#include "snow/accumulate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "snow/stabilize_cpu.h"
#include "snow/stabilize_step.h"

namespace snow {

SnowResult accumulate(const Scene& scene, const SnowMaps& maps, const CoverageSettings& coverage,
                      const StabilizeSettings& stabilize, const AccumulateSettings& settings,
                      const plan::GlFacts& gl, const std::vector<uint8_t>& receives,
                      CoverageBvh* bvh) {
  if (!std::isfinite(settings.fall_depth) || settings.fall_depth < 0 ||
      settings.fall_depth > 1000) {
    throw InputError("snow depth must be between 0 and 1000 m, got " +
                     std::to_string(settings.fall_depth));
  }
  if (settings.steps < 1 || settings.steps > kMaxSnowSteps) {
    throw InputError("snow steps must be between 1 and " + std::to_string(kMaxSnowSteps) +
                     ", got " + std::to_string(settings.steps));
  }
  check_drift_settings(settings.drift);
  if (settings.snow_on_snow_every < 0 || settings.snow_on_snow_every > kMaxSnowSteps) {
    throw InputError("snow-on-snow interval must be 0 (off) or 1.." +
                     std::to_string(kMaxSnowSteps) + " steps, got " +
                     std::to_string(settings.snow_on_snow_every));
  }

  SnowResult result;
  std::unique_ptr<CoverageRenderer> shadows = CoverageRenderer::make(scene, maps, gl, bvh);
  result.coverage = shadows->compute(maps, coverage);
  result.coverage_method = shadows->timings().method;
  mask_coverage(maps, receives, result.coverage);
  result.coverage_updates = 1;
  // Without snow-on-snow updates the shadow maps are done with: they are
  // freed before the stabilizer allocates its textures, so the two never
  // take memory at the same time.
  if (!(settings.snow_on_snow_every > 0 && settings.steps > settings.snow_on_snow_every)) {
    shadows.reset();
  }
  const bool on_cpu = result.stabilized_on_cpu =
      stabilizes_on_cpu(stabilize, StabilizerUse::Batch, gl);
  // The steps over either stabilizer (same passes, same results).
  auto run_steps = [&](auto& stabilizer) {
    const float per_step = settings.fall_depth / float(settings.steps);
    const double texel_area = double(maps.grid.texel) * double(maps.grid.texel);
    Progress progress("snowfall", settings.steps);
    double lost_before = 0.0;  // m^3 the stabilizer lost before its last set_depth
    for (int step = 0; step < settings.steps; ++step) {
      const bool update =
          settings.snow_on_snow_every > 0 && step > 0 && step % settings.snow_on_snow_every == 0;
      if (update) {
        const std::vector<float> lying = stabilizer.depth();
        result.coverage = shadows->compute(maps, coverage, &lying);
        mask_coverage(maps, receives, result.coverage);
        ++result.coverage_updates;
      }
      stabilizer.add_snow(result.coverage, per_step);
      const double added =
          parallel_sum(result.coverage.size(), kSumChunk, [&](size_t begin, size_t end) {
            double part = 0.0;
            for (size_t k = begin; k < end; ++k) {
              if (!std::isnan(maps.ground[k])) part += double(result.coverage[k] * per_step);
            }
            return part;
          });
      result.fallen_volume += added * texel_area;
      if (settings.drift.transport > 0.0f && per_step > 0.0f) {
        const auto start = std::chrono::steady_clock::now();
        const DriftResult drift =
            drift_lying_snow(stabilizer, maps, per_step, settings.drift, lost_before);
        char line[160];
        std::snprintf(
            line, sizeof line,
            "wind: eroded and carried %.3g m^3, %.3g in and %.3g out over the border, "
            "in %.2f s",
            drift.moved, drift.entered, drift.left,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        log_debug(line);
        result.drifted_in += drift.entered;
        result.drifted_out += drift.left;
        result.drifted += drift.moved;
      }
      result.last = stabilize_step(stabilizer, stabilize,
                                   [&](double done) { progress.update(double(step) + done); });
      result.iterations += result.last.iterations;
      progress.update(step + 1);
    }
    progress.finish();

    result.depth = stabilizer.depth();
    result.fallen_volume += result.drifted_in;
    result.lost_volume = lost_before + stabilizer.lost_volume() + result.drifted_out;
    result.volume = snow_volume(maps, result.depth);
  };
  // The volumes are summed once, at the end.
  if (on_cpu) {
    CpuStabilizer stabilizer(maps, stabilize);
    stabilizer.set_volume_sums(false);
    run_steps(stabilizer);
  } else {
    Stabilizer stabilizer(maps, stabilize);
    stabilizer.set_volume_sums(false);
    run_steps(stabilizer);
  }
  return result;
}

}  // namespace snow
