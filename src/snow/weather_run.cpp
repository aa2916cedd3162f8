// Snowfall driven by a weather series (snow/accumulate.h, accumulate_weather;
// the physics in snow/weather.h and snow/snowpack.h).
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "snow/accumulate.h"
#include "snow/stabilize_cpu.h"
#include "snow/stabilize_step.h"
#include "snow/weather_step.h"

namespace snow {
namespace {

template <class AnyStabilizer>
void run_weather(AnyStabilizer& stabilizer, CoverageRenderer& shadows, const SnowMaps& maps,
                 const CoverageSettings& coverage, const StabilizeSettings& stabilize,
                 const WeatherRun& run, SnowPack& pack, const std::vector<uint8_t>& receives,
                 SnowResult& result) {
  WeatherStepper stepper(shadows, maps, coverage, run, receives);
  // The last frame written before the first step (a resumed run's).
  int frame =
      run.every_hours > 0.0 ? int(std::floor(run.steps.front().hour / run.every_hours + 1e-9)) : 0;
  Progress progress("weather", double(run.steps.size()));
  bool tracked = false;
  for (size_t n = 0; n < run.steps.size(); ++n) {
    const WeatherStep& step = run.steps[n];
    if (std::optional<std::vector<float>> depth = stepper.snowfall(step, pack, result)) {
      stabilizer.set_depth(*depth);
      result.last = stabilize_step(stabilizer, stabilize,
                                   [&](double done) { progress.update(double(n) + done); });
      result.iterations += result.last.iterations;
      account_moves(pack, maps, stabilizer.depth());
    }
    stepper.melt(step, pack);
    const double end = step.hour + step.hours;
    if (run.on_tracks && !tracked && end >= run.tracks_hour - 1e-9) {
      run.on_tracks(pack);
      tracked = true;
    }
    // Frames at the multiples of every_hours since hour 0 (so a resumed
    // run's frames go on counting), and at the end.
    const bool last = n + 1 == run.steps.size();
    if (run.on_frame && run.every_hours > 0.0) {
      const int due = int(std::floor(end / run.every_hours + 1e-9));
      if (due > frame || last) {
        frame = last && end > double(due) * run.every_hours + 1e-9 ? due + 1 : due;
        run.on_frame(frame, end, pack);
      }
    }
    progress.update(double(n + 1));
  }
  progress.finish();
  result.coverage = stepper.coverage();
}

}  // namespace

SnowResult accumulate_weather(const Scene& scene, const SnowMaps& maps,
                              const CoverageSettings& coverage, const StabilizeSettings& stabilize,
                              const WeatherRun& run, SnowPack& pack, const plan::GlFacts& gl,
                              const std::vector<uint8_t>& receives, CoverageBvh* bvh) {
  if (run.steps.empty()) throw InputError("weather: no steps");
  if (pack.depth.size() != maps.ground.size() || pack.swe.size() != maps.ground.size() ||
      pack.albedo.size() != maps.ground.size()) {
    throw InputError("weather: the snowpack does not match the maps");
  }
  SnowResult result;
  std::unique_ptr<CoverageRenderer> shadows = CoverageRenderer::make(scene, maps, gl, bvh);
  const bool on_cpu = result.stabilized_on_cpu =
      stabilizes_on_cpu(stabilize, StabilizerUse::Batch, gl);
  const double fallen_before = pack.fallen, melted_before = pack.melted, lost_before = pack.lost;
  if (on_cpu) {
    CpuStabilizer stabilizer(maps, stabilize);
    stabilizer.set_volume_sums(false);
    run_weather(stabilizer, *shadows, maps, coverage, stabilize, run, pack, receives, result);
  } else {
    Stabilizer stabilizer(maps, stabilize);
    stabilizer.set_volume_sums(false);
    run_weather(stabilizer, *shadows, maps, coverage, stabilize, run, pack, receives, result);
  }
  result.depth = pack.depth;
  result.volume = snow_volume(maps, result.depth);
  char line[256];
  std::snprintf(line, sizeof line,
                "weather: %zu steps; water equivalent %.4g m^3 fell as snow, %.4g melted, %.4g "
                "left the maps, %.4g lies",
                run.steps.size(), pack.fallen - fallen_before, pack.melted - melted_before,
                pack.lost - lost_before, pack.lying(maps));
  log_info(line);
  return result;
}

}  // namespace snow
