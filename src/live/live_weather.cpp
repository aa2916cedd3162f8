// The live preview playing a weather series (live/live_sim.h): the batch
// job's steps (snow/weather_step.h) applied as the clock passes their ends,
// the stabilizer's passes spread over the frames between them.
#include <algorithm>
#include <chrono>

#include "gl/gl.h"
#include "live/live_weather.h"
#include "snow/stabilize_cpu.h"

namespace snow::live {
namespace {

/// Slack on hour comparisons (hours): the clock adds frame after frame.
constexpr double kHourSlack = 1e-9;

double end_of(const WeatherStep& step) { return step.hour + step.hours; }

}  // namespace

void LiveSim::restart_weather() {
  if (!settings_.weather) {
    weather_.reset();
    return;
  }
  auto w = std::make_unique<Weather>();
  w->run = settings_.weather;
  w->pack = SnowPack::empty(maps_);
  w->stepper =
      std::make_unique<WeatherStepper>(*shadows_, maps_, settings_.coverage, *w->run, receives_);
  w->hour = w->run->steps.front().hour;
  weather_ = std::move(w);
}

void LiveSim::step_weather() {
  const auto start = Clock::now();
  const size_t before = weather_->next;
  play_weather_to(weather_->hour + double(settings_.weather_speed) * settings_.frame_time);
  timings_.add = seconds_since(start);
  relax(weather_->next != before);
  ++frame_;
}

void LiveSim::seek(double hour) {
  if (!weather_) return;
  play_weather_to(hour);
}

void LiveSim::sync_snowpack() {
  if (weather_) account_moves(weather_->pack, maps_, depth());
}

void LiveSim::play_weather_to(double hour) {
  const std::vector<WeatherStep>& steps = weather_->run->steps;
  hour = std::clamp(hour, steps.front().hour, end_of(steps.back()));
  if (hour < weather_->hour - kHourSlack) reset();  // back: from the start
  Weather& w = *weather_;
  w.hour = hour;
  auto due = [&] { return w.next < steps.size() && end_of(steps[w.next]) <= hour + kHourSlack; };
  if (!due()) return;
  // What the passes moved since the last step, then the steps due at once.
  sync_snowpack();
  const int updates = w.stats.coverage_updates;
  const double drifted_out = w.stats.drifted_out;
  for (; due(); ++w.next) {
    const WeatherStep& step = steps[w.next];
    if (std::optional<std::vector<float>> moved = w.stepper->snowfall(step, w.pack, w.stats)) {
      account_moves(w.pack, maps_, *moved);
      fallen_depth_ += fresh_snow_depth(step);
    }
    w.stepper->melt(step, w.pack);
  }
  lost_before_ += w.stats.drifted_out - drifted_out;
  replace_depth(w.pack.depth);
  fallen_volume_ = w.stats.fallen_volume;
  last_.converged = false;
  if (w.stats.coverage_updates != updates) {
    coverage_ = w.stepper->coverage();
    ++coverage_version_;
  }
}

const SnowPack* LiveSim::snowpack() const { return weather_ ? &weather_->pack : nullptr; }

double LiveSim::weather_hour() const { return weather_ ? weather_->hour : 0.0; }

double LiveSim::snowpack_hour() const {
  if (!weather_) return 0.0;
  const std::vector<WeatherStep>& steps = weather_->run->steps;
  return weather_->next == 0 ? steps.front().hour : end_of(steps[weather_->next - 1]);
}

const WeatherStep* LiveSim::weather_now() const {
  if (!weather_ || weather_->next >= weather_->run->steps.size()) return nullptr;
  return &weather_->run->steps[weather_->next];
}

bool LiveSim::snowing() const {
  if (!weather_) return settings_.fall_rate > 0.0f && fallen_depth_ < settings_.total_depth;
  const WeatherStep* now = weather_now();
  return now && snow_water(*now) > 0.0f;
}

glm::vec2 LiveSim::fall_wind() const {
  if (!weather_) return settings_.coverage.wind;
  const WeatherStep* now = weather_now();
  return now ? weather_->run->compass.wind(now->wind_ms, now->wind_from_deg) : glm::vec2(0.0f);
}

}  // namespace snow::live
