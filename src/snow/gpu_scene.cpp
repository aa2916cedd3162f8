// Scene upload and GL state guard shared by the peel and coverage passes.
#include "snow/gpu_scene.h"

#include <algorithm>
#include <chrono>

#include <glm/glm.hpp>

#include "core/error.h"
#include "shaders/bindings.h"

namespace snow {

void weld_vertices(const std::vector<glm::vec3>& corners, std::vector<glm::vec3>& vertices,
                   std::vector<uint32_t>& indices) {
  // Sorted as records (position, corner), not as corner numbers compared
  // through the positions: the sort then reads memory in order.
  struct Corner {
    glm::vec3 p;
    uint32_t index;
  };
  std::vector<Corner> sorted(corners.size());
  for (size_t k = 0; k < corners.size(); ++k) sorted[k] = {corners[k], uint32_t(k)};
  const auto less = [](const glm::vec3& p, const glm::vec3& q) {
    if (p.x != q.x) return p.x < q.x;
    if (p.y != q.y) return p.y < q.y;
    return p.z < q.z;
  };
  std::sort(sorted.begin(), sorted.end(),
            [&](const Corner& a, const Corner& b) { return less(a.p, b.p); });
  indices.resize(corners.size());
  vertices.clear();
  for (size_t k = 0; k < sorted.size(); ++k) {
    if (k == 0 || less(sorted[k - 1].p, sorted[k].p)) vertices.push_back(sorted[k].p);
    indices[sorted[k].index] = uint32_t(vertices.size() - 1);
  }
}

GpuScene::GpuScene(const Scene& scene, bool indexed) : triangles_(scene.triangle_count()) {
  if (triangles_ * 3 > size_t(0x7fffffff)) {
    throw InputError("scene has " + std::to_string(triangles_) +
                     " triangles, more than one draw call can take");
  }
  vao_ = gl::create_vertex_array();
  if (triangles_ == 0) return;
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
  if (indexed) weld_vertices(scene.positions, vertices, indices);
  const std::vector<glm::vec3>& uploaded = indexed ? vertices : scene.positions;
  positions_ = gl::create_buffer();
  glNamedBufferStorage(positions_.id(), GLsizeiptr(uploaded.size() * sizeof(glm::vec3)),
                       uploaded.data(), 0);
  if (indexed) {
    indices_ = gl::create_buffer();
    glNamedBufferStorage(indices_.id(), GLsizeiptr(indices.size() * sizeof(uint32_t)),
                         indices.data(), 0);
    glVertexArrayElementBuffer(vao_.id(), indices_.id());
  }
  gl::check_error("scene vertex buffer");
  glVertexArrayVertexBuffer(vao_.id(), 0, positions_.id(), 0, sizeof(glm::vec3));
  glEnableVertexArrayAttrib(vao_.id(), SNOW_ATTR_POSITION);
  glVertexArrayAttribFormat(vao_.id(), SNOW_ATTR_POSITION, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao_.id(), SNOW_ATTR_POSITION, 0);
  gl::check_error("scene vertex array");
}

void GpuScene::draw() const {
  if (triangles_ == 0) return;
  glBindVertexArray(vao_.id());
  if (indices_) {
    glDrawElements(GL_TRIANGLES, GLsizei(triangles_ * 3), GL_UNSIGNED_INT, nullptr);
  } else {
    glDrawArrays(GL_TRIANGLES, 0, GLsizei(triangles_ * 3));
  }
}

GlStateGuard::GlStateGuard() {
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo_);
  glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &read_fbo_);
  glGetIntegerv(GL_CURRENT_PROGRAM, &program_);
  glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &vao_);
  glGetIntegerv(GL_DEPTH_FUNC, &depth_func_);
  glGetIntegerv(GL_VIEWPORT, viewport_);
  glGetBooleanv(GL_DEPTH_WRITEMASK, &depth_mask_);
  depth_test_ = glIsEnabled(GL_DEPTH_TEST);
  cull_ = glIsEnabled(GL_CULL_FACE);
  blend_ = glIsEnabled(GL_BLEND);
  scissor_ = glIsEnabled(GL_SCISSOR_TEST);
}

GlStateGuard::~GlStateGuard() {
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(draw_fbo_));
  glBindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(read_fbo_));
  glUseProgram(GLuint(program_));
  glBindVertexArray(GLuint(vao_));
  glDepthFunc(GLenum(depth_func_));
  glViewport(viewport_[0], viewport_[1], viewport_[2], viewport_[3]);
  glDepthMask(depth_mask_);
  const auto set = [](GLenum cap, GLboolean on) { on ? glEnable(cap) : glDisable(cap); };
  set(GL_DEPTH_TEST, depth_test_);
  set(GL_CULL_FACE, cull_);
  set(GL_BLEND, blend_);
  set(GL_SCISSOR_TEST, scissor_);
}

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace snow
