#pragma once
// Internal to the GPU passes of stages 1 and 2 (snow/peel/gpu.cpp, snow/coverage/gpu.cpp): the
// scene uploaded once and drawn with one call, and a guard that restores
// the GL state those passes change. Includes GL: not for other modules.
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "gl/objects.h"
#include "scene/scene.h"

namespace snow {

/// Welds a triangle soup (3 corners per triangle): exactly equal corners
/// become one vertex; indices[c] is corner c's vertex. O(n log n).
void weld_vertices(const std::vector<glm::vec3>& corners, std::vector<glm::vec3>& vertices,
                   std::vector<uint32_t>& indices);

/// The scene's triangles in one vertex buffer (positions at
/// SNOW_ATTR_POSITION; triangles in the Scene's order, so gl_PrimitiveID is
/// the triangle index), either as the soup itself or welded with an index
/// buffer (fewer vertex-shader runs; worth the weld for many passes). Needs a
/// current context for its whole life.
class GpuScene {
 public:
  /// Uploads the positions. Throws InputError for more triangles than one
  /// draw call takes, GLError on GL_OUT_OF_MEMORY.
  explicit GpuScene(const Scene& scene, bool indexed = false);

  /// Draws every triangle (one glDrawArrays) with the bound program.
  void draw() const;
  size_t triangle_count() const { return triangles_; }

 private:
  gl::VertexArray vao_;
  gl::Buffer positions_;
  gl::Buffer indices_;
  size_t triangles_ = 0;
};

/// Saves the GL state the map passes change (framebuffer, viewport, program,
/// vertex array, depth, cull, blend and scissor state) and restores it on
/// destruction.
class GlStateGuard {
 public:
  GlStateGuard();
  ~GlStateGuard();
  GlStateGuard(const GlStateGuard&) = delete;
  GlStateGuard& operator=(const GlStateGuard&) = delete;

 private:
  GLint draw_fbo_ = 0, read_fbo_ = 0, program_ = 0, vao_ = 0, depth_func_ = 0;
  GLint viewport_[4] = {0, 0, 0, 0};
  GLboolean depth_test_ = 0, depth_mask_ = 0, cull_ = 0, blend_ = 0, scissor_ = 0;
};

/// Seconds on a steady clock (for stage timings).
double now_seconds();

}  // namespace snow
