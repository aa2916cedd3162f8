// RAII GL object creators and GL error checks.
#include "gl/objects.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
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

// Test-only fault injection (tests/test_hostile.cpp): SNOWMODEL_FAULT=
// "gl-alloc[:WHERE]" makes one GL error check report GL_OUT_OF_MEMORY;
// "context-loss[:WHERE]" makes it and every later check report a lost
// context. WHERE is a number N (the N-th check of the process; default 1) or
// a word (the first check whose label contains it: "coverage", "stabilize",
// "preview"). Read once per process.
struct Fault {
  enum Kind { None, Alloc, ContextLoss } kind = None;
  long at = 1;        // N-th check, when where is empty
  std::string where;  // label substring
};

const Fault& injected_fault() {
  static const Fault fault = [] {
    Fault f;
    const char* env = std::getenv("SNOWMODEL_FAULT");
    if (!env || !*env) return f;
    const std::string text = env;
    const size_t colon = text.find(':');
    const std::string name = text.substr(0, colon);
    if (name == "gl-alloc") f.kind = Fault::Alloc;
    if (name == "context-loss") f.kind = Fault::ContextLoss;
    if (colon != std::string::npos) {
      const std::string arg = text.substr(colon + 1);
      if (!arg.empty() && arg.find_first_not_of("0123456789") == std::string::npos) {
        f.at = std::max(1L, std::atol(arg.c_str()));
      } else {
        f.where = arg;
      }
    }
    return f;
  }();
  return fault;
}

/// True when the injected fault fires at this check (`what` is its label).
bool fault_fires(const Fault& fault, const char* what) {
  static long checks = 0;
  static bool fired = false;
  ++checks;
  if (fired) return fault.kind == Fault::ContextLoss;  // a lost context stays lost
  fired =
      fault.where.empty() ? checks >= fault.at : std::strstr(what, fault.where.c_str()) != nullptr;
  return fired;
}

const char* reset_status_name(GLenum status) {
  switch (status) {
    case GL_GUILTY_CONTEXT_RESET:
      return "GL_GUILTY_CONTEXT_RESET";
    case GL_INNOCENT_CONTEXT_RESET:
      return "GL_INNOCENT_CONTEXT_RESET";
    case GL_UNKNOWN_CONTEXT_RESET:
      return "GL_UNKNOWN_CONTEXT_RESET";
    default:
      return "unknown reset";
  }
}

[[noreturn]] void throw_context_lost(const char* what, const char* why) {
  throw GLError(std::string("OpenGL context lost during ") + what + " (" + why +
                "): the GPU or its driver was reset; run again");
}

}  // namespace

void check_error(const char* what) {
  const Fault& fault = injected_fault();
  if (fault.kind != Fault::None && fault_fires(fault, what)) {
    if (fault.kind == Fault::ContextLoss) throw_context_lost(what, "injected by SNOWMODEL_FAULT");
    throw GLError(std::string(what) +
                  ": out of GPU memory (GL_OUT_OF_MEMORY, injected by SNOWMODEL_FAULT); use a "
                  "coarser --texel, fewer --layers or --directions");
  }
  GLenum error = glGetError();
  // With a robust context (context_egl.cpp asks for one) a reset shows here.
  const GLenum reset = glGetGraphicsResetStatus ? glGetGraphicsResetStatus() : GL_NO_ERROR;
  if (reset != GL_NO_ERROR) throw_context_lost(what, reset_status_name(reset));
  if (error == GL_NO_ERROR) return;
  std::string names;
  bool out_of_memory = false, lost = false;
  for (int i = 0; error != GL_NO_ERROR && i < 16; ++i, error = glGetError()) {
    if (!names.empty()) names += ", ";
    names += error_name(error);
    out_of_memory |= error == GL_OUT_OF_MEMORY;
    lost |= error == GL_CONTEXT_LOST;
  }
  if (lost) throw_context_lost(what, names.c_str());
  if (out_of_memory) {
    throw GLError(std::string(what) + ": out of GPU memory (" + names +
                  "); use a coarser --texel, fewer --layers or --directions");
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

Texture create_texture_view(const Texture& original, GLenum internal_format, int layers,
                            const char* what) {
  GLuint id = 0;
  glGenTextures(1, &id);  // a view needs a name that is not yet a texture object
  Texture view(id);
  glTextureView(view.id(), GL_TEXTURE_2D_ARRAY, original.id(), internal_format, 0, 1, 0,
                GLuint(layers));
  set_nearest_clamp(view.id());
  check_error(what);
  return view;
}

RenderTarget create_render_target(int width, int height, int samples, bool with_depth,
                                  const char* what) {
  RenderTarget t;
  t.color = create_renderbuffer();
  t.fbo = create_framebuffer();
  const auto storage = [&](const Renderbuffer& r, GLenum format) {
    if (samples > 1) {
      glNamedRenderbufferStorageMultisample(r.id(), samples, format, width, height);
    } else {
      glNamedRenderbufferStorage(r.id(), format, width, height);
    }
  };
  storage(t.color, GL_RGBA8);
  if (with_depth) {
    t.depth = create_renderbuffer();
    storage(t.depth, GL_DEPTH_COMPONENT32F);
  }
  check_error(what);
  glNamedFramebufferRenderbuffer(t.fbo.id(), GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t.color.id());
  if (with_depth)
    glNamedFramebufferRenderbuffer(t.fbo.id(), GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, t.depth.id());
  check_framebuffer(t.fbo, what);
  return t;
}

void check_framebuffer(const Framebuffer& fbo, const char* what) {
  const GLenum status = glCheckNamedFramebufferStatus(fbo.id(), GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    throw GLError(std::string(what) + ": framebuffer incomplete (" +
                  framebuffer_status_name(status) + ")");
  }
}

}  // namespace snow::gl
