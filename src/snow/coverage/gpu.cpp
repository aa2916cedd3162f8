// The GL side of the coverage stage: Tokoi's shadow buffers from many
// directions (Tokoi 2006, section 4) drawn in batches into a 2D array
// texture, a compute pass classifying every (receiver, direction) pair
// against the receiver's own plane (a receiver-plane depth bias: Isidoro,
// "Shadow Mapping: GPU-based Tips and Techniques", GDC 2006), and a second
// compute pass casting the uncertain pairs exactly through the scene's BVH
// (shaders/coverage_common.glsl explains the two passes). No readback
// until the end.
#include "snow/coverage/gpu.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

#include "core/log.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "shaders/bindings.h"
#include "snow/gpu_scene.h"

namespace snow::cov {
namespace {

constexpr float kNoSnowSurface = -3.0e38f;  // "no surface" in the snow-surface texture
constexpr int kLocalSize = 64;              // coverage.comp's local_size_x
constexpr int kMaxGroups = 65535;           // work groups per dispatch

// Uploads the batch's direction parameters to `batch_directions[]`.
void set_batch_directions(const gl::Program& program, const glm::vec4* params, int n) {
  const GLint location = glGetUniformLocation(program.id(), "batch_directions");
  glProgramUniform4fv(program.id(), location, n, &params[0].x);
  program.set("direction_count", n);
}

// The receivers, their counts (zeroed), the queue and the indirect
// dispatch's arguments.
void upload_receivers(GpuSide& gpu, const std::vector<glm::uvec4>& recv) {
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
}

// The snow surface as a texture array: (top, depth) per layer texel, top
// kNoSnowSurface where there is no surface.
void upload_snow_surface(GpuSide& gpu, const SnowMaps& maps, const std::vector<float>& snow_depth,
                         const std::vector<float>& top) {
  const MapGrid& grid = maps.grid;
  const size_t total = maps.ground.size();
  std::vector<glm::vec2> surface(total);
  for (size_t k = 0; k < total; ++k) {
    const float s = snow_depth[k];
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

// The shadow passes' uniforms.
void set_shadow_uniforms(GpuSide& gpu, const GpuJob& job) {
  const MapGrid& grid = job.maps.grid;
  const glm::ivec2 size = job.frames.front().size;
  const double st = job.frames.front().st;
  const glm::vec2 map_extent(float(size.x * st), float(size.y * st));
  for (gl::Program* p : {&gpu.shadow, &gpu.shadow_snow}) {
    p->set("map_extent", map_extent);
    p->set("y_top", job.y_top);
    p->set("y_range", job.y_range);
  }
  gpu.shadow_snow.set("grid_origin", grid.origin);
  gpu.shadow_snow.set("texel", grid.texel);
  gpu.shadow_snow.set("cut", kSnowSurfaceCutTexels * grid.texel);
}

// The counting passes' uniforms (count: pass 1, exact: pass 2; with a snow
// surface, their snow variants).
void set_pass_uniforms(const GpuSide& gpu, const GpuJob& job, gl::Program& count,
                       gl::Program& exact) {
  const MapGrid& grid = job.maps.grid;
  const glm::ivec2 size = job.frames.front().size;
  const double st = job.frames.front().st;
  for (gl::Program* p : {&count, &exact}) {
    p->set("grid_origin", grid.origin);
    p->set("texel", grid.texel);
    p->set("shadow_texel", float(st));
    p->set("shadow_size", size);
    p->set("shadow_scale", glm::vec2(float(1.0 / (st * size.x)), float(1.0 / (st * size.y))));
    p->set("bias", job.bias);
    p->set("y_top", job.y_top);
    p->set("y_range", job.y_range);
  }
  count.set("receiver_count", int(job.receivers.recv.size()));
  exact.set("node_count", int(gpu.nodes));
  if (job.receivers.snowy_layers.empty()) return;
  exact.set("grid_size", glm::ivec2(grid.width, grid.height));
  exact.set("cut", kSnowSurfaceCutTexels * grid.texel);
  const size_t texels = grid.texels();
  const std::vector<int>& snowy_layers = job.receivers.snowy_layers;
  std::vector<GLint> layers(snowy_layers.begin(), snowy_layers.end());
  std::vector<GLfloat> tops(layers.size(), -kOpenSky);
  for (size_t m = 0; m < layers.size(); ++m) {
    for (size_t t = 0; t < texels; ++t) {
      const float h = job.receivers.top[size_t(layers[m]) * texels + t];
      if (!std::isnan(h)) tops[m] = std::max(tops[m], h);
    }
  }
  exact.set("snow_layer_count", int(layers.size()));
  glProgramUniform1iv(exact.id(), glGetUniformLocation(exact.id(), "snow_layers"),
                      GLsizei(layers.size()), layers.data());
  glProgramUniform1fv(exact.id(), glGetUniformLocation(exact.id(), "snow_top"),
                      GLsizei(tops.size()), tops.data());
}

// Draws the n shadow maps of a batch (params: their directions'), the
// scene and the snow heightfield's quads into each.
void draw_shadow_maps(GpuSide& gpu, const GpuJob& job, const glm::vec4* params, int n) {
  const Receivers& rc = job.receivers;
  for (int k = 0; k < n; ++k) {
    glBindFramebuffer(GL_FRAMEBUFFER, gpu.fbos[size_t(k)].id());
    const GLfloat clear_depth = 1.0f;
    glClearBufferfv(GL_DEPTH, 0, &clear_depth);
    gpu.shadow.set("shear_origin", params[k]);
    gpu.shadow.use();
    gpu.draw_scene();
    if (rc.snowy_layers.empty()) continue;
    gpu.shadow_snow.set("shear_origin", params[k]);
    gpu.shadow_snow.use();
    glBindTextureUnit(SNOW_SHADOW_SNOW_TEXTURE, gpu.snow_surface.id());
    glBindVertexArray(gpu.empty_vao.id());
    for (size_t m = 0; m < rc.snowy_layers.size(); ++m) {
      const glm::ivec4& q = rc.snowy_quads[m];
      gpu.shadow_snow.set("layer", rc.snowy_layers[m]);
      gpu.shadow_snow.set("quad_origin", glm::ivec2(q.x, q.z));
      gpu.shadow_snow.set("quad_columns", q.y - q.x);
      glDrawArrays(GL_TRIANGLES, 0, 6 * (q.y - q.x) * (q.w - q.z));
    }
  }
}

// Binds what the counting passes read and write.
void bind_pass_inputs(const GpuSide& gpu, bool rays, bool snow) {
  if (!rays) glBindTextureUnit(SNOW_COVERAGE_SHADOW_TEXTURE, gpu.shadow_depth.id());
  if (snow) glBindTextureUnit(SNOW_COVERAGE_SNOW_TEXTURE, gpu.snow_surface.id());
  if (gpu.triangles > 0) {
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_BVH_NODES, gpu.node_buffer.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_BVH_TRIANGLES,
                     gpu.triangle_buffer.id());
  }
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_RECEIVERS, gpu.receivers.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_COUNTS, gpu.counts.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_QUEUE, gpu.queue.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_COVERAGE_DISPATCH, gpu.dispatch_args.id());
}

// CoverageMethod::GpuRays: every receiver queued with every direction of a
// batch of n (uploaded again only where the mask changes; `queued_mask`:
// the mask of the queue uploaded last).
void queue_every_receiver(GpuSide& gpu, size_t receivers, int n, uint32_t& queued_mask) {
  const uint32_t mask = n == 32 ? ~0u : (1u << n) - 1u;
  if (mask == queued_mask) return;
  std::vector<glm::uvec2> queue(2 + receivers, glm::uvec2(0u));  // 16-byte header
  queue[0].x = uint32_t(receivers);
  for (size_t r = 0; r < receivers; ++r) queue[2 + r] = glm::uvec2(uint32_t(r), mask);
  glNamedBufferSubData(gpu.queue.id(), 0, GLsizeiptr(queue.size() * sizeof(glm::uvec2)),
                       queue.data());
  queued_mask = mask;
}

// Pass 1 over a batch of n directions: certain cases counted, uncertain
// ones queued; then the queue's length sizes pass 2's dispatch.
void count_pass(GpuSide& gpu, gl::Program& count, const glm::vec4* params, int n,
                size_t receivers) {
  const GLuint zero = 0;
  glClearNamedBufferSubData(gpu.queue.id(), GL_R32UI, 0, 4, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
  count.use();
  set_batch_directions(count, params, n);
  for (size_t first = 0; first < receivers; first += size_t(kMaxGroups) * kLocalSize) {
    const size_t left = receivers - first;
    const GLuint groups =
        GLuint(std::min<size_t>(kMaxGroups, (left + kLocalSize - 1) / kLocalSize));
    count.set("first_receiver", int(first));
    glDispatchCompute(groups, 1, 1);
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  gpu.dispatch.use();
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
}

// Pass 2 over a batch of n directions: exact tests of the queue, sized on
// the GPU (no readback), or with `rays` one group per kLocalSize receivers.
void exact_pass(const GpuSide& gpu, gl::Program& exact, const glm::vec4* params, int n,
                size_t receivers, bool rays) {
  exact.use();
  set_batch_directions(exact, params, n);
  if (rays) {
    glDispatchCompute(
        GLuint(std::min<size_t>(kMaxGroups, (receivers + kLocalSize - 1) / kLocalSize)), 1, 1);
  } else {
    glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, gpu.dispatch_args.id());
    glDispatchComputeIndirect(0);
    glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, 0);
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  gl::check_error("coverage counting pass");
}

// The GL state the passes need: depth test, no culling, blending or
// scissor, the shadow maps' viewport.
void set_pass_state(glm::ivec2 size) {
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  glViewport(0, 0, size.x, size.y);
}

// The counts, read back once, as coverage per receiver (directions lit / K).
void read_back(const GpuSide& gpu, const GpuJob& job, std::vector<float>& coverage) {
  const std::vector<uint32_t>& recv_index = job.receivers.recv_index;
  const size_t k_count = job.frames.size();
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<uint32_t> counts(job.receivers.recv.size());
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
}

}  // namespace

GpuSide::GpuSide(const Bvh& bvh, bool weld)
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
  std::vector<glm::vec3> welded;
  std::vector<uint32_t> indices;
  if (weld) {
    weld_vertices(bvh.corners(), welded, indices);
  } else {
    indices.resize(bvh.corners().size());
    std::iota(indices.begin(), indices.end(), 0u);
  }
  const std::vector<glm::vec3>& vertices = weld ? welded : bvh.corners();
  triangle_buffer = gl::create_buffer();
  glNamedBufferStorage(triangle_buffer.id(), GLsizeiptr(bvh.corners().size() * sizeof(glm::vec3)),
                       bvh.corners().data(), 0);
  gl::check_error("coverage scene triangles");
  nodes = bvh.nodes().size();
  node_buffer = gl::create_buffer();
  glNamedBufferStorage(node_buffer.id(), GLsizeiptr(nodes * sizeof(Bvh::Node)), bvh.nodes().data(),
                       0);
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

void GpuSide::draw_scene() const {
  if (triangles == 0) return;
  glBindVertexArray(vao.id());
  glDrawElements(GL_TRIANGLES, GLsizei(triangles * 3), GL_UNSIGNED_INT, nullptr);
}

void GpuSide::ensure_shadow_maps(glm::ivec2 size, int layers) {
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

void GpuSide::upload(gl::Buffer& buffer, const void* data, size_t bytes, const char* what) {
  if (!buffer) buffer = gl::create_buffer();
  glNamedBufferData(buffer.id(), GLsizeiptr(std::max<size_t>(bytes, 4)), data, GL_DYNAMIC_DRAW);
  gl::check_error(what);
}

int max_texture_size() {
  gl::require_context();
  GLint max_texture = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_texture);
  return int(max_texture);
}

void count_on_gpu(GpuSide& gpu, const GpuJob& job, std::vector<float>& coverage,
                  CoverageRenderer::Timings& timings, Progress& progress) {
  const size_t receivers = job.receivers.recv.size();
  const size_t k_count = job.frames.size();
  const glm::ivec2 size = job.frames.front().size;
  std::vector<glm::vec4> params(k_count);  // the frames' (a, b, u0, v0), as floats
  for (size_t k = 0; k < k_count; ++k) params[k] = glm::vec4(job.frames[k].params);

  GlStateGuard state;
  if (!job.rays) gpu.ensure_shadow_maps(size, job.batch);
  upload_receivers(gpu, job.receivers.recv);
  const bool snow = !job.receivers.snowy_layers.empty();
  if (snow) upload_snow_surface(gpu, job.maps, *job.snow_depth, job.receivers.top);
  set_shadow_uniforms(gpu, job);
  gl::Program& count = snow ? gpu.count_snow : gpu.count;
  gl::Program& exact = snow ? gpu.exact_snow : gpu.exact;
  set_pass_uniforms(gpu, job, count, exact);
  set_pass_state(size);
  if (job.profiling) glFinish();
  double t_mark = now_seconds();
  timings.setup = t_mark - job.t_start;

  uint32_t queued_mask = 0;  // rays: the direction mask of the queue uploaded last
  for (size_t b0 = 0; b0 < k_count; b0 += size_t(job.batch)) {
    const int n = int(std::min(size_t(job.batch), k_count - b0));
    if (!job.rays) draw_shadow_maps(gpu, job, &params[b0], n);
    gl::check_error("coverage shadow pass");
    if (job.profiling) {
      glFinish();
      const double t = now_seconds();
      timings.shadow += t - t_mark;
      t_mark = t;
    }
    bind_pass_inputs(gpu, job.rays, snow);
    if (job.rays) {
      queue_every_receiver(gpu, receivers, n, queued_mask);
    } else {
      count_pass(gpu, count, &params[b0], n, receivers);
    }
    exact_pass(gpu, exact, &params[b0], n, receivers, job.rays);
    timings.pairs += uint64_t(receivers) * uint64_t(n);
    if (job.profiling) {
      GLuint queued = 0;
      glGetNamedBufferSubData(gpu.queue.id(), 0, sizeof queued, &queued);
      timings.queued += queued;
      const double t = now_seconds();
      timings.composite += t - t_mark;
      t_mark = t;
    }
    progress.update(double(b0 + size_t(n)));
  }
  if (!job.profiling) {
    glFinish();
    const double t = now_seconds();
    timings.shadow = t - t_mark;  // shadow and counting together when not profiling
    t_mark = t;
  }
  read_back(gpu, job, coverage);
  progress.finish();
  timings.readback = now_seconds() - t_mark;
}

}  // namespace snow::cov
