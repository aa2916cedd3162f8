// Stage 2: snow coverage from jittered multi-direction shadow maps.
// Tokoi, "A Shadow Buffer Technique for Simulating Snow-Covered Shapes"
// (2006), section 4 (shadow buffers from many directions, composited);
// flake flutter and wind after Fearing, "Computer Modelling of Fallen Snow"
// (SIGGRAPH 2000), section 4.1 (directions.cpp).
//
// CoverageRenderer::compute in steps: check the inputs, list the receivers
// (receivers.cpp), settle those lit or shaded along every direction
// (sky_cull.cpp), choose the method for the work left through the plan
// (plan::choose_coverage_method), and run it: CPU rays (cpu_rays.cpp), CPU
// shadow maps (cpu_shadow_maps.cpp), or shadow maps or rays on the GPU
// (gpu.cpp). docs/ARCHITECTURE.md ("Coverage") shows the methods side by side.
#include "snow/coverage.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "snow/bvh.h"
#include "snow/coverage/gpu.h"
#include "snow/coverage/internal.h"
#include "snow/gpu_scene.h"

namespace snow {
namespace {

using cov::Receivers;
using cov::ShadowFrame;

constexpr int kMaxShadowSide = 16384;  // texels, also capped by GL_MAX_TEXTURE_SIZE

std::string seconds(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f s", v);
  return text;
}

// Throws InputError for what compute() does not take (coverage.h).
void check_inputs(const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
                  const std::vector<glm::vec2>& jitter, const CoverageSettings& settings,
                  const std::vector<float>* snow_depth) {
  cov::validate_settings(settings);
  if (dirs.empty() || jitter.size() != dirs.size()) {
    throw InputError("coverage: " + std::to_string(dirs.size()) + " directions and " +
                     std::to_string(jitter.size()) + " shadow-origin offsets");
  }
  for (const glm::vec3& d : dirs) {
    if (!(d.y < -0.2f) || !std::isfinite(d.x) || !std::isfinite(d.z)) {
      throw InputError(
          "coverage: a fall direction points less than 11.5 degrees below the horizon");
    }
  }
  const MapGrid& grid = maps.grid;
  const size_t texels = grid.texels();
  const size_t total = size_t(std::max(maps.layers, 0)) * texels;
  if (maps.ground.size() != total || maps.normal.size() != total || grid.width < 1 ||
      grid.height < 1 || !(grid.texel > 0.0f)) {
    throw InputError("coverage: the snow maps are inconsistent (arrays do not match the grid)");
  }
  if (grid.width > 65536 || grid.height > 65536) {
    throw InputError("coverage: maps wider than 65536 texels are not supported");
  }
  if (snow_depth && snow_depth->size() != total) {
    throw InputError("coverage: snow depth has " + std::to_string(snow_depth->size()) +
                     " values, the maps have " + std::to_string(total));
  }
}

// The BVH for a scene of `triangles` whose coverage is computed on `maps`
// (plan::coverage_bvh_morton: its walks scale with the receivers, its build
// with the triangles).
Bvh::Build bvh_build_for(size_t triangles, const SnowMaps* maps) {
  if (!maps) return Bvh::Build::Sah;
  const size_t receivers = size_t(std::count_if(maps->ground.begin(), maps->ground.end(),
                                                [](float y) { return !std::isnan(y); }));
  return coverage_bvh_build(triangles, receivers);
}

// One compute(): its inputs, and what each step hands the next.
struct Job {
  const SnowMaps& maps;
  const std::vector<glm::vec3>& dirs;
  const std::vector<glm::vec2>& jitter;
  const CoverageSettings& settings;
  const std::vector<float>* snow_depth;
  double t_start;               // now_seconds() at the start
  std::vector<float> coverage;  // the result, per layer texel
  Receivers receivers;          // every receiver, then those the sky cull left
  float scene_hi = 0;           // metres, the top of the scene and every receiver
  float y_top = 0;              // metres, the top of the shadow maps' depth range
  float y_range = 0;            // metres, its height
  float bias = 0;               // metres, the receiver-plane depth bias
  double tan_max = 0;           // of the fall directions
  float y_lo = 0, y_hi = 0;     // metres, the heights of the receivers left
  glm::ivec4 texel_box{0};      // (i, j) bounds of the receivers left
  CoverageWork work;            // what choose_coverage_method weighs
  CoverageMethod method = CoverageMethod::ShadowMaps;
};

// Every receiver (receivers.cpp), and the coverage zeroed. Throws
// InputError when memory runs out.
void list_all_receivers(Job& job) {
  const size_t total = job.maps.ground.size();
  try {
    job.coverage.assign(total, 0.0f);
    if (total > size_t(std::numeric_limits<uint32_t>::max())) {
      throw InputError("coverage: more than 2^32 layer texels");
    }
    cov::list_receivers(job.maps, job.snow_depth, job.receivers);
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory for " + std::to_string(total) +
                     " layer texels; use a coarser texel size");
  }
  log_debug("coverage: " + std::to_string(job.receivers.recv.size()) + " receivers listed in " +
            seconds(now_seconds() - job.t_start));
}

// The shadow maps' depth range: the scene and every receiver (snow tops may
// rise above the scene); and the bias, settings.bias or automatic.
void set_depth_range(Job& job, const Bounds& bounds) {
  const float y_lo = job.receivers.y_lo, y_hi = job.receivers.y_hi;
  const float scene_lo = bounds.empty() ? y_lo : std::min(bounds.min.y, y_lo);
  const float scene_hi = bounds.empty() ? y_hi : std::max(bounds.max.y, y_hi);
  const double pad = 1e-3 * std::max(1.0, double(scene_hi) - scene_lo) + 1e-3;
  job.scene_hi = scene_hi;
  job.y_top = float(scene_hi + pad);
  job.y_range = float(double(scene_hi) - scene_lo + 2 * pad);
  job.bias = job.settings.bias >= 0.0f ? job.settings.bias
                                       : float(0.25 * job.maps.grid.texel + 1e-5 * job.y_range);
}

// The receivers the sky cull keeps: their count, heights and texel box
// (about a shadow map's), from which the method is chosen.
void measure_kept(Job& job, const std::vector<uint8_t>& culled) {
  const MapGrid& grid = job.maps.grid;
  const std::vector<glm::uvec4>& recv = job.receivers.recv;
  job.y_lo = kOpenSky;
  job.y_hi = -kOpenSky;
  glm::ivec4& texel_box = job.texel_box;
  texel_box = glm::ivec4(grid.width, grid.height, -1, -1);
  for (size_t r = 0; r < recv.size(); ++r) {
    if (culled[r]) continue;
    ++job.work.receivers;
    const float y = cov::receiver_height(recv[r]);
    job.y_lo = std::min(job.y_lo, y);
    job.y_hi = std::max(job.y_hi, y);
    const glm::ivec2 t = cov::receiver_texel(recv[r]);
    texel_box = glm::ivec4(glm::min(glm::ivec2(texel_box), t),
                           glm::max(glm::ivec2(texel_box.z, texel_box.w), t));
  }
  job.work.shadow_texels = double(std::max(texel_box.z - texel_box.x + 1, 0)) *
                           double(std::max(texel_box.w - texel_box.y + 1, 0));
}

// Each direction's shadow map: the box of the receivers left projected
// along it (a shear onto the horizontal plane), origin jittered by a
// sub-texel offset; texels of the snow map's size, coarser only where a
// map would be wider than `limit` texels.
std::vector<ShadowFrame> shadow_frames(const Job& job, int limit) {
  const MapGrid& grid = job.maps.grid;
  const std::vector<glm::vec3>& dirs = job.dirs;
  const glm::ivec4& texel_box = job.texel_box;
  const float y_lo = job.y_lo, y_hi = job.y_hi;
  const double gx0 = grid.origin.x + double(texel_box.x) * grid.texel;
  const double gz0 = grid.origin.y + double(texel_box.y) * grid.texel;
  const double gx1 = grid.origin.x + double(texel_box.z + 1) * grid.texel;
  const double gz1 = grid.origin.y + double(texel_box.w + 1) * grid.texel;
  const size_t k_count = dirs.size();
  std::vector<glm::dvec2> shear(k_count);
  double span_u = 0, span_v = 0;
  for (size_t k = 0; k < k_count; ++k) {
    shear[k] = glm::dvec2(double(dirs[k].x) / dirs[k].y, double(dirs[k].z) / dirs[k].y);
    span_u = std::max(span_u, gx1 - gx0 + std::abs(shear[k].x) * (double(y_hi) - y_lo));
    span_v = std::max(span_v, gz1 - gz0 + std::abs(shear[k].y) * (double(y_hi) - y_lo));
  }
  double st = grid.texel;
  const double longest = std::max(span_u, span_v);
  if (longest / st + 2 > limit) st = longest / (limit - 2);
  const glm::ivec2 size(int(std::ceil(span_u / st)) + 2, int(std::ceil(span_v / st)) + 2);
  std::vector<ShadowFrame> frames(k_count);
  for (size_t k = 0; k < k_count; ++k) {
    const double a = shear[k].x, b = shear[k].y;
    const double u_min = gx0 - std::max(a * y_lo, a * y_hi);
    const double v_min = gz0 - std::max(b * y_lo, b * y_hi);
    // The parameters as the GPU passes take them (floats).
    const glm::vec4 params(float(a), float(b), float(u_min - job.jitter[k].x * st),
                           float(v_min - job.jitter[k].y * st));
    frames[k] = ShadowFrame{glm::dvec4(params), st, size};
  }
  return frames;
}

}  // namespace

CoverageBvh build_coverage_bvh(const Scene& scene, Bvh::Build build) {
  if (scene.triangle_count() * 3 > size_t(0x7fffffff)) {
    throw InputError("scene has " + std::to_string(scene.triangle_count()) +
                     " triangles, more than one draw call can take");
  }
  const double t0 = now_seconds();
  CoverageBvh out;
  out.build = build;
  out.bvh = Bvh(scene.positions, build);
  out.seconds = now_seconds() - t0;
  return out;
}

struct CoverageRenderer::Impl {
  Impl(const Scene& scene, CoverageBvh built)
      : bounds(scene.bounds), build(built.build), bvh(std::move(built.bvh)) {
    triangles = bvh.triangle_count();
    log_debug("coverage: BVH of " + std::to_string(triangles) + " triangles in " +
              seconds(built.seconds));
  }

  // The GL side, made on first use. The shadow passes draw the triangles in
  // leaf order through an index buffer, their corners welded first where
  // the plan says so (plan::weld_shadow_vertices).
  cov::GpuSide& gpu() {
    if (!gpu_side) {
      gpu_side = std::make_unique<cov::GpuSide>(bvh, plan::weld_shadow_vertices(gl));
    }
    return *gpu_side;
  }

  void cull_and_choose(Job& job);
  void run_cpu_rays(Job& job, Progress& progress);
  void run_shadow_maps(Job& job, Progress& progress);
  void run_cpu_shadow_maps(Job& job, const std::vector<ShadowFrame>& frames, Progress& progress);
  void run_gpu(Job& job, const std::vector<ShadowFrame>& frames, Progress& progress);

  Bounds bounds;
  Bvh::Build build = Bvh::Build::Sah;
  Bvh bvh;  // the scene's triangles in leaf order, for the exact pass, CPU rays and sky culling
  size_t triangles = 0;
  std::unique_ptr<cov::GpuSide> gpu_side;
  Timings timings;
  glm::ivec2 shadow_size{0};  // of the last compute's shadow maps (0 without)
  plan::GlFacts gl;           // as the constructor or set_gl gave them
  bool profiling = false;
  bool run_bounds = true;  // CPU shadow maps: runs of receivers settled at once, and only
                           // the triangles they read drawn
};

// The sky cull, and the method chosen for the receivers it leaves (those
// culled get their coverage and leave job.receivers).
void CoverageRenderer::Impl::cull_and_choose(Job& job) {
  Receivers& rc = job.receivers;
  CoverageWork& work = job.work;  // drawn per shadow map: the scene and two triangles per
                                  // snowy quad
  work.triangles = double(triangles);
  for (const glm::ivec4& q : rc.snowy_quads) work.triangles += 2.0 * (q.y - q.x) * (q.w - q.z);
  work.snow = !rc.snowy_layers.empty();
  work.software = gl.software;
  work.gl_cold = !gl.software && !gl.started;
  job.tan_max = cov::steepest_tan(job.dirs);
  const std::vector<uint8_t> culled = cov::cull_receivers(
      bvh, job.maps, job.snow_depth ? &rc.top : nullptr, rc.recv, rc.recv_index, job.tan_max);
  measure_kept(job, culled);
  if ((work.software || work.gl_cold) && !work.snow && work.receivers > 0) {
    const double reach = job.tan_max * std::max(0.0, double(job.scene_hi) - double(job.y_lo));
    work.drawn = double(cov::triangles_near_receivers(bvh, job.maps.grid, rc.recv, culled, reach));
  }
  job.method = choose_coverage_method(job.settings, work);
  cov::drop_culled(culled, rc.recv, rc.recv_index, job.coverage);
  timings.culled = culled.size() - rc.recv.size();
  timings.shaded = size_t(std::count(culled.begin(), culled.end(), cov::kShaded));
}

void CoverageRenderer::Impl::run_cpu_rays(Job& job, Progress& progress) {
  const Receivers& rc = job.receivers;
  log_debug("coverage: " + std::to_string(rc.recv.size()) +
            " receivers neither open to the sky nor under a solid, every line cast on the CPU");
  cov::cast_rays_on_cpu(bvh, job.maps, job.dirs, job.snow_depth, rc.recv, rc.recv_index,
                        job.coverage, progress);
  timings.shadow = now_seconds() - job.t_start;
  timings.pairs = uint64_t(rc.recv.size()) * uint64_t(job.dirs.size());
  progress.finish();
}

// The methods with shadow maps (on the GPU or the CPU) and GPU rays: the
// maps' frames (GPU rays use their depth range alone), then the method.
void CoverageRenderer::Impl::run_shadow_maps(Job& job, Progress& progress) {
  const bool on_cpu = job.method == CoverageMethod::CpuShadowMaps;
  const bool rays = job.method == CoverageMethod::GpuRays;
  const int max_texture = on_cpu ? 0 : cov::max_texture_size();
  const int limit = std::min(kMaxShadowSide, max_texture > 0 ? max_texture : kMaxShadowSide);
  const std::vector<ShadowFrame> frames = shadow_frames(job, limit);
  const glm::ivec2 size = frames.front().size;
  if (!rays) shadow_size = size;
  const CoverageWork& work = job.work;
  log_debug("coverage: " + std::to_string(job.receivers.recv.size()) +
            " receivers neither open to the sky nor under a solid, " +
            std::to_string(size_t(work.triangles)) + " triangles per shadow map" +
            (on_cpu && work.drawn >= 0.0
                 ? " (about " + std::to_string(size_t(work.drawn)) + " near the receivers)"
                 : std::string()) +
            ": " +
            (rays ? "every line cast by the GPU"
                  : "shadow maps of " + std::to_string(size.x) + " x " + std::to_string(size.y) +
                        " texels" + (on_cpu ? " drawn on the CPU" : "")));
  if (on_cpu) {
    run_cpu_shadow_maps(job, frames, progress);
  } else {
    run_gpu(job, frames, progress);
  }
}

void CoverageRenderer::Impl::run_cpu_shadow_maps(Job& job, const std::vector<ShadowFrame>& frames,
                                                 Progress& progress) {
  const Receivers& rc = job.receivers;
  const size_t k_count = job.dirs.size();
  const cov::CpuShadowMapCounts counts = cov::shadow_maps_on_cpu(
      bvh, job.maps, job.dirs, frames, job.bias, job.snow_depth, rc.recv, rc.recv_index, run_bounds,
      plan::kCpuShadowBytes, job.coverage, progress);
  timings.queued = counts.uncertain;
  timings.settled = counts.settled;
  timings.left_out = counts.left_out;
  timings.shadow = now_seconds() - job.t_start;
  timings.pairs = uint64_t(rc.recv.size()) * uint64_t(k_count);
  char line[200];
  std::snprintf(
      line, sizeof line,
      "coverage: %.0f %% of the pairs settled by runs of receivers, %.0f %% cast "
      "exactly; %.0f %% of the triangles left out of the maps",
      100.0 * double(timings.settled) / double(timings.pairs),
      100.0 * double(timings.queued) / double(timings.pairs),
      100.0 * double(timings.left_out) / std::max(1.0, job.work.triangles * double(k_count)));
  log_debug(line);
  progress.finish();
}

void CoverageRenderer::Impl::run_gpu(Job& job, const std::vector<ShadowFrame>& frames,
                                     Progress& progress) {
  const bool rays = job.method == CoverageMethod::GpuRays;
  const glm::ivec2 size = frames.front().size;
  cov::GpuSide& side = gpu();
  const int batch = rays ? std::min(cov::kMaxBatch, job.settings.directions)
                         : shadow_batch(job.settings, double(size.x) * double(size.y));
  const cov::GpuJob gpu_job{job.maps, job.snow_depth, job.receivers, frames,
                            job.bias, job.y_top,      job.y_range,   batch,
                            rays,     profiling,      job.t_start};
  cov::count_on_gpu(side, gpu_job, job.coverage, timings, progress);
}

CoverageRenderer::CoverageRenderer(const Scene& scene, const plan::GlFacts& gl,
                                   const SnowMaps* maps) {
  try {
    impl_ = std::make_unique<Impl>(
        scene, build_coverage_bvh(scene, bvh_build_for(scene.triangle_count(), maps)));
    impl_->gl = gl;
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory uploading " + std::to_string(scene.triangle_count()) +
                     " triangles");
  }
}

CoverageRenderer::CoverageRenderer(const Scene& scene, CoverageBvh bvh, const plan::GlFacts& gl)
    : impl_(std::make_unique<Impl>(scene, std::move(bvh))) {
  impl_->gl = gl;
}

std::unique_ptr<CoverageRenderer> CoverageRenderer::make(const Scene& scene, const SnowMaps& maps,
                                                         const plan::GlFacts& gl,
                                                         CoverageBvh* bvh) {
  if (bvh) return std::make_unique<CoverageRenderer>(scene, std::move(*bvh), gl);
  return std::make_unique<CoverageRenderer>(scene, gl, &maps);
}
CoverageRenderer::~CoverageRenderer() = default;

const CoverageRenderer::Timings& CoverageRenderer::timings() const { return impl_->timings; }
void CoverageRenderer::set_profiling(bool on) { impl_->profiling = on; }
void CoverageRenderer::set_gl(const plan::GlFacts& gl) { impl_->gl = gl; }
void CoverageRenderer::set_run_bounds(bool on) { impl_->run_bounds = on; }
glm::ivec2 CoverageRenderer::shadow_map_size() const { return impl_->shadow_size; }
Bvh::Build CoverageRenderer::bvh_build() const { return impl_->build; }

std::vector<float> CoverageRenderer::compute(const SnowMaps& maps, const CoverageSettings& settings,
                                             const std::vector<float>* snow_depth) {
  return compute(maps, fall_directions(settings), shadow_origin_jitter(settings), settings,
                 snow_depth);
}

std::vector<float> CoverageRenderer::compute(const SnowMaps& maps,
                                             const std::vector<glm::vec3>& dirs,
                                             const std::vector<glm::vec2>& jitter,
                                             const CoverageSettings& settings,
                                             const std::vector<float>* snow_depth) {
  try {
    return compute_checked(maps, dirs, jitter, settings, snow_depth);
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory for maps of " + std::to_string(maps.grid.width) +
                     " x " + std::to_string(maps.grid.height) + " texels x " +
                     std::to_string(maps.layers) + " layers; use a coarser texel size");
  }
}

std::vector<float> CoverageRenderer::compute_checked(const SnowMaps& maps,
                                                     const std::vector<glm::vec3>& dirs,
                                                     const std::vector<glm::vec2>& jitter,
                                                     const CoverageSettings& settings,
                                                     const std::vector<float>* snow_depth) {
  Impl& im = *impl_;
  im.timings = Timings{};
  im.shadow_size = glm::ivec2(0);
  Job job{maps, dirs, jitter, settings, snow_depth, now_seconds()};
  check_inputs(maps, dirs, jitter, settings, snow_depth);
  // From here the stage's progress and time include finding and culling
  // the receivers, not only the method's passes.
  Progress progress("coverage", double(dirs.size()));
  list_all_receivers(job);
  const std::vector<glm::uvec4>& recv = job.receivers.recv;
  if (recv.empty()) return std::move(job.coverage);
  if (recv.size() > size_t(std::numeric_limits<int32_t>::max())) {
    throw InputError("coverage: " + std::to_string(recv.size()) +
                     " surface texels, more than 2^31; use a coarser texel size");
  }
  set_depth_range(job, im.bounds);
  im.cull_and_choose(job);
  im.timings.method = job.method;
  if (recv.empty()) return std::move(job.coverage);
  if (job.method == CoverageMethod::CpuRays) {
    im.run_cpu_rays(job, progress);
  } else {
    im.run_shadow_maps(job, progress);
  }
  return std::move(job.coverage);
}

std::vector<float> compute_coverage(const Scene& scene, const SnowMaps& maps,
                                    const CoverageSettings& settings, const plan::GlFacts& gl,
                                    const std::vector<float>* snow_depth) {
  CoverageRenderer renderer(scene, gl);
  return renderer.compute(maps, settings, snow_depth);
}

}  // namespace snow
