#pragma once
// LiveSim's weather series state (internal to src/live; live_weather.cpp).
#include <chrono>
#include <cstddef>
#include <memory>

#include "live/live_sim.h"
#include "snow/accumulate.h"
#include "snow/weather_step.h"

namespace snow::live {

using Clock = std::chrono::steady_clock;

/// Wall seconds since `start`, after glFinish: the GPU's time too.
double seconds_since(Clock::time_point start);

struct LiveSim::Weather {
  std::shared_ptr<const WeatherRun> run;    // settings().weather
  SnowPack pack;                            // as of the last step applied
  std::unique_ptr<WeatherStepper> stepper;  // on the LiveSim's maps and coverage settings
  double hour = 0.0;                        // the clock, hours of the series
  size_t next = 0;                          // the first step not applied
  SnowResult stats;                         // the steps' fallen volume and coverage updates
};

}  // namespace snow::live
