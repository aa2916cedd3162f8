#pragma once
// Where the live preview draws: a GLFW window with its input, or headless an
// off-screen framebuffer on a headless GL context; Dear ImGui set up on
// either. Only surface.cpp and viewer.cpp include GLFW.
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "live/viewer.h"

struct GLFWwindow;

namespace snow::gl {
class Context;
struct RenderTarget;
}  // namespace snow::gl

namespace snow::live {

/// Input gathered by the GLFW callbacks between frames.
struct Input {
  double scroll = 0;
  std::vector<int> keys;  // keys pressed (GLFW_KEY_*)
};

/// The window's context (GLFW, its callbacks filling `input`) or, with
/// options.headless, a context of options.gl_backend drawing into an
/// off-screen framebuffer of options.width x height; Dear ImGui set up on
/// the window, or headless for a --screenshot-panel (its GLFW backend only
/// with the window). Made current on construction; everything drawn with it
/// must be destroyed first. Throws GLError when the window, the context,
/// the framebuffer or the panel's renderer cannot be made.
class Surface {
 public:
  Surface(const ViewerOptions& options, Input* input);
  ~Surface();
  Surface(const Surface&) = delete;
  Surface& operator=(const Surface&) = delete;

  GLFWwindow* window() const { return window_; }
  /// Dear ImGui is set up: new_frame() starts its frames (the caller ends
  /// each with ImGui::Render()).
  bool has_ui() const { return ui_; }
  /// The framebuffer frames are drawn into (0: the window's).
  unsigned target() const;
  bool closed() const;
  /// Polls the window's events; the framebuffer's size (pixels).
  glm::ivec2 poll();
  /// Starts an ImGui frame, `seconds` after the last one (nothing without
  /// the UI).
  void new_frame(double seconds);
  /// Shows the frame (headless: waits until it is drawn).
  void present();

 private:
  void close_ui();
  std::unique_ptr<gl::Context> context_;
  GLFWwindow* window_ = nullptr;
  std::unique_ptr<gl::RenderTarget> offscreen_;  // headless: the frame drawn into
  glm::ivec2 size_{0, 0};
  bool ui_ = false, renderer_ = false;  // ImGui's context; its OpenGL renderer
};

}  // namespace snow::live
