// libFuzzer target: load a scene from arbitrary bytes, then run the whole
// pipeline on tiny maps (16 x 16 texels, 2 layers, 4 directions): peel,
// coverage + snowfall + stabilizer (accumulate), polygonize. One GL context
// (EGL surfaceless llvmpipe by default) is created once per process. Bad
// input must end in an InputError; any other exception, crash, sanitizer
// report or hang is a finding. Results are checked for non-finite values
// and mass balance.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>

#include "core/error.h"
#include "core/log.h"
#include "fuzz_common.h"
#include "gl/context.h"
#include "mesh/polygonize.h"
#include "scene/load_gltf.h"
#include "snow/accumulate.h"
#include "snow/peel.h"

namespace {
std::unique_ptr<snow::gl::Context> g_context;
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  snow::set_log_level(snow::LogLevel::Quiet);
  g_context = snow::gl::create_context();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = snow::fuzz::write_input(data, size);
  snow::LoadSettings load;
  load.load_images = false;
  load.limits.max_triangles = 20'000;  // keep each run short on llvmpipe
  snow::Scene scene;
  try {
    scene = snow::load_scene(path, load);
  } catch (const snow::InputError&) {
    return 0;
  }
  // A few settings from the input's first bytes, within their documented ranges.
  const uint8_t b0 = size > 0 ? data[0] : 0, b1 = size > 1 ? data[size - 1] : 0;
  snow::PeelSettings peel;
  peel.max_side = 8 + (b0 & 15);  // 8..23 texels
  peel.layers = 1 + (b1 & 1);     // 1..2
  peel.memory_budget = uint64_t(512) << 20;
  snow::CoverageSettings coverage;
  coverage.directions = 4;
  coverage.batch = 4;
  coverage.wind = glm::vec2(float(b1 >> 4) - 8.0f, 0.0f);
  snow::StabilizeSettings stabilize;
  stabilize.max_iterations = 200;
  snow::AccumulateSettings accumulate;
  accumulate.fall_depth = 0.3f;
  accumulate.steps = 1 + ((b0 >> 4) & 1);
  accumulate.snow_on_snow_every = (b0 >> 5) & 1;
  accumulate.drift = snow::drift_for_wind(coverage.wind, snow::SnowKind::Fresh, 0.3f);
  snow::PolygonizeSettings polygonize;
  if (accumulate.drift.transport > 0.0f) {
    polygonize.cornice.direction = glm::normalize(accumulate.drift.direction);
    polygonize.cornice.length = 0.5f;
  }
  try {
    const snow::SnowMaps maps = snow::peel_layers(scene, peel, snow::plan::current_gl());
    const snow::SnowResult snow =
        snow::accumulate(scene, maps, coverage, stabilize, accumulate, snow::plan::current_gl());
    if (!std::isfinite(snow.volume) || snow.volume < -1e-6) __builtin_trap();
    // Mass: what lies plus what left is what fell (the wind's in and out included).
    if (std::abs(snow.volume + snow.lost_volume - snow.fallen_volume) >
        1e-3 * std::max(1.0, snow.fallen_volume))
      __builtin_trap();
    for (float d : snow.depth) {
      if (!std::isfinite(d) || d < -1e-4f) __builtin_trap();
    }
    for (float c : snow.coverage) {
      if (!(c >= 0.0f && c <= 1.0f)) __builtin_trap();
    }
    const auto patches = snow::polygonize(maps, snow.depth, scene, polygonize);
    for (const snow::SnowPatch& p : patches) {
      for (const glm::vec3& v : p.mesh.positions) {
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) __builtin_trap();
      }
      for (uint32_t i : p.mesh.indices) {
        if (i >= p.mesh.positions.size()) __builtin_trap();
      }
    }
  } catch (const snow::InputError&) {
  }
  return 0;
}
