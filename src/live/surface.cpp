// The live preview's window or off-screen framebuffer (live/surface.h).
#include "live/surface.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "core/error.h"
#include "core/log.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "gl/objects.h"

namespace snow::live {
namespace {

void on_scroll(GLFWwindow* window, double /*x*/, double y) {
  static_cast<Input*>(glfwGetWindowUserPointer(window))->scroll += y;
}

void on_key(GLFWwindow* window, int key, int /*scancode*/, int action, int /*mods*/) {
  if (action == GLFW_PRESS)
    static_cast<Input*>(glfwGetWindowUserPointer(window))->keys.push_back(key);
}

}  // namespace

Surface::Surface(const ViewerOptions& options, Input* input) {
  gl::ContextOptions context_options;
  if (options.headless) {
    context_options.backend = gl::parse_backend(options.gl_backend);
  } else {
    context_options.backend = gl::Backend::Glfw;
    context_options.window_width = options.width;
    context_options.window_height = options.height;
    context_options.title =
        "snowmodel preview - " + std::filesystem::path(options.input).filename().string();
  }
  context_ = gl::create_context(context_options);
  log_info("OpenGL: " + context_->description());
  window_ = static_cast<GLFWwindow*>(context_->native_window());
  if (window_) {
    glfwSetWindowUserPointer(window_, input);
    glfwSetScrollCallback(window_, on_scroll);
    glfwSetKeyCallback(window_, on_key);
    glfwSwapInterval(options.frames > 0 ? 0 : 1);
  } else {
    offscreen_ = std::make_unique<gl::RenderTarget>(gl::create_render_target(
        options.width, options.height, 1, true, "headless preview framebuffer"));
    size_ = {options.width, options.height};
  }
  // Headless, the panel is drawn only into a --screenshot-panel.
  if (!window_ && !(options.panel && options.screenshot_panel)) return;
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ui_ = true;
  ImGui::GetIO().IniFilename = nullptr;
  ImGui::StyleColorsDark();
  if (window_) ImGui_ImplGlfw_InitForOpenGL(window_, true);  // chains the callbacks above
  // Dear ImGui loads GL functions its own way, which fails on some
  // contexts (OSMesa's).
  if (!ImGui_ImplOpenGL3_Init("#version 430 core")) {
    close_ui();
    throw GLError("the settings panel (Dear ImGui) cannot load OpenGL functions on this " +
                  std::string(window_ ? "window" : "context (drop --screenshot-panel)"));
  }
  renderer_ = true;
}

void Surface::close_ui() {
  if (renderer_) ImGui_ImplOpenGL3_Shutdown();
  if (ui_ && window_) ImGui_ImplGlfw_Shutdown();
  if (ui_) ImGui::DestroyContext();
  ui_ = renderer_ = false;
}

Surface::~Surface() {
  close_ui();
  offscreen_.reset();
}

unsigned Surface::target() const { return offscreen_ ? offscreen_->fbo.id() : 0; }

bool Surface::closed() const { return window_ && glfwWindowShouldClose(window_); }

glm::ivec2 Surface::poll() {
  if (window_) {
    glfwPollEvents();
    glfwGetFramebufferSize(window_, &size_.x, &size_.y);
  }
  return size_;
}

void Surface::new_frame(double seconds) {
  if (!ui_) return;
  ImGui_ImplOpenGL3_NewFrame();
  if (window_) {
    ImGui_ImplGlfw_NewFrame();
  } else {
    ImGuiIO& io = ImGui::GetIO();
    io.DisplaySize = ImVec2(float(size_.x), float(size_.y));
    io.DeltaTime = float(std::max(seconds, 1e-4));
  }
  ImGui::NewFrame();
}

void Surface::present() {
  if (window_) {
    glfwSwapBuffers(window_);
  } else {
    glFinish();
  }
}

}  // namespace snow::live
