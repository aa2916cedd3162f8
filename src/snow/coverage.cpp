// Stage 2: snow coverage from jittered multi-direction shadow maps.
// Tokoi, "A Shadow Buffer Technique for Simulating Snow-Covered Shapes"
// (2006), section 4 (shadow buffers from many directions, composited);
// flake flutter and wind after Fearing, "Computer Modelling of Fallen Snow"
// (SIGGRAPH 2000), section 4.1. Direction sampling: stratified in cos(angle)
// with a golden-ratio azimuth sequence (a jittered spherical Fibonacci
// pattern), uniform in solid angle over the cone. Shadow-map comparison with
// a receiver-plane depth bias (Isidoro, "Shadow Mapping: GPU-based Tips and
// Techniques", GDC 2006); uncertain texels resolved by exact ray casting
// through a BVH (shaders/coverage_common.glsl explains the two passes).
#include "snow/coverage.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <numeric>
#include <optional>
#include <string>

#include <glm/gtc/packing.hpp>

#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "shaders/bindings.h"
#include "snow/bvh.h"
#include "snow/coverage/internal.h"
#include "snow/gpu_scene.h"
#include "snow/reference/coverage_ref.h"

namespace snow {

using cov::kMaxBatch;
using cov::receiver_height;
using cov::receiver_point;
using cov::receiver_texel;
using cov::ShadowFrame;

namespace {

constexpr float kNoSnowSurface = -3.0e38f;  // "no surface" in the snow-surface texture
constexpr int kLocalSize = 64;              // coverage.comp's local_size_x
constexpr int kMaxShadowSide = 16384;       // texels, also capped by GL_MAX_TEXTURE_SIZE

std::string seconds(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f s", v);
  return text;
}

// Uploads the batch's direction parameters to `batch_directions[]`.
void set_batch_directions(const gl::Program& program, const glm::vec4* params, int n) {
  const GLint location = glGetUniformLocation(program.id(), "batch_directions");
  glProgramUniform4fv(program.id(), location, n, &params[0].x);
  program.set("direction_count", n);
}

}  // namespace

int shadow_batch(const CoverageSettings& settings, double shadow_texels) {
  return plan::choose_shadow_batch(settings.batch, settings.directions, shadow_texels, kMaxBatch);
}

// --- CoverageRenderer --------------------------------------------------------

namespace {

// The GL side of a CoverageRenderer: programs, the scene's buffers, shadow
// maps and the passes' buffers. Made on the first compute that draws shadow
// maps or casts rays on the GPU: runs whose rays are cast on the CPU upload
// nothing (ToyCar: 0.04 s; a 1M-triangle terrain's shadow-pass vertices
// and indices).
struct GpuSide {
  // One buffer of triangles in BVH leaf order, ray cast by the exact pass
  // (storage buffer); the shadow passes draw `vertices` (welded, or those
  // corners) through an index buffer in the same order.
  GpuSide(const Bvh& bvh, const std::vector<glm::vec3>& vertices,
          const std::vector<uint32_t>& indices)
      : shadow({"shadow.vert", "depth_only.frag"}),
        shadow_snow({"shadow_snow.vert", "depth_only.frag"}),
        count({"coverage.comp"}),
        count_snow({"coverage_snow.comp"}),
        exact({"coverage_exact.comp"}),
        exact_snow({"coverage_exact_snow.comp"}),
        dispatch({"coverage_dispatch.comp"}),
        vao(gl::create_vertex_array()),
        empty_vao(gl::create_vertex_array()),
        triangles(bvh.triangle_count()) {
    if (triangles == 0) return;
    triangle_buffer = gl::create_buffer();
    glNamedBufferStorage(triangle_buffer.id(), GLsizeiptr(bvh.corners().size() * sizeof(glm::vec3)),
                         bvh.corners().data(), 0);
    gl::check_error("coverage scene triangles");
    nodes = bvh.nodes().size();
    node_buffer = gl::create_buffer();
    glNamedBufferStorage(node_buffer.id(), GLsizeiptr(nodes * sizeof(Bvh::Node)),
                         bvh.nodes().data(), 0);
    gl::check_error("coverage scene BVH");
    vertex_buffer = gl::create_buffer();
    glNamedBufferStorage(vertex_buffer.id(), GLsizeiptr(vertices.size() * sizeof(glm::vec3)),
                         vertices.data(), 0);
    index_buffer = gl::create_buffer();
    glNamedBufferStorage(index_buffer.id(), GLsizeiptr(indices.size() * sizeof(uint32_t)),
                         indices.data(), 0);
    gl::check_error("coverage scene vertices");
    glVertexArrayVertexBuffer(vao.id(), 0, vertex_buffer.id(), 0, sizeof(glm::vec3));
    glVertexArrayElementBuffer(vao.id(), index_buffer.id());
    glEnableVertexArrayAttrib(vao.id(), SNOW_ATTR_POSITION);
    glVertexArrayAttribFormat(vao.id(), SNOW_ATTR_POSITION, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao.id(), SNOW_ATTR_POSITION, 0);
    gl::check_error("coverage scene vertex array");
  }

  gl::Program shadow;       // scene depth into a shadow map
  gl::Program shadow_snow;  // snow heightfield depth into a shadow map
  gl::Program count;        // pass 1: certain cases counted, the others queued
  gl::Program count_snow;   // the same with a snow surface in the shadow maps
  gl::Program exact;        // pass 2: exact ray casts of the queued pairs
  gl::Program exact_snow;
  gl::Program dispatch;  // queue length -> indirect dispatch size
  gl::VertexArray vao;
  gl::VertexArray empty_vao;
  gl::Buffer triangle_buffer;  // float[9] per triangle, BVH leaf order (exact pass)
  gl::Buffer node_buffer;      // Bvh::Node per node
  gl::Buffer vertex_buffer;    // the shadow passes' vertices
  gl::Buffer index_buffer;     // 3 per triangle, BVH leaf order
  size_t triangles = 0;
  size_t nodes = 0;

  // Shadow maps: one DEPTH32F array layer per direction of a batch.
  gl::Texture shadow_depth;
  glm::ivec2 shadow_size{0};
  int shadow_layers = 0;
  std::vector<gl::Framebuffer> fbos;
  gl::Texture snow_surface;  // RG32F array (top, depth)
  glm::ivec3 snow_size{0};
  gl::Buffer receivers, counts, queue, dispatch_args;

  void draw_scene() const {
    if (triangles == 0) return;
    glBindVertexArray(vao.id());
    glDrawElements(GL_TRIANGLES, GLsizei(triangles * 3), GL_UNSIGNED_INT, nullptr);
  }

  void ensure_shadow_maps(glm::ivec2 size, int layers) {
    if (shadow_depth && size == shadow_size && layers == shadow_layers) return;
    fbos.clear();
    shadow_depth.reset();
    shadow_depth = gl::create_texture_2d_array(GL_DEPTH_COMPONENT32F, size.x, size.y, layers,
                                               "coverage shadow maps");
    glTextureParameteri(shadow_depth.id(), GL_TEXTURE_COMPARE_MODE, GL_NONE);
    shadow_size = size;
    shadow_layers = layers;
    for (int k = 0; k < layers; ++k) {
      gl::Framebuffer fbo = gl::create_framebuffer();
      glNamedFramebufferTextureLayer(fbo.id(), GL_DEPTH_ATTACHMENT, shadow_depth.id(), 0, k);
      glNamedFramebufferDrawBuffer(fbo.id(), GL_NONE);
      glNamedFramebufferReadBuffer(fbo.id(), GL_NONE);
      gl::check_framebuffer(fbo, "coverage shadow framebuffer");
      fbos.push_back(std::move(fbo));
    }
  }

  static void upload(gl::Buffer& buffer, const void* data, size_t bytes, const char* what) {
    if (!buffer) buffer = gl::create_buffer();
    glNamedBufferData(buffer.id(), GLsizeiptr(std::max<size_t>(bytes, 4)), data, GL_DYNAMIC_DRAW);
    gl::check_error(what);
  }
};

// The BVH for a scene of `triangles` whose coverage is computed on `maps`
// (plan::coverage_bvh_morton: its walks scale with the receivers, its build
// with the triangles).
Bvh::Build bvh_build_for(size_t triangles, const SnowMaps* maps) {
  if (!maps) return Bvh::Build::Sah;
  const size_t receivers = size_t(std::count_if(maps->ground.begin(), maps->ground.end(),
                                                [](float y) { return !std::isnan(y); }));
  return coverage_bvh_build(triangles, receivers);
}

}  // namespace

Bvh::Build coverage_bvh_build(size_t triangles, size_t receivers) {
  return plan::coverage_bvh_morton(triangles, receivers) ? Bvh::Build::Morton : Bvh::Build::Sah;
}

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
  GpuSide& gpu() {
    if (!gpu_side) {
      std::vector<glm::vec3> welded;
      std::vector<uint32_t> indices;
      const bool weld = plan::weld_shadow_vertices(gl_now);
      if (weld) {
        weld_vertices(bvh.corners(), welded, indices);
      } else {
        indices.resize(bvh.corners().size());
        std::iota(indices.begin(), indices.end(), 0u);
      }
      gpu_side = std::make_unique<GpuSide>(bvh, weld ? welded : bvh.corners(), indices);
    }
    return *gpu_side;
  }

  Bounds bounds;
  Bvh::Build build = Bvh::Build::Sah;
  Bvh bvh;  // the scene's triangles in leaf order, for the exact pass, CPU rays and sky culling
  size_t triangles = 0;
  std::unique_ptr<GpuSide> gpu_side;
  Timings timings;
  glm::ivec2 shadow_size{0};  // of the last compute's shadow maps (0 without)
  std::optional<plan::GlFacts> gl;  // as given by set_gl; else plan::current_gl() per compute
  plan::GlFacts gl_now;              // the facts of the compute running
  bool profiling = false;
  bool run_bounds = true;  // CPU shadow maps: runs of receivers settled at once, and only
                           // the triangles they read drawn
};

CoverageRenderer::CoverageRenderer(const Scene& scene, const SnowMaps* maps) {
  try {
    impl_ = std::make_unique<Impl>(
        scene, build_coverage_bvh(scene, bvh_build_for(scene.triangle_count(), maps)));
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory uploading " + std::to_string(scene.triangle_count()) +
                     " triangles");
  }
}

CoverageRenderer::CoverageRenderer(const Scene& scene, CoverageBvh bvh)
    : impl_(std::make_unique<Impl>(scene, std::move(bvh))) {}
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
  const double t_start = now_seconds();
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
  // From here: the stage's time includes finding and culling the receivers
  // (about 1 s of a 2048 map), not only the shadow passes.
  Progress progress("coverage", double(dirs.size()));

  std::vector<float> coverage;
  cov::Receivers receivers;
  try {
    coverage.assign(total, 0.0f);
    if (total > size_t(std::numeric_limits<uint32_t>::max())) {
      throw InputError("coverage: more than 2^32 layer texels");
    }
    cov::list_receivers(maps, snow_depth, receivers);
  } catch (const std::bad_alloc&) {
    throw InputError("coverage: out of memory for " + std::to_string(total) +
                     " layer texels; use a coarser texel size");
  }
  std::vector<glm::uvec4>& recv = receivers.recv;
  std::vector<uint32_t>& recv_index = receivers.recv_index;
  const std::vector<float>& top = receivers.top;
  const std::vector<int>& snowy_layers = receivers.snowy_layers;
  const std::vector<glm::ivec4>& snowy_quads = receivers.snowy_quads;
  float y_lo = receivers.y_lo, y_hi = receivers.y_hi;
  log_debug("coverage: " + std::to_string(recv.size()) + " receivers listed in " +
            seconds(now_seconds() - t_start));
  if (recv.empty()) return coverage;
  if (recv.size() > size_t(std::numeric_limits<int32_t>::max())) {
    throw InputError("coverage: " + std::to_string(recv.size()) +
                     " surface texels, more than 2^31; use a coarser texel size");
  }

  // Depth range: the scene and every receiver (snow tops may rise above the scene).
  const float scene_lo = im.bounds.empty() ? y_lo : std::min(im.bounds.min.y, y_lo);
  const float scene_hi = im.bounds.empty() ? y_hi : std::max(im.bounds.max.y, y_hi);
  const double pad = 1e-3 * std::max(1.0, double(scene_hi) - scene_lo) + 1e-3;
  const float y_top = float(scene_hi + pad);
  const float y_range = float(double(scene_hi) - scene_lo + 2 * pad);
  const float bias =
      settings.bias >= 0.0f ? settings.bias : float(0.25 * grid.texel + 1e-5 * y_range);

  CoverageWork work;  // for choose_coverage_method: drawn per shadow map, the scene and
                      // two triangles per snowy quad
  work.triangles = double(im.triangles);
  for (const glm::ivec4& q : snowy_quads) work.triangles += 2.0 * (q.y - q.x) * (q.w - q.z);
  work.snow = !snowy_layers.empty();
  im.gl_now = im.gl ? *im.gl : plan::current_gl();
  work.software = im.gl_now.software;
  work.gl_cold = !im.gl_now.software && !im.gl_now.started;
  CoverageMethod method = CoverageMethod::ShadowMaps;

  // Receivers open to the sky along every direction are lit without GPU work.
  glm::ivec4 texel_box(0, 0, grid.width - 1, grid.height - 1);  // the others' (i, j) bounds
  double tan_max = 0;                                           // of the fall directions
  {
    tan_max = cov::steepest_tan(dirs);
    const std::vector<uint8_t> culled =
        cov::cull_receivers(im.bvh, maps, snow_depth ? &top : nullptr, recv, recv_index, tan_max);
    // The receivers left: their count, heights and texel box (about a
    // shadow map's), from which the method is chosen.
    y_lo = kOpenSky;
    y_hi = -kOpenSky;
    texel_box = glm::ivec4(grid.width, grid.height, -1, -1);
    for (size_t r = 0; r < recv.size(); ++r) {
      if (culled[r]) continue;
      ++work.receivers;
      const float y = receiver_height(recv[r]);
      y_lo = std::min(y_lo, y);
      y_hi = std::max(y_hi, y);
      const glm::ivec2 t = receiver_texel(recv[r]);
      texel_box = glm::ivec4(glm::min(glm::ivec2(texel_box), t),
                             glm::max(glm::ivec2(texel_box.z, texel_box.w), t));
    }
    work.shadow_texels = double(std::max(texel_box.z - texel_box.x + 1, 0)) *
                         double(std::max(texel_box.w - texel_box.y + 1, 0));
    if ((work.software || work.gl_cold) && !work.snow && work.receivers > 0) {
      const double reach = tan_max * std::max(0.0, double(scene_hi) - double(y_lo));
      work.drawn = double(cov::triangles_near_receivers(im.bvh, grid, recv, culled, reach));
    }
    method = choose_coverage_method(settings, work);
    cov::drop_culled(culled, recv, recv_index, coverage);
    im.timings.culled = culled.size() - recv.size();
    im.timings.shaded = size_t(std::count(culled.begin(), culled.end(), cov::kShaded));
  }
  im.timings.method = method;
  if (recv.empty()) return coverage;
  if (method == CoverageMethod::CpuRays) {
    log_debug("coverage: " + std::to_string(recv.size()) +
              " receivers neither open to the sky nor under a solid, every line cast on the CPU");
    cov::cast_rays_on_cpu(im.bvh, maps, dirs, snow_depth, recv, recv_index, coverage, progress);
    im.timings.shadow = now_seconds() - t_start;
    im.timings.pairs = uint64_t(recv.size()) * uint64_t(dirs.size());
    progress.finish();
    return coverage;
  }
  const bool on_cpu = method == CoverageMethod::CpuShadowMaps;

  // Shadow-map regions: each direction's map covers the remaining
  // receivers' box projected along it, origin jittered by a sub-texel offset.
  GLint max_texture = 0;
  if (!on_cpu) {
    gl::require_context();
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_texture);
  }
  const int limit = std::min(kMaxShadowSide, max_texture > 0 ? int(max_texture) : kMaxShadowSide);
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
  std::vector<glm::vec4> dir_params(k_count);
  std::vector<ShadowFrame> frames(k_count);
  for (size_t k = 0; k < k_count; ++k) {
    const double a = shear[k].x, b = shear[k].y;
    const double u_min = gx0 - std::max(a * y_lo, a * y_hi);
    const double v_min = gz0 - std::max(b * y_lo, b * y_hi);
    dir_params[k] = glm::vec4(float(a), float(b), float(u_min - jitter[k].x * st),
                              float(v_min - jitter[k].y * st));
    frames[k] = ShadowFrame{glm::dvec4(dir_params[k]), st, size};
  }
  if (method != CoverageMethod::GpuRays) im.shadow_size = size;
  const bool rays = method == CoverageMethod::GpuRays;
  log_debug("coverage: " + std::to_string(recv.size()) +
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
    const cov::CpuShadowMapCounts counts =
        cov::shadow_maps_on_cpu(im.bvh, maps, dirs, frames, bias, snow_depth, recv, recv_index,
                                im.run_bounds, plan::kCpuShadowBytes, coverage, progress);
    im.timings.queued = counts.uncertain;
    im.timings.settled = counts.settled;
    im.timings.left_out = counts.left_out;
    im.timings.shadow = now_seconds() - t_start;
    im.timings.pairs = uint64_t(recv.size()) * uint64_t(k_count);
    char line[200];
    std::snprintf(
        line, sizeof line,
        "coverage: %.0f %% of the pairs settled by runs of receivers, %.0f %% cast "
        "exactly; %.0f %% of the triangles left out of the maps",
        100.0 * double(im.timings.settled) / double(im.timings.pairs),
        100.0 * double(im.timings.queued) / double(im.timings.pairs),
        100.0 * double(im.timings.left_out) / std::max(1.0, work.triangles * double(k_count)));
    log_debug(line);
    progress.finish();
    return coverage;
  }
  GpuSide& gpu = im.gpu();
  const int batch = rays ? std::min(kMaxBatch, settings.directions)
                         : shadow_batch(settings, double(size.x) * double(size.y));

  GlStateGuard state;
  if (!rays) gpu.ensure_shadow_maps(size, batch);
  GpuSide::upload(gpu.receivers, recv.data(), recv.size() * sizeof(glm::uvec4),
                  "coverage receivers");
  GpuSide::upload(gpu.counts, nullptr, recv.size() * sizeof(uint32_t), "coverage counts");
  const GLuint zero = 0;
  glClearNamedBufferData(gpu.counts.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
  // Queue of receivers with uncertain directions: a 16-byte header (the
  // count), then up to one (receiver, direction mask) entry per receiver.
  GpuSide::upload(gpu.queue, nullptr, 16 + recv.size() * sizeof(glm::uvec2), "coverage queue");
  const GLuint dispatch_init[4] = {1, 1, 1, 0};
  GpuSide::upload(gpu.dispatch_args, dispatch_init, sizeof dispatch_init, "coverage dispatch");
  if (!snowy_layers.empty()) {
    std::vector<glm::vec2> surface(total);
    for (size_t k = 0; k < total; ++k) {
      const float s = (*snow_depth)[k];
      surface[k] = std::isnan(top[k]) ? glm::vec2(kNoSnowSurface, 0.0f)
                                      : glm::vec2(top[k], std::isfinite(s) && s > 0.0f ? s : 0.0f);
    }
    const glm::ivec3 snow_size(grid.width, grid.height, maps.layers);
    if (!gpu.snow_surface || gpu.snow_size != snow_size) {
      gpu.snow_surface.reset();
      gpu.snow_surface = gl::create_texture_2d_array(GL_RG32F, grid.width, grid.height, maps.layers,
                                                     "coverage snow surface");
      gpu.snow_size = snow_size;
    }
    glTextureSubImage3D(gpu.snow_surface.id(), 0, 0, 0, 0, grid.width, grid.height, maps.layers,
                        GL_RG, GL_FLOAT, surface.data());
    gl::check_error("coverage snow surface upload");
  }

  const glm::vec2 map_extent(float(size.x * st), float(size.y * st));
  for (gl::Program* p : {&gpu.shadow, &gpu.shadow_snow}) {
    p->set("map_extent", map_extent);
    p->set("y_top", y_top);
    p->set("y_range", y_range);
  }
  gpu.shadow_snow.set("grid_origin", grid.origin);
  gpu.shadow_snow.set("texel", grid.texel);
  gpu.shadow_snow.set("cut", kSnowSurfaceCutTexels * grid.texel);
  const bool snow = !snowy_layers.empty();
  gl::Program& count = snow ? gpu.count_snow : gpu.count;
  gl::Program& exact = snow ? gpu.exact_snow : gpu.exact;
  for (gl::Program* p : {&count, &exact}) {
    p->set("grid_origin", grid.origin);
    p->set("texel", grid.texel);
    p->set("shadow_texel", float(st));
    p->set("shadow_size", size);
    p->set("shadow_scale", glm::vec2(float(1.0 / (st * size.x)), float(1.0 / (st * size.y))));
    p->set("bias", bias);
    p->set("y_top", y_top);
    p->set("y_range", y_range);
  }
  count.set("receiver_count", int(recv.size()));
  exact.set("node_count", int(gpu.nodes));
  if (snow) {
    exact.set("grid_size", glm::ivec2(grid.width, grid.height));
    exact.set("cut", kSnowSurfaceCutTexels * grid.texel);
    std::vector<GLint> layers(snowy_layers.begin(), snowy_layers.end());
    std::vector<GLfloat> tops(layers.size(), -kOpenSky);
    for (size_t m = 0; m < layers.size(); ++m) {
      for (size_t t = 0; t < texels; ++t) {
        const float h = top[size_t(layers[m]) * texels + t];
        if (!std::isnan(h)) tops[m] = std::max(tops[m], h);
      }
    }
    exact.set("snow_layer_count", int(layers.size()));
    glProgramUniform1iv(exact.id(), glGetUniformLocation(exact.id(), "snow_layers"),
                        GLsizei(layers.size()), layers.data());
    glProgramUniform1fv(exact.id(), glGetUniformLocation(exact.id(), "snow_top"),
                        GLsizei(tops.size()), tops.data());
  }

  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  glViewport(0, 0, size.x, size.y);
  if (im.profiling) glFinish();
  double t_mark = now_seconds();
  im.timings.setup = t_mark - t_start;

  const int max_groups = 65535;
  uint32_t queued_mask = 0;  // rays: the direction mask of the queue uploaded last
  for (size_t b0 = 0; b0 < k_count; b0 += size_t(batch)) {
    const int n = int(std::min(size_t(batch), k_count - b0));
    for (int k = 0; k < n && !rays; ++k) {
      glBindFramebuffer(GL_FRAMEBUFFER, gpu.fbos[size_t(k)].id());
      const GLfloat clear_depth = 1.0f;
      glClearBufferfv(GL_DEPTH, 0, &clear_depth);
      gpu.shadow.set("shear_origin", dir_params[b0 + size_t(k)]);
      gpu.shadow.use();
      gpu.draw_scene();
      if (!snowy_layers.empty()) {
        gpu.shadow_snow.set("shear_origin", dir_params[b0 + size_t(k)]);
        gpu.shadow_snow.use();
        glBindTextureUnit(SNOW_SHADOW_SNOW_TEXTURE, gpu.snow_surface.id());
        glBindVertexArray(gpu.empty_vao.id());
        for (size_t m = 0; m < snowy_layers.size(); ++m) {
          const glm::ivec4& q = snowy_quads[m];
          gpu.shadow_snow.set("layer", snowy_layers[m]);
          gpu.shadow_snow.set("quad_origin", glm::ivec2(q.x, q.z));
          gpu.shadow_snow.set("quad_columns", q.y - q.x);
          glDrawArrays(GL_TRIANGLES, 0, 6 * (q.y - q.x) * (q.w - q.z));
        }
      }
    }
    gl::check_error("coverage shadow pass");
    if (im.profiling) {
      glFinish();
      const double t = now_seconds();
      im.timings.shadow += t - t_mark;
      t_mark = t;
    }
    if (!rays) glBindTextureUnit(SNOW_COVERAGE_SHADOW_TEXTURE, gpu.shadow_depth.id());
    if (snow) glBindTextureUnit(SNOW_COVERAGE_SNOW_TEXTURE, gpu.snow_surface.id());
    if (im.triangles > 0) {
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_BVH_NODES, gpu.node_buffer.id());
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_BVH_TRIANGLES,
                       gpu.triangle_buffer.id());
    }
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_RECEIVERS, gpu.receivers.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_COUNTS, gpu.counts.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_QUEUE, gpu.queue.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_DISPATCH, gpu.dispatch_args.id());
    if (rays) {
      // Every receiver queued with every direction of the batch.
      const uint32_t mask = n == 32 ? ~0u : (1u << n) - 1u;
      if (mask != queued_mask) {
        std::vector<glm::uvec2> queue(2 + recv.size(), glm::uvec2(0u));  // 16-byte header
        queue[0].x = uint32_t(recv.size());
        for (size_t r = 0; r < recv.size(); ++r) queue[2 + r] = glm::uvec2(uint32_t(r), mask);
        glNamedBufferSubData(gpu.queue.id(), 0, GLsizeiptr(queue.size() * sizeof(glm::uvec2)),
                             queue.data());
        queued_mask = mask;
      }
    } else {
      glClearNamedBufferSubData(gpu.queue.id(), GL_R32UI, 0, 4, GL_RED_INTEGER, GL_UNSIGNED_INT,
                                &zero);
      // Pass 1: certain cases counted, uncertain ones queued.
      count.use();
      set_batch_directions(count, &dir_params[b0], n);
      for (size_t first = 0; first < recv.size(); first += size_t(max_groups) * kLocalSize) {
        const size_t left = recv.size() - first;
        const GLuint groups =
            GLuint(std::min<size_t>(max_groups, (left + kLocalSize - 1) / kLocalSize));
        count.set("first_receiver", int(first));
        glDispatchCompute(groups, 1, 1);
      }
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      gpu.dispatch.use();
      glDispatchCompute(1, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
    }
    // Pass 2: exact tests of the queue, sized on the GPU (no readback).
    exact.use();
    set_batch_directions(exact, &dir_params[b0], n);
    if (rays) {
      glDispatchCompute(
          GLuint(std::min<size_t>(max_groups, (recv.size() + kLocalSize - 1) / kLocalSize)), 1, 1);
    } else {
      glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, gpu.dispatch_args.id());
      glDispatchComputeIndirect(0);
      glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
    }
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    gl::check_error("coverage counting pass");
    im.timings.pairs += uint64_t(recv.size()) * uint64_t(n);
    if (im.profiling) {
      GLuint queued = 0;
      glGetNamedBufferSubData(gpu.queue.id(), 0, sizeof queued, &queued);
      im.timings.queued += queued;
      const double t = now_seconds();
      im.timings.composite += t - t_mark;
      t_mark = t;
    }
    progress.update(double(b0 + size_t(n)));
  }
  if (!im.profiling) {
    glFinish();
    const double t = now_seconds();
    im.timings.shadow = t - t_mark;  // shadow and counting together when not profiling
    t_mark = t;
  }

  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<uint32_t> counts(recv.size());
  glGetNamedBufferSubData(gpu.counts.id(), 0, GLsizeiptr(counts.size() * sizeof(uint32_t)),
                          counts.data());
  gl::check_error("coverage readback");
  glBindTextureUnit(SNOW_COVERAGE_SHADOW_TEXTURE, 0);
  glBindTextureUnit(SNOW_COVERAGE_SNOW_TEXTURE, 0);
  glBindTextureUnit(SNOW_SHADOW_SNOW_TEXTURE, 0);
  for (size_t r = 0; r < counts.size(); ++r) {
    coverage[recv_index[r]] =
        float(std::min<uint32_t>(counts[r], uint32_t(k_count))) / float(k_count);
  }
  progress.finish();
  im.timings.readback = now_seconds() - t_mark;
  return coverage;
}

std::vector<float> compute_coverage(const Scene& scene, const SnowMaps& maps,
                                    const CoverageSettings& settings,
                                    const std::vector<float>* snow_depth) {
  CoverageRenderer renderer(scene);
  return renderer.compute(maps, settings, snow_depth);
}

}  // namespace snow
