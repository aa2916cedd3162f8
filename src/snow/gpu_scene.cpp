// Scene upload and GL state guard shared by the peel and coverage passes.
#include "snow/gpu_scene.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <vector>

#include <glm/glm.hpp>

#include "core/error.h"
#include "shaders/bindings.h"

namespace snow {

GpuScene::GpuScene(const Scene& scene, bool with_triangle_info)
    : triangles_(scene.triangle_count()) {
  if (triangles_ * 3 > size_t(0x7fffffff)) {
    throw InputError("scene has " + std::to_string(triangles_) +
                     " triangles, more than one draw call can take");
  }
  vao_ = gl::create_vertex_array();
  if (triangles_ == 0) return;
  positions_ = gl::create_buffer();
  glNamedBufferStorage(positions_.id(), GLsizeiptr(triangles_ * 3 * sizeof(glm::vec3)),
                       scene.positions.data(), 0);
  gl::check_error("scene vertex buffer");
  glVertexArrayVertexBuffer(vao_.id(), 0, positions_.id(), 0, sizeof(glm::vec3));
  glEnableVertexArrayAttrib(vao_.id(), SNOW_ATTR_POSITION);
  glVertexArrayAttribFormat(vao_.id(), SNOW_ATTR_POSITION, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao_.id(), SNOW_ATTR_POSITION, 0);
  gl::check_error("scene vertex array");
  if (!with_triangle_info) return;

  std::vector<glm::vec4> info(triangles_, glm::vec4(0.0f));
  for (size_t t = 0; t < triangles_; ++t) {
    const glm::dvec3 a(scene.positions[3 * t]);
    const glm::dvec3 n = glm::cross(glm::dvec3(scene.positions[3 * t + 1]) - a,
                                    glm::dvec3(scene.positions[3 * t + 2]) - a);
    const double len = glm::length(n);
    if (len > 0) info[t] = glm::vec4(glm::vec3(n / len), 0.0f);
  }
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const SceneObject& obj = scene.objects[o];
    const int32_t id = int32_t(o);
    float bits;
    std::memcpy(&bits, &id, sizeof bits);
    for (uint32_t k = 0; k < obj.triangle_count && obj.first_triangle + k < triangles_; ++k) {
      info[obj.first_triangle + k].w = bits;
    }
  }
  // Triangles outside every object range (not expected) get object -1.
  std::vector<bool> covered(triangles_, false);
  for (const SceneObject& obj : scene.objects) {
    for (uint32_t k = 0; k < obj.triangle_count && obj.first_triangle + k < triangles_; ++k) {
      covered[obj.first_triangle + k] = true;
    }
  }
  const int32_t none = -1;
  float none_bits;
  std::memcpy(&none_bits, &none, sizeof none_bits);
  for (size_t t = 0; t < triangles_; ++t) {
    if (!covered[t]) info[t].w = none_bits;
  }
  triangle_info_ = gl::create_buffer();
  glNamedBufferStorage(triangle_info_.id(), GLsizeiptr(info.size() * sizeof(glm::vec4)),
                       info.data(), 0);
  gl::check_error("scene triangle buffer");
}

void GpuScene::draw() const {
  if (triangles_ == 0) return;
  glBindVertexArray(vao_.id());
  if (triangle_info_) {
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_PEEL_TRIANGLES, triangle_info_.id());
  }
  glDrawArrays(GL_TRIANGLES, 0, GLsizei(triangles_ * 3));
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
