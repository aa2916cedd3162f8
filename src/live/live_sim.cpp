// The live snowfall: the batch job's stages (peel, coverage, stabilizer; Tokoi
// 2006, Fearing 2000) stepped frame by frame with their GPU state kept.
#include "live/live_sim.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "gl/gl.h"
#include "live/live_weather.h"
#include "snow/accumulate.h"
#include "snow/drift.h"
#include "snow/stabilize_cpu.h"

namespace snow::live {

double seconds_since(Clock::time_point start) {
  glFinish();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

namespace {

// fn(stabilizer) on whichever of the two exists (same contract, same passes).
template <class Fn>
auto on_either(CpuStabilizer* cpu, Stabilizer* gpu, Fn fn) {
  return cpu ? fn(*cpu) : fn(*gpu);
}

bool same(const PeelSettings& a, const PeelSettings& b) {
  return a.texel == b.texel && a.max_side == b.max_side && a.layers == b.layers &&
         a.margin == b.margin && a.merge_distance == b.merge_distance;
}

bool same(const CoverageSettings& a, const CoverageSettings& b) {
  return a.directions == b.directions && a.flutter_deg == b.flutter_deg && a.wind == b.wind &&
         a.fall_speed == b.fall_speed && a.seed == b.seed && a.batch == b.batch && a.bias == b.bias;
}

bool same(const StabilizeSettings& a, const StabilizeSettings& b) {
  return a.repose_deg == b.repose_deg && a.repose_jitter_deg == b.repose_jitter_deg &&
         a.tolerance == b.tolerance && a.min_move == b.min_move &&
         a.max_iterations == b.max_iterations && a.check_every == b.check_every &&
         a.max_stride == b.max_stride && a.adaptive_stride == b.adaptive_stride &&
         a.route_steep == b.route_steep && a.deposit_piles == b.deposit_piles &&
         a.drain_edges == b.drain_edges && a.route_creep == b.route_creep && a.seed == b.seed &&
         a.device == b.device;
}

void check(const LiveSettings& s) {
  auto finite_non_negative = [](float v) { return std::isfinite(v) && v >= 0.0f; };
  if (!finite_non_negative(s.total_depth) || s.total_depth > 1000.0f)
    throw InputError("total snow depth must be between 0 and 1000 m");
  if (!finite_non_negative(s.fall_rate) || s.fall_rate > 1000.0f)
    throw InputError("fall rate must be between 0 and 1000 m/s");
  if (!(s.frame_time > 0.0f) || s.frame_time > 3600.0f)
    throw InputError("frame time must be between 0 and 3600 s");
  if (s.passes_per_frame < 0 || s.passes_per_frame > 100000)
    throw InputError("stabilizer passes per frame must be between 0 and 100000");
  if (s.add_every < 0 || s.add_every > 100000)
    throw InputError("snow addition interval must be between 0 (automatic) and 100000 frames");
  if (!(s.weather_speed >= 0.0f) || s.weather_speed > 1e4f)
    throw InputError("weather speed must be between 0 and 10000 hours per simulated second");
  if (s.weather && s.weather->steps.empty()) throw InputError("weather: no steps");
  if (s.snow_on_snow_every < 0)
    throw InputError("snow-on-snow interval must be 0 (off) or a positive number of frames");
  fall_directions(s.coverage);             // throws InputError for bad coverage settings
  texel_repose_deg(s.stabilize, 0, 0, 0);  // throws InputError for bad stabilizer settings
}

}  // namespace

LiveSim::LiveSim(const Scene& scene, const LiveSettings& settings, const plan::GlFacts& gl,
                 std::vector<uint8_t> receives)
    : scene_(scene), gl_(gl), settings_(settings), receives_(std::move(receives)) {
  check(settings_);
  shadows_ = std::make_unique<CoverageRenderer>(scene_, gl_);
  peel();
}

LiveSim::~LiveSim() = default;

void LiveSim::peel() {
  const auto start = Clock::now();
  SnowMaps maps = peel_layers(scene_, settings_.peel, gl_);
  make_stabilizer(maps, nullptr);
  maps_ = std::move(maps);
  timings_.peel = seconds_since(start);
  ++maps_version_;
  compute_coverage(nullptr);
  fallen_depth_ = 0;
  fallen_volume_ = 0;
  lost_before_ = 0;
  frame_ = 0;
  last_ = StabilizeResult();
  restart_weather();
}

void LiveSim::make_stabilizer(const SnowMaps& maps, const std::vector<float>* depth) {
  const StabilizeSettings& s = settings_.stabilize;
  if (snow::stabilizes_on_cpu(s, StabilizerUse::Live, gl_)) {
    auto cpu = std::make_unique<CpuStabilizer>(maps, s);
    cpu->set_volume_sums(false);
    cpu->set_depth(depth ? *depth : std::vector<float>(maps.ground.size(), 0.0f));
    gl::Texture texture = gl::create_texture_2d_array(GL_R32F, maps.grid.width, maps.grid.height,
                                                      maps.layers, "live snow depth");
    cpu_ = std::move(cpu);
    cpu_depth_ = std::move(texture);
    gpu_.reset();
    upload_depth(maps);
  } else {
    auto gpu = std::make_unique<Stabilizer>(maps, s);
    gpu->set_async_checks(true);  // no frame waits for its own passes
    gpu->set_volume_sums(false);  // the panel reads them now and then (snow_volume)
    if (depth) gpu->set_depth(*depth);
    gpu_ = std::move(gpu);
    cpu_.reset();
    cpu_depth_ = gl::Texture();
  }
}

void LiveSim::upload_depth(const SnowMaps& maps) {
  if (!cpu_) return;
  glTextureSubImage3D(cpu_depth_.id(), 0, 0, 0, 0, maps.grid.width, maps.grid.height, maps.layers,
                      GL_RED, GL_FLOAT, cpu_->depth_data());
  gl::check_error("live snow depth upload");
}

unsigned LiveSim::depth_texture() const { return cpu_ ? cpu_depth_.id() : gpu_->depth_texture(); }

std::vector<float> LiveSim::depth() const { return cpu_ ? cpu_->depth() : gpu_->depth(); }

double LiveSim::lost_volume() const {
  return lost_before_ + (cpu_ ? cpu_->lost_volume() : gpu_->lost_volume());
}

void LiveSim::compute_coverage(const std::vector<float>* lying) {
  const auto start = Clock::now();
  std::vector<float> coverage = shadows_->compute(maps_, settings_.coverage, lying);
  mask_coverage(maps_, receives_, coverage);
  coverage_ = std::move(coverage);
  double sum = 0;
  for (size_t k = 0; k < coverage_.size(); ++k) {
    if (!std::isnan(maps_.ground[k])) sum += double(coverage_[k]);
  }
  coverage_area_ = sum * double(maps_.grid.texel) * double(maps_.grid.texel);
  // The stabilizer keeps it (on the GPU), so each addition uploads nothing.
  on_either(cpu_.get(), gpu_.get(), [&](auto& s) { s.set_snow_amount(coverage_); });
  timings_.last_coverage = seconds_since(start);
  timings_.coverage = timings_.last_coverage;
  ++coverage_version_;
}

int LiveSim::add_every() const {
  return settings_.add_every > 0 ? settings_.add_every : plan::preview_add_every(gl_);
}

void LiveSim::step() {
  timings_.coverage = 0;
  if (weather_) {
    step_weather();
    return;
  }
  const int every = settings_.snow_on_snow_every;
  if (every > 0 && frame_ > 0 && frame_ % every == 0 && fallen_depth_ < settings_.total_depth) {
    const std::vector<float> lying = depth();
    compute_coverage(&lying);
  }
  auto start = Clock::now();
  const int add_every = this->add_every();
  const bool adds = frame_ % add_every == 0;
  const float amount = adds
                           ? std::min(float(add_every) * settings_.fall_rate * settings_.frame_time,
                                      settings_.total_depth - fallen_depth_)
                           : 0.0f;
  if (amount > 0.0f) {
    on_either(cpu_.get(), gpu_.get(), [&](auto& s) { s.add_snow(amount); });
    fallen_depth_ += amount;
    fallen_volume_ += double(amount) * coverage_area_;
    const DriftSettings drift =
        drift_for_wind(settings_.wind_transport ? settings_.coverage.wind : glm::vec2(0.0f),
                       settings_.snow_kind, settings_.total_depth);
    if (drift.transport > 0.0f) {
      const DriftResult moved = on_either(cpu_.get(), gpu_.get(), [&](auto& s) {
        return drift_lying_snow(s, maps_, amount, drift, lost_before_);
      });
      fallen_volume_ += moved.entered;
      lost_before_ += moved.left;
      last_.converged = false;
    }
  }
  timings_.add = seconds_since(start);
  relax(amount > 0.0f);
  ++frame_;
}

void LiveSim::relax(bool fell) {
  const auto start = Clock::now();
  if (fell || !last_.converged) {
    last_ = on_either(cpu_.get(), gpu_.get(),
                      [&](auto& s) { return s.iterate(settings_.passes_per_frame); });
    upload_depth(maps_);
  }  // else: nothing fell and the snow is at rest; passes would move nothing
  timings_.stabilize = seconds_since(start);
  log_debug("live frame " + std::to_string(frame_) + ": add " + std::to_string(timings_.add) +
            " s, stabilize " + std::to_string(timings_.stabilize) + " s (" +
            std::to_string(last_.route_passes) + " routing, " + std::to_string(last_.iterations) +
            " relaxation passes)");
}

void LiveSim::replace_depth(const std::vector<float>& depth) {
  lost_before_ += on_either(cpu_.get(), gpu_.get(), [](auto& s) { return s.lost_volume(); });
  on_either(cpu_.get(), gpu_.get(), [&](auto& s) { s.set_depth(depth); });
  upload_depth(maps_);
}

void LiveSim::reset() {
  replace_depth(std::vector<float>(maps_.ground.size(), 0.0f));
  fallen_depth_ = 0;
  fallen_volume_ = 0;
  lost_before_ = 0;
  frame_ = 0;
  last_ = StabilizeResult();
  restart_weather();
  if (!weather_ && settings_.snow_on_snow_every > 0) compute_coverage(nullptr);
}

void LiveSim::apply(const LiveSettings& settings) {
  check(settings);
  const LiveSettings old = settings_;
  settings_ = settings;
  try {
    if (!same(old.peel, settings.peel)) {
      peel();  // new maps, stabilizer and coverage; the snow restarts
      return;
    }
    if (!same(old.stabilize, settings.stabilize)) {
      const std::vector<float> lying = depth();
      const double lost =
          on_either(cpu_.get(), gpu_.get(), [](auto& s) { return s.lost_volume(); });
      make_stabilizer(maps_, &lying);
      on_either(cpu_.get(), gpu_.get(), [&](auto& s) { s.set_snow_amount(coverage_); });
      lost_before_ += lost;  // the new stabilizer counts from 0
      last_.converged = false;
    }
    if (old.weather != settings.weather) reset();  // the series starts over (or stops)
    if (!same(old.coverage, settings.coverage)) {
      if (weather_) weather_->stepper->forget();
      if (settings_.snow_on_snow_every > 0) {
        const std::vector<float> lying = depth();
        compute_coverage(&lying);
      } else {
        compute_coverage(nullptr);
      }
    }
  } catch (...) {
    settings_ = old;
    throw;
  }
}

}  // namespace snow::live
