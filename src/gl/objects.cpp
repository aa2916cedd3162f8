// RAII GL object creators and GL error checks.
#include "gl/objects.h"

#include <string>

#include "core/error.h"

namespace snow::gl {
namespace {

const char* error_name(GLenum error) {
  switch (error) {
    case GL_INVALID_ENUM:
      return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:
      return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:
      return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION:
      return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY:
      return "GL_OUT_OF_MEMORY";
    case GL_STACK_UNDERFLOW:
      return "GL_STACK_UNDERFLOW";
    case GL_STACK_OVERFLOW:
      return "GL_STACK_OVERFLOW";
    case GL_CONTEXT_LOST:
      return "GL_CONTEXT_LOST";
    default:
      return "unknown GL error";
  }
}

const char* framebuffer_status_name(GLenum status) {
  switch (status) {
    case GL_FRAMEBUFFER_UNDEFINED:
      return "GL_FRAMEBUFFER_UNDEFINED";
    case GL_FRAMEBUFFER_INCOMPLETE_ATTACHMENT:
      return "GL_FRAMEBUFFER_INCOMPLETE_ATTACHMENT";
    case GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT:
      return "GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT";
    case GL_FRAMEBUFFER_INCOMPLETE_DRAW_BUFFER:
      return "GL_FRAMEBUFFER_INCOMPLETE_DRAW_BUFFER";
    case GL_FRAMEBUFFER_INCOMPLETE_READ_BUFFER:
      return "GL_FRAMEBUFFER_INCOMPLETE_READ_BUFFER";
    case GL_FRAMEBUFFER_UNSUPPORTED:
      return "GL_FRAMEBUFFER_UNSUPPORTED";
    case GL_FRAMEBUFFER_INCOMPLETE_MULTISAMPLE:
      return "GL_FRAMEBUFFER_INCOMPLETE_MULTISAMPLE";
    case GL_FRAMEBUFFER_INCOMPLETE_LAYER_TARGETS:
      return "GL_FRAMEBUFFER_INCOMPLETE_LAYER_TARGETS";
    default:
      return "unknown framebuffer status";
  }
}

void check_size(int width, int height, int layers, const char* what) {
  if (width < 1 || height < 1 || layers < 1) {
    throw GLError(std::string(what) + ": texture size " + std::to_string(width) + "x" +
                  std::to_string(height) + "x" + std::to_string(layers) + " is empty");
  }
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (max_size > 0 && (width > max_size || height > max_size)) {
    throw GLError(std::string(what) + ": texture size " + std::to_string(width) + "x" +
                  std::to_string(height) + " exceeds GL_MAX_TEXTURE_SIZE " +
                  std::to_string(max_size));
  }
}

void set_nearest_clamp(GLuint texture) {
  glTextureParameteri(texture, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(texture, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureParameteri(texture, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(texture, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTextureParameteri(texture, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE);
}

}  // namespace

void check_error(const char* what) {
  GLenum error = glGetError();
  if (error == GL_NO_ERROR) return;
  std::string names;
  for (int i = 0; error != GL_NO_ERROR && i < 16; ++i, error = glGetError()) {
    if (!names.empty()) names += ", ";
    names += error_name(error);
  }
  throw GLError(std::string(what) + ": " + names);
}

Texture create_texture(GLenum target) {
  GLuint id = 0;
  glCreateTextures(target, 1, &id);
  check_error("glCreateTextures");
  return Texture(id);
}

Buffer create_buffer() {
  GLuint id = 0;
  glCreateBuffers(1, &id);
  check_error("glCreateBuffers");
  return Buffer(id);
}

Framebuffer create_framebuffer() {
  GLuint id = 0;
  glCreateFramebuffers(1, &id);
  check_error("glCreateFramebuffers");
  return Framebuffer(id);
}

Renderbuffer create_renderbuffer() {
  GLuint id = 0;
  glCreateRenderbuffers(1, &id);
  check_error("glCreateRenderbuffers");
  return Renderbuffer(id);
}

VertexArray create_vertex_array() {
  GLuint id = 0;
  glCreateVertexArrays(1, &id);
  check_error("glCreateVertexArrays");
  return VertexArray(id);
}

Query create_query(GLenum target) {
  GLuint id = 0;
  glCreateQueries(target, 1, &id);
  check_error("glCreateQueries");
  return Query(id);
}

Texture create_texture_2d_array(GLenum internal_format, int width, int height, int layers,
                                const char* what) {
  check_size(width, height, layers, what);
  Texture texture = create_texture(GL_TEXTURE_2D_ARRAY);
  glTextureStorage3D(texture.id(), 1, internal_format, width, height, layers);
  set_nearest_clamp(texture.id());
  check_error(what);
  return texture;
}

Texture create_texture_2d(GLenum internal_format, int width, int height, const char* what) {
  check_size(width, height, 1, what);
  Texture texture = create_texture(GL_TEXTURE_2D);
  glTextureStorage2D(texture.id(), 1, internal_format, width, height);
  set_nearest_clamp(texture.id());
  check_error(what);
  return texture;
}

void check_framebuffer(const Framebuffer& fbo, const char* what) {
  const GLenum status = glCheckNamedFramebufferStatus(fbo.id(), GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    throw GLError(std::string(what) + ": framebuffer incomplete (" +
                  framebuffer_status_name(status) + ")");
  }
}

}  // namespace snow::gl
