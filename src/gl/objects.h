#pragma once
// RAII owners of GL object names: movable, not copyable, deleted in the
// destructor. They need a current context for their whole life.
#include <utility>

#include "gl/gl.h"

namespace snow::gl {

template <void (*Delete)(GLuint)>
class Handle {
 public:
  Handle() = default;
  explicit Handle(GLuint id) : id_(id) {}
  ~Handle() { reset(); }
  Handle(Handle&& other) noexcept : id_(std::exchange(other.id_, 0)) {}
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = std::exchange(other.id_, 0);
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;

  GLuint id() const { return id_; }
  explicit operator bool() const { return id_ != 0; }
  void reset() {
    if (id_) Delete(id_);
    id_ = 0;
  }

 private:
  GLuint id_ = 0;
};

namespace detail {
inline void delete_texture(GLuint id) { glDeleteTextures(1, &id); }
inline void delete_buffer(GLuint id) { glDeleteBuffers(1, &id); }
inline void delete_framebuffer(GLuint id) { glDeleteFramebuffers(1, &id); }
inline void delete_renderbuffer(GLuint id) { glDeleteRenderbuffers(1, &id); }
inline void delete_vertex_array(GLuint id) { glDeleteVertexArrays(1, &id); }
inline void delete_program(GLuint id) { glDeleteProgram(id); }
inline void delete_query(GLuint id) { glDeleteQueries(1, &id); }
}  // namespace detail

using Texture = Handle<detail::delete_texture>;
using Buffer = Handle<detail::delete_buffer>;
using Framebuffer = Handle<detail::delete_framebuffer>;
using Renderbuffer = Handle<detail::delete_renderbuffer>;
using VertexArray = Handle<detail::delete_vertex_array>;
using ProgramHandle = Handle<detail::delete_program>;
using Query = Handle<detail::delete_query>;

/// Creators (DSA, GL 4.5). Each checks for GL errors and throws GLError.
Texture create_texture(GLenum target);
Buffer create_buffer();
Framebuffer create_framebuffer();
Renderbuffer create_renderbuffer();
VertexArray create_vertex_array();
/// A query object of `target` (GL_TIME_ELAPSED, GL_SAMPLES_PASSED, ...).
Query create_query(GLenum target);

/// Allocates immutable storage for a 2D texture array (glTextureStorage3D)
/// and sets nearest filtering and clamp-to-edge. Throws GLError on failure
/// (GL_OUT_OF_MEMORY included), naming `what`.
Texture create_texture_2d_array(GLenum internal_format, int width, int height, int layers,
                                const char* what);
/// Same for a 2D texture.
Texture create_texture_2d(GLenum internal_format, int width, int height, const char* what);
/// A view of all `layers` layers of a 2D texture array made by
/// create_texture_2d_array, as `internal_format` (of the same size class:
/// RG32UI for RG32F, ...), sharing its memory; nearest filtering and
/// clamp-to-edge. Throws GLError naming `what`.
Texture create_texture_view(const Texture& original, GLenum internal_format, int layers,
                            const char* what);

/// Throws GLError naming `what` unless the framebuffer is complete.
void check_framebuffer(const Framebuffer& fbo, const char* what);

/// A framebuffer drawn into off-screen: an RGBA8 colour renderbuffer and,
/// if asked for, a DEPTH_COMPONENT32F one.
struct RenderTarget {
  Renderbuffer color, depth;
  Framebuffer fbo;
};
/// A complete RenderTarget of width x height pixels, multisampled when
/// `samples` > 1. Throws GLError naming `what` (GL_OUT_OF_MEMORY included).
RenderTarget create_render_target(int width, int height, int samples, bool with_depth,
                                  const char* what);

}  // namespace snow::gl
