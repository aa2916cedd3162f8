// GLFW backend: a window with a GL 4.5 core context (4.3 at least), for the
// live preview. Needs a display (X11 or Wayland); visible or hidden per
// ContextOptions::visible.
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <string>

#include "core/error.h"
#include "gl/context_internal.h"

// Under AddressSanitizer GLFW stays initialized until the process ends:
// glfwTerminate closes the X display, and Mesa then unloads its GLX driver
// with a little llvmpipe state never freed, from frames LeakSanitizer can
// neither name nor suppress. Kept initialized, that state stays reachable.
#if defined(__SANITIZE_ADDRESS__)
#define SNOW_GLFW_KEEP_INITIALIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SNOW_GLFW_KEEP_INITIALIZED 1
#endif
#endif

namespace snow::gl::detail {
namespace {

std::string g_last_glfw_error;  // set by the error callback
int g_glfw_users = 0;           // live windows; glfwTerminate after the last

void on_glfw_error(int /*code*/, const char* description) {
  g_last_glfw_error = description ? description : "unknown GLFW error";
}

ProcAddressFn glfw_loader() { return reinterpret_cast<ProcAddressFn>(&glfwGetProcAddress); }

void acquire_glfw() {
  if (g_glfw_users == 0) {
    glfwSetErrorCallback(on_glfw_error);
    g_last_glfw_error.clear();
    if (!glfwInit()) {
      throw GLError("glfwInit failed (" + g_last_glfw_error + ")");
    }
  }
  ++g_glfw_users;
}

void release_glfw() {
  if (--g_glfw_users == 0) {
#ifndef SNOW_GLFW_KEEP_INITIALIZED
    glfwTerminate();
    forget_loaded_functions(glfw_loader());
#endif
  }
}

class GlfwContext final : public Context {
 public:
  GlfwContext() { acquire_glfw(); }
  ~GlfwContext() override {
    if (window_) {
      if (glfwGetCurrentContext() == window_) glfwMakeContextCurrent(nullptr);
      glfwDestroyWindow(window_);
    }
    release_glfw();
  }

  Backend backend() const override { return Backend::Glfw; }
  void* native_window() const override { return window_; }

  void make_current() override {
    glfwMakeContextCurrent(window_);
    load_functions(glfw_loader(), Backend::Glfw);
  }

  void create(const ContextOptions& options) {
    for (int minor : {5, 4, 3}) {
      glfwDefaultWindowHints();
      glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_API);
      glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
      glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, minor);
      glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
      glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
      glfwWindowHint(GLFW_OPENGL_DEBUG_CONTEXT, want_debug(options) ? GLFW_TRUE : GLFW_FALSE);
      glfwWindowHint(GLFW_VISIBLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
      g_last_glfw_error.clear();
      window_ = glfwCreateWindow(options.window_width, options.window_height, options.title.c_str(),
                                 nullptr, nullptr);
      if (window_) break;
    }
    if (!window_) {
      throw GLError("no OpenGL 4.3+ core window (" + g_last_glfw_error + ")");
    }
    glfwMakeContextCurrent(window_);
    init_new_context(glfw_loader(), Backend::Glfw, options);
  }

 private:
  GLFWwindow* window_ = nullptr;
};

}  // namespace

std::unique_ptr<Context> create_glfw_context(const ContextOptions& options) {
  if (options.window_width < 1 || options.window_height < 1) {
    throw GLError("window size " + std::to_string(options.window_width) + "x" +
                  std::to_string(options.window_height) + " is empty");
  }
  auto context = std::make_unique<GlfwContext>();
  context->create(options);
  return context;
}

}  // namespace snow::gl::detail
