#pragma once
// The live snowfall of the preview window: the batch stages (peel_layers,
// CoverageRenderer, Stabilizer or CpuStabilizer) with their state kept
// between frames. Each frame adds fresh snow in proportion to the coverage
// and runs a few stabilizer passes, so snow piles up, slides off roofs and
// drops to the ground while the viewer draws it (the physics is the batch
// job's: docs/ARCHITECTURE.md; Tokoi 2006 and Fearing 2000).
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "gl/objects.h"
#include "plan/rules.h"
#include "scene/scene.h"
#include "snow/cohesion.h"
#include "snow/coverage.h"
#include "snow/maps.h"
#include "snow/peel.h"
#include "snow/snowpack.h"
#include "snow/stabilize.h"
#include "snow/tracks.h"

namespace snow {
class CpuStabilizer;
struct WeatherRun;
}  // namespace snow

namespace snow::live {

struct LiveSettings {
  PeelSettings peel;            // maps (texel size, layers); a change re-peels and resets the snow
  CoverageSettings coverage;    // fall directions; a change recomputes the coverage
  StabilizeSettings stabilize;  // repose; a change rebuilds the stabilizer, keeping the snow.
                                // device: as in the batch job (auto: the CPU passes where
                                // GL is software, their depth uploaded for drawing)
  float total_depth = 0.3f;     // metres of fresh snow on open flat ground; snowfall stops there
  float fall_rate = 0.05f;      // metres of fresh snow per simulated second on open flat ground
  float frame_time = 1.0f / 30.0f;  // simulated seconds per frame (fixed: same frames, same snow)
  int add_every = 0;           // frames between snow additions, each adding that many frames' worth
                               // (routing runs after each addition: fewer, larger additions cost
                               // less); 0 = automatic (plan::preview_add_every)
  int passes_per_frame = 4;    // stabilizer relaxation passes per frame (>= 0)
  int snow_on_snow_every = 0;  // frames between coverage updates that include the lying snow
                               // (drifts shade what lies behind them); 0 = off
  SnowKind snow_kind = SnowKind::Fresh;  // its drift threshold (snow::drift_for_wind)
  bool wind_transport = true;            // a wind above the threshold moves each addition's snow
                                         // (snow/drift.h) before the passes
  // A weather series to play (snow/weather.h; its kind and wind_transport
  // apply): each frame moves its clock weather_speed * frame_time hours on
  // and applies the steps that end by then, as the batch job's --weather
  // does (snow/weather_step.h), the stabilizer's passes spread over frames.
  // Replaces fall_rate, total_depth (which then only sizes the view),
  // add_every, snow_on_snow_every and the coverage's wind. Null: a steady
  // snowfall.
  std::shared_ptr<const WeatherRun> weather;
  float weather_speed = 1.0f;  // weather hours per simulated second (0..1e4)
};

/// Wall seconds of the work of the last frame, by stage (with glFinish at
/// each boundary, so they are the GPU's time too).
struct LiveTimings {
  double add = 0;            // adding fresh snow
  double stabilize = 0;      // routing and relaxation passes
  double coverage = 0;       // coverage recomputed this frame (0 when not)
  double peel = 0;           // last re-peel (kept)
  double last_coverage = 0;  // last coverage computation (kept)
};

/// The simulation state. Needs the GL context that was current at
/// construction to be current in every call, including destruction.
class LiveSim {
 public:
  /// Peels the maps, computes the coverage and starts with no snow. Keeps a
  /// reference to `scene`, which must outlive the LiveSim.
  /// `receives[object]` == 0 keeps fresh snow off that object (may be empty).
  /// `gl`: what the window's GL renders on (the planner's choices of the
  /// stabilizer and the coverage depend on it).
  /// Throws InputError for bad settings, GLError for GL trouble.
  LiveSim(const Scene& scene, const LiveSettings& settings, const plan::GlFacts& gl,
          std::vector<uint8_t> receives = {});
  ~LiveSim();
  LiveSim(const LiveSim&) = delete;
  LiveSim& operator=(const LiveSim&) = delete;

  /// One frame: every add_every frames (add_every() when automatic) adds
  /// min(add_every * fall_rate *
  /// frame_time, what is left of total_depth) metres times the coverage and
  /// lets the wind move it (wind_transport), recomputes the coverage
  /// with the lying snow when snow_on_snow_every says so, and runs passes_per_frame stabilizer
  /// passes (none once nothing falls and the last passes converged: the snow is at rest).
  void step();
  /// Removes all snow; the fallen depth and frame count restart at 0 (a
  /// weather series from its first hour).
  void reset();
  /// Weather series only: plays forward to `hour` (clamped to the series'
  /// span), applying the steps that end by then at once; an earlier hour
  /// restarts from the first step and plays forward to it.
  void seek(double hour);
  /// Applies new settings: re-peels (and resets the snow) when the maps'
  /// settings changed, recomputes the coverage when the coverage settings
  /// changed, rebuilds the stabilizer with the current snow when its
  /// settings changed. Throws like the constructor; the old state is kept
  /// when it throws.
  void apply(const LiveSettings& settings);

  const LiveSettings& settings() const { return settings_; }
  /// Frames between snow additions: settings().add_every, or the planner's
  /// where that is 0.
  int add_every() const;
  const SnowMaps& maps() const { return maps_; }
  const std::vector<float>& coverage() const { return coverage_; }
  /// The snow depth as a GL_TEXTURE_2D_ARRAY, one layer per map layer, r =
  /// depth in metres (the GPU stabilizer's own texture, or the CPU
  /// stabilizer's depth uploaded after each change); valid until the next
  /// step, reset or apply.
  unsigned depth_texture() const;
  /// Current snow depth (metres per layer texel; a full readback).
  std::vector<float> depth() const;
  /// m^3 of snow that left the maps since the last reset or re-peel (the
  /// wind's included).
  double lost_volume() const;
  /// The stabilizer runs on the CPU (settings.stabilize.device).
  bool stabilizes_on_cpu() const { return cpu_ != nullptr; }
  const StabilizeResult& last_result() const { return last_; }
  const LiveTimings& timings() const { return timings_; }

  /// Whether snow falls now (a steady snowfall short of its total, or the
  /// weather step under way holding snow).
  bool snowing() const;
  /// The wind the flakes fall in now (m/s, x and z).
  glm::vec2 fall_wind() const;
  /// Weather series only (null otherwise): the snowpack as of the last step
  /// applied, the clock (hours of the series) and the step under way (null
  /// past the end).
  const SnowPack* snowpack() const;
  double weather_hour() const;
  const WeatherStep* weather_now() const;
  /// Hours of weather behind snowpack(): the end of the last step applied.
  double snowpack_hour() const;
  /// Weather series: turns what the passes moved since the last step into
  /// the snowpack's water (account_moves; a full readback), so snowpack()
  /// holds the snow drawn.
  void sync_snowpack();

  /// Presses `sources` into the snow lying now (snow/tracks.h's
  /// make_tracks; a weather series' snowpack, else the snow at
  /// kSettledSnowDensity); the stabilizer goes on from there, the tracks'
  /// snow held where it lies. A full readback and upload.
  TrackResult make_tracks(const std::vector<TrackSource>& sources, const TrackSettings& settings);
  /// Where the ray from `origin` along `direction` (world, metres) first
  /// meets the top of the snow or of the highest surface (layer 0), marched
  /// at half a texel over the maps; nothing where it misses them. A full
  /// readback.
  std::optional<glm::vec3> pick(glm::vec3 origin, glm::vec3 direction) const;
  /// The preview's brush: a disc of `radius` metres pressed
  /// (or cleared) where pick() finds the snow along the ray, on one
  /// readback; nothing where the ray misses the maps.
  std::optional<TrackResult> brush(glm::vec3 origin, glm::vec3 direction, float radius,
                                   TrackMode mode, const TrackSettings& settings);

  float fallen_depth() const { return fallen_depth_; }  // metres fallen on open flat ground
  /// m^3 of fresh snow added, and drifted in over the maps' border.
  double fallen_volume() const { return fallen_volume_; }
  int64_t frame() const { return frame_; }  // frames stepped since reset
  /// Incremented whenever the maps change (re-peel) or the coverage does.
  uint64_t maps_version() const { return maps_version_; }
  uint64_t coverage_version() const { return coverage_version_; }

 private:
  void peel();
  void compute_coverage(const std::vector<float>* lying);
  /// Replaces the stabilizer by one for `maps` and settings_.stabilize
  /// holding `depth` (null: no snow); keeps the old one when it throws.
  void make_stabilizer(const SnowMaps& maps, const std::vector<float>* depth);
  /// The CPU stabilizer's depth (on `maps`) into cpu_depth_ (nothing for
  /// the GPU's).
  void upload_depth(const SnowMaps& maps);
  /// The stabilizer's depth replaced by `depth` (what it lost so far kept in
  /// lost_before_) and uploaded for drawing.
  void replace_depth(const std::vector<float>& depth);
  /// The relaxation passes of a frame (none when nothing fell and the last
  /// passes converged); `fell`: snow was added this frame.
  void relax(bool fell);
  /// make_tracks on `lying`, the depth just read back.
  TrackResult press(const std::vector<float>& lying, const std::vector<TrackSource>& sources,
                    const TrackSettings& settings);
  /// pick on `lying`.
  std::optional<glm::vec3> hit(const std::vector<float>& lying, glm::vec3 origin,
                               glm::vec3 direction) const;
  // The weather series' part (live_weather.cpp).
  struct Weather;
  void restart_weather();
  void step_weather();
  void play_weather_to(double hour);

  const Scene& scene_;
  plan::GlFacts gl_;
  LiveSettings settings_;
  std::vector<uint8_t> receives_;
  SnowMaps maps_;
  std::unique_ptr<CoverageRenderer> shadows_;
  std::unique_ptr<Stabilizer> gpu_;     // one of these two is set
  std::unique_ptr<CpuStabilizer> cpu_;  //
  gl::Texture cpu_depth_;               // R32F array: cpu_'s depth, for drawing
  std::vector<float> coverage_;
  double coverage_area_ = 0;  // sum of coverage * texel area (m^2): volume per metre of fall
  StabilizeResult last_;
  LiveTimings timings_;
  float fallen_depth_ = 0;
  double fallen_volume_ = 0;
  double lost_before_ = 0;  // m^3 lost before the stabilizer's last set_depth, and drifted out
  int64_t frame_ = 0;
  uint64_t maps_version_ = 0;
  uint64_t coverage_version_ = 0;
  std::unique_ptr<Weather> weather_;  // set while settings_.weather is
};

}  // namespace snow::live
