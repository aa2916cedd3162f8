#pragma once
// One stabilizing of the snowfall stage (snow/accumulate.h): the
// stabilizer's passes in chunks, with progress reports (internal to
// src/snow).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/log.h"
#include "snow/stabilize.h"

namespace snow {

/// Relaxation passes per progress report: seconds of work on a software
/// rasterizer at large maps, a negligible readback overhead on a GPU.
constexpr int kPassesPerReport = 64;

/// Stabilizer::run() in chunks of passes, reporting the share done, in
/// [0, 1), after each.
template <class AnyStabilizer, class Report>
inline StabilizeResult stabilize_step(AnyStabilizer& stabilizer, const StabilizeSettings& settings,
                                      Report report) {
  StabilizeResult total;
  double first_residual = 0;
  double reported = 0;  // the share never goes back (a residual may rise for a while)
  for (;;) {
    const int passes = std::min(kPassesPerReport, settings.max_iterations - total.iterations);
    const StabilizeResult r = stabilizer.iterate(passes);
    total.add(r);
    char line[200];
    std::snprintf(
        line, sizeof line,
        "stabilize: %d passes, largest move %.3g m, routing %d passes (%.2f s), %d of creeping "
        "snow, %d drains, %d pours of pressed snow",
        total.iterations, double(r.residual), r.route_passes, r.route_seconds, r.creep_routes,
        r.drains, r.pours);
    log_debug(line);
    if (r.converged || passes <= 0 || total.iterations >= settings.max_iterations) break;
    // The larger of the share of passes run and the share of the way down
    // to the tolerance on a log scale (relaxation converges about
    // geometrically; a tolerance of 0 runs every pass).
    double done = double(total.iterations) / double(settings.max_iterations);
    if (first_residual == 0) first_residual = r.residual;
    const double span = std::log(first_residual / double(settings.tolerance));
    if (settings.tolerance > 0 && span > 0) {
      const double gone = std::log(first_residual / std::max(double(r.residual), 1e-30));
      done = std::max(done, gone / span);
    }
    reported = std::max(reported, std::clamp(done, 0.0, 0.99));
    report(reported);
  }
  return total;
}

}  // namespace snow
