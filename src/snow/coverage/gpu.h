#pragma once
// The GL side of the coverage stage (gpu.cpp), private to
// src/snow/coverage/: the shadow-map method's passes and the exact pass on
// the GPU (CoverageMethod::ShadowMaps and GpuRays). Includes GL: for
// gpu.cpp and renderer.cpp only.
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "gl/objects.h"
#include "gl/program.h"
#include "snow/bvh.h"
#include "snow/coverage.h"
#include "snow/coverage/internal.h"
#include "snow/maps.h"

namespace snow::cov {

/// The GL side of a CoverageRenderer: programs, the scene's buffers, shadow
/// maps and the passes' buffers. Made on the first compute that draws
/// shadow maps or casts rays on the GPU (runs whose rays are cast on the
/// CPU upload nothing). Needs a current context for its whole life.
struct GpuSide {
  /// One buffer of triangles in BVH leaf order, ray cast by the exact pass
  /// (storage buffer); the shadow passes draw the triangles through an
  /// index buffer in the same order, their corners welded first where
  /// `weld` (weld_vertices). Throws GLError when GL fails.
  GpuSide(const Bvh& bvh, bool weld);

  gl::Program shadow;       // scene depth into a shadow map
  gl::Program shadow_snow;  // snow heightfield depth into a shadow map
  gl::Program count;        // pass 1: certain cases counted, the others queued
  gl::Program count_snow;   // the same with a snow surface in the shadow maps
  gl::Program exact;        // pass 2: exact ray casts of the queued pairs
  gl::Program exact_snow;
  gl::Program dispatch;  // queue length maps to the indirect dispatch size
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

  /// Draws every scene triangle with the bound program (one call).
  void draw_scene() const;
  /// Makes `layers` shadow maps of `size` texels and their framebuffers,
  /// unless those are there.
  void ensure_shadow_maps(glm::ivec2 size, int layers);
  /// (Re)fills `buffer` with `bytes` (4 at least) from `data` (or undefined).
  static void upload(gl::Buffer& buffer, const void* data, size_t bytes, const char* what);
};

/// The largest texture side GL takes (GL_MAX_TEXTURE_SIZE; 0 where it does
/// not say), for the shadow maps. Makes the context where a
/// gl::OnDemandContext is installed (gl::require_context).
int max_texture_size();

/// What the GPU passes of one compute read.
struct GpuJob {
  const SnowMaps& maps;
  const std::vector<float>* snow_depth;    // metres per layer texel, or null
  const Receivers& receivers;              // those the sky cull left
  const std::vector<ShadowFrame>& frames;  // one per direction, all of one size
  float bias;                              // metres, the receiver-plane depth bias
  float y_top;     // metres, the top of the depth range (scene and receivers)
  float y_range;   // metres, its height
  int batch;       // directions per batch (shadow maps at once)
  bool rays;       // CoverageMethod::GpuRays: every pair queued, no shadow maps
  bool profiling;  // glFinish between the stages, for their timings
  double t_start;  // now_seconds() at the compute's start, for timings.setup
};

/// Counts the directions from which each receiver sees the sky on the GPU:
/// per batch, the shadow maps (unless job.rays), pass 1 classifying every
/// pair and queueing the uncertain ones (with job.rays: every pair queued),
/// and pass 2 casting the queue exactly; one readback at the end. Sets
/// coverage[recv_index[r]] of each receiver r, and timings' setup, shadow,
/// composite, readback, pairs and (profiling) queued. Restores the GL state
/// it changes. Throws GLError when GL fails.
void count_on_gpu(GpuSide& gpu, const GpuJob& job, std::vector<float>& coverage,
                  CoverageRenderer::Timings& timings, Progress& progress);

}  // namespace snow::cov
