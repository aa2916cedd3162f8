#pragma once
// OpenGL contexts behind one interface. Only the backend .cpp files include
// EGL, OSMesa or GLFW headers. Every backend gives a GL 4.5 core context
// (4.3 at least) with functions loaded through glad from its own
// get-proc-address.
#include <functional>
#include <memory>
#include <optional>
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
/// softpipe or swrast): its "GPU" passes run on the CPU cores. While an
/// OnDemandContext of this thread is not made yet: what it was told.
/// False where no context has loaded the GL functions yet.
bool renderer_is_software();

/// Creates a context and makes it current. With Backend::Auto (and no
/// SNOWMODEL_GL_BACKEND) tries the headless backends in order. Throws
/// GLError whose message lists each backend tried and why it failed.
std::unique_ptr<Context> create_context(const ContextOptions& options = {});

/// Whether create_context has made a context in this process, on any
/// thread: after that the driver is loaded, and further contexts come
/// cheaply (EGL displays stay initialized).
bool context_made();

/// The backend create_context(options) tries: options.backend, or for Auto
/// the one SNOWMODEL_GL_BACKEND names (if set; InputError for a bad name).
Backend requested_backend(const ContextOptions& options);

/// Whether create_context(options) would give a software renderer, found
/// without creating a context: OSMesa always; Auto (and SNOWMODEL_GL_BACKEND),
/// egl-device and egl-surfaceless when EGL lists devices and none is
/// hardware (Mesa's surfaceless display then runs llvmpipe); not where EGL
/// lists no devices but NVIDIA's driver node (/dev/nvidiactl) is there.
/// Empty where only a context can tell (GLFW; other EGL without device
/// enumeration).
std::optional<bool> probe_software(const ContextOptions& options = {});

/// A context made when a pass first needs GL (require_context), for runs
/// whose passes may all go to the CPU (small maps where GL renders in
/// software): those never load the driver. Installed on
/// the constructing thread, one at a time; `make` creates the context (and
/// makes it current), `software` answers renderer_is_software() until then.
/// The context, if made, is destroyed with this object.
class OnDemandContext {
 public:
  OnDemandContext(std::function<std::unique_ptr<Context>()> make, bool software);
  ~OnDemandContext();
  OnDemandContext(const OnDemandContext&) = delete;
  OnDemandContext& operator=(const OnDemandContext&) = delete;

  bool made() const { return context_ != nullptr; }
  bool software() const { return software_; }
  void make();

 private:
  std::function<std::unique_ptr<Context>()> make_;
  bool software_;
  std::unique_ptr<Context> context_;
};

/// Called by every pass before its first GL call: makes this thread's
/// OnDemandContext if there is one and it is not made yet (else a context
/// must be current, as without one). Throws what making it throws.
void require_context();

}  // namespace snow::gl
