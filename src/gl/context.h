#pragma once
// OpenGL contexts behind one interface. Only the backend .cpp files include
// EGL, OSMesa or GLFW headers. Every backend gives a GL 4.5 core context
// (4.3 at least) with functions loaded through glad from its own
// get-proc-address.
#include <memory>
#include <string>

namespace snow::gl {

enum class Backend {
  Auto,            // headless: EglDevice, then EglSurfaceless, then OSMesa
  EglDevice,       // EGL_EXT_platform_device (a GPU without a display)
  EglSurfaceless,  // EGL_MESA_platform_surfaceless (Mesa, e.g. llvmpipe)
  OSMesa,          // Mesa off-screen
  Glfw,            // a window (preview); needs a display
};

/// "auto", "egl-device", "egl-surfaceless", "osmesa", "glfw".
std::string to_string(Backend backend);
/// Parses the names above; throws InputError listing the valid names.
Backend parse_backend(const std::string& name);

struct ContextOptions {
  Backend backend = Backend::Auto;  // SNOWMODEL_GL_BACKEND overrides Auto
  bool debug = false;               // KHR_debug output (on in debug builds)
  // Glfw only:
  int window_width = 1280;  // pixels
  int window_height = 800;  // pixels
  bool visible = true;
  std::string title = "snowmodel";
};

class Context {
 public:
  virtual ~Context() = default;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  virtual Backend backend() const = 0;
  virtual void make_current() = 0;
  /// Opaque native window (GLFWwindow*) for Glfw, nullptr otherwise.
  virtual void* native_window() const { return nullptr; }

  /// "vendor | renderer | version" of the current context.
  std::string description() const;

 protected:
  Context() = default;
};

/// True when the current context renders in software (Mesa's llvmpipe,
/// softpipe or swrast): its "GPU" passes run on the CPU cores.
bool renderer_is_software();

/// Creates a context and makes it current. With Backend::Auto (and no
/// SNOWMODEL_GL_BACKEND) tries the headless backends in order. Throws
/// GLError whose message lists each backend tried and why it failed.
std::unique_ptr<Context> create_context(const ContextOptions& options = {});

}  // namespace snow::gl
