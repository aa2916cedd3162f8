// EGL backends: EGL_EXT_platform_device (a GPU without a display server) and
// EGL_MESA_platform_surfaceless (Mesa, e.g. llvmpipe on a machine without a
// GPU). Both make a GL 4.5 core context current without any surface
// (EGL_KHR_surfaceless_context), or with a tiny pbuffer where that extension
// is missing; all rendering goes to framebuffer objects.
//
// libEGL is opened at run time, on first use (open_library), as libOSMesa
// is: a program start that needs no GL does not pay for loading it (twice
// with the huge-page re-execution). The snow command's probe for a hardware
// device asks EGL only where the machine has a GPU device node, and runs
// beside the scene's load.
#define EGL_NO_X11
#define MESA_EGL_NO_X11_HEADERS
#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstring>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "core/error.h"
#include "gl/context_internal.h"

namespace snow::gl::detail {
namespace {

// The EGL entry points the backends call, from the library opened once.
struct EglApi {
  decltype(&eglGetProcAddress) get_proc_address = nullptr;
  decltype(&eglGetError) get_error = nullptr;
  decltype(&eglQueryString) query_string = nullptr;
  decltype(&eglInitialize) initialize = nullptr;
  decltype(&eglBindAPI) bind_api = nullptr;
  decltype(&eglChooseConfig) choose_config = nullptr;
  decltype(&eglCreateContext) create_context = nullptr;
  decltype(&eglCreatePbufferSurface) create_pbuffer_surface = nullptr;
  decltype(&eglMakeCurrent) make_current = nullptr;
  decltype(&eglGetCurrentContext) get_current_context = nullptr;
  decltype(&eglDestroyContext) destroy_context = nullptr;
  decltype(&eglDestroySurface) destroy_surface = nullptr;
  bool complete = false;  // every entry point found
};

const EglApi& egl() {
  static const EglApi api = [] {
    void* lib = open_library({"libEGL.so.1", "libEGL.so"});
    EglApi a;
    if (!lib) return a;
    a.complete = find_symbol(lib, a.get_proc_address, "eglGetProcAddress") &&
                 find_symbol(lib, a.get_error, "eglGetError") &&
                 find_symbol(lib, a.query_string, "eglQueryString") &&
                 find_symbol(lib, a.initialize, "eglInitialize") &&
                 find_symbol(lib, a.bind_api, "eglBindAPI") &&
                 find_symbol(lib, a.choose_config, "eglChooseConfig") &&
                 find_symbol(lib, a.create_context, "eglCreateContext") &&
                 find_symbol(lib, a.create_pbuffer_surface, "eglCreatePbufferSurface") &&
                 find_symbol(lib, a.make_current, "eglMakeCurrent") &&
                 find_symbol(lib, a.get_current_context, "eglGetCurrentContext") &&
                 find_symbol(lib, a.destroy_context, "eglDestroyContext") &&
                 find_symbol(lib, a.destroy_surface, "eglDestroySurface");
    return a;
  }();
  if (!api.complete) {
    throw GLError("egl: libEGL.so.1 with EGL 1.4 not found (install libegl1)");
  }
  return api;
}

const char* egl_error_name(EGLint error) {
  switch (error) {
    case EGL_SUCCESS:
      return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE:
      return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP:
      return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW:
      return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE:
      return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST:
      return "EGL_CONTEXT_LOST";
    default:
      return "EGL error";
  }
}

std::string egl_error() { return egl_error_name(egl().get_error()); }

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    const bool starts = p == list || p[-1] == ' ';
    const bool ends = p[n] == '\0' || p[n] == ' ';
    if (starts && ends) return true;
  }
  return false;
}

ProcAddressFn egl_loader() { return reinterpret_cast<ProcAddressFn>(egl().get_proc_address); }

// One eglInitialize per display, kept for the life of the process: the
// same EGLDisplay is shared by every context on it (eglTerminate would pull
// it from under the others), re-initializing costs time, and Mesa leaks a
// little driver state on eglTerminate. The OS frees it all at exit.
void initialize_display(EGLDisplay display) {
  static std::set<EGLDisplay> initialized;
  if (initialized.count(display)) return;
  EGLint major = 0;
  EGLint minor = 0;
  if (!egl().initialize(display, &major, &minor)) {
    throw GLError("eglInitialize failed (" + egl_error() + ")");
  }
  initialized.insert(display);
}

class EglContext final : public Context {
 public:
  EglContext(Backend backend, EGLDisplay display) : backend_(backend), display_(display) {
    initialize_display(display_);
  }
  ~EglContext() override {
    const EglApi& api = egl();
    if (context_ != EGL_NO_CONTEXT) {
      if (api.get_current_context() == context_) {
        api.make_current(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      }
      api.destroy_context(display_, context_);
    }
    if (surface_ != EGL_NO_SURFACE) api.destroy_surface(display_, surface_);
  }

  Backend backend() const override { return backend_; }

  void make_current() override {
    // Another backend (OSMesa) may have taken the thread since; libglvnd
    // skips an eglMakeCurrent of the context it thinks is current, so
    // release first to make Mesa really bind this one again.
    const EglApi& api = egl();
    if (api.get_current_context() == context_ && !functions_loaded_from(egl_loader())) {
      api.make_current(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    }
    if (!api.make_current(display_, surface_, surface_, context_)) {
      throw GLError(to_string(backend_) + ": eglMakeCurrent failed (" + egl_error() + ")");
    }
    load_functions(egl_loader(), backend_);
  }

  // Creates the context (GL 4.5 core, else 4.4, else 4.3) and makes it current.
  void create(const ContextOptions& options) {
    const EglApi& api = egl();
    const char* extensions = api.query_string(display_, EGL_EXTENSIONS);
    const bool surfaceless = has_extension(extensions, "EGL_KHR_surfaceless_context");
    const bool no_config = has_extension(extensions, "EGL_KHR_no_config_context");
    if (!api.bind_api(EGL_OPENGL_API)) {
      throw GLError("no desktop OpenGL on this EGL display (" + egl_error() + ")");
    }

    EGLConfig config = nullptr;
    if (!(surfaceless && no_config)) {
      const EGLint attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE,
                                EGL_PBUFFER_BIT, EGL_NONE};
      EGLint count = 0;
      if (!api.choose_config(display_, attribs, &config, 1, &count) || count < 1) {
        throw GLError("no EGL config with OpenGL and pbuffers");
      }
    }

    std::string last_error;
    // Ask for reset notification first (EGL 1.5 / EGL_EXT_create_context_robustness),
    // so that a GPU reset shows as glGetGraphicsResetStatus != GL_NO_ERROR
    // (gl::check_error turns it into a GLError); fall back to a plain context.
    for (EGLint minor : {5, 4, 3}) {
      for (bool robust : {true, false}) {
        std::vector<EGLint> attribs = {
            EGL_CONTEXT_MAJOR_VERSION,       4,
            EGL_CONTEXT_MINOR_VERSION,       minor,
            EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT};
        if (want_debug(options)) {
          attribs.push_back(EGL_CONTEXT_OPENGL_DEBUG);
          attribs.push_back(EGL_TRUE);
        }
        if (robust) {
          attribs.push_back(EGL_CONTEXT_OPENGL_RESET_NOTIFICATION_STRATEGY);
          attribs.push_back(EGL_LOSE_CONTEXT_ON_RESET);
        }
        attribs.push_back(EGL_NONE);
        context_ = api.create_context(display_, config ? config : EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT,
                                      attribs.data());
        if (context_ != EGL_NO_CONTEXT) break;
        last_error = egl_error();
      }
      if (context_ != EGL_NO_CONTEXT) break;
    }
    if (context_ == EGL_NO_CONTEXT) {
      throw GLError("eglCreateContext for OpenGL 4.3+ core failed (" + last_error + ")");
    }
    if (!surfaceless) {
      const EGLint attribs[] = {EGL_WIDTH, 16, EGL_HEIGHT, 16, EGL_NONE};
      surface_ = api.create_pbuffer_surface(display_, config, attribs);
      if (surface_ == EGL_NO_SURFACE) {
        throw GLError("eglCreatePbufferSurface failed (" + egl_error() + ")");
      }
    }
    if (!api.make_current(display_, surface_, surface_, context_)) {
      throw GLError("eglMakeCurrent failed (" + egl_error() + ")");
    }
    init_new_context(egl_loader(), backend_, options);
  }

 private:
  Backend backend_;
  EGLDisplay display_;
  EGLContext context_ = EGL_NO_CONTEXT;
  EGLSurface surface_ = EGL_NO_SURFACE;
};

template <typename Fn>
Fn egl_function(const char* name) {
  return reinterpret_cast<Fn>(egl().get_proc_address(name));
}

}  // namespace

std::unique_ptr<Context> create_egl_device_context(const ContextOptions& options) {
  const char* client = egl().query_string(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_EXT_platform_device") ||
      !has_extension(client, "EGL_EXT_device_enumeration")) {
    throw GLError("EGL has no EGL_EXT_platform_device/EGL_EXT_device_enumeration");
  }
  auto query_devices = egl_function<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
  auto query_device_string =
      egl_function<PFNEGLQUERYDEVICESTRINGEXTPROC>("eglQueryDeviceStringEXT");
  auto get_platform_display =
      egl_function<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
  if (!query_devices || !query_device_string || !get_platform_display) {
    throw GLError("EGL device functions missing");
  }
  EGLDeviceEXT devices[16];
  EGLint count = 0;
  if (!query_devices(16, devices, &count) || count < 1) {
    throw GLError("no EGL devices");
  }

  // Hardware devices only: a software device (EGL_MESA_device_software) is
  // what egl-surfaceless gives too, so Auto moves on to that instead.
  std::string reasons;
  int software = 0;
  for (EGLint i = 0; i < count; ++i) {
    const char* exts = query_device_string(devices[i], EGL_EXTENSIONS);
    if (has_extension(exts, "EGL_MESA_device_software")) {
      ++software;
      continue;
    }
    EGLDisplay display = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
    if (display == EGL_NO_DISPLAY) {
      reasons += " device " + std::to_string(i) + ": no display (" + egl_error() + ")";
      continue;
    }
    try {
      auto context = std::make_unique<EglContext>(Backend::EglDevice, display);
      context->create(options);
      return context;
    } catch (const GLError& e) {
      reasons += std::string(" device ") + std::to_string(i) + ": " + e.what();
    }
  }
  if (reasons.empty()) {
    throw GLError("no hardware EGL device (" + std::to_string(software) + " software only)");
  }
  throw GLError("no EGL device worked:" + reasons);
}

std::optional<bool> egl_lists_hardware_device() {
  // A hardware device has a device node: under /dev/dri (Mesa's drivers,
  // virtual GPUs) or NVIDIA's /dev/nvidiactl. Without either, EGL lists none,
  // and asking it would load libEGL and Mesa's vendor library for nothing.
  std::error_code error;
  if (!std::filesystem::exists("/dev/dri", error) &&
      !std::filesystem::exists("/dev/nvidiactl", error)) {
    return false;
  }
  const EglApi* api = nullptr;
  try {
    api = &egl();
  } catch (const GLError&) {
    return std::nullopt;  // no libEGL
  }
  // Where EGL cannot list its devices, NVIDIA's driver node still tells:
  // its EGL renders on the GPU (where libglvnd lists no devices, asking
  // would start the driver for every scene).
  const std::optional<bool> unlisted =
      std::filesystem::exists("/dev/nvidiactl", error) ? std::optional<bool>(true) : std::nullopt;
  const char* client = api->query_string(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_EXT_device_enumeration")) return unlisted;
  auto query_devices = egl_function<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
  auto query_device_string =
      egl_function<PFNEGLQUERYDEVICESTRINGEXTPROC>("eglQueryDeviceStringEXT");
  if (!query_devices || !query_device_string) return unlisted;
  EGLDeviceEXT devices[16];
  EGLint count = 0;
  if (!query_devices(16, devices, &count) || count < 1) return unlisted;
  for (EGLint i = 0; i < count; ++i) {
    if (!has_extension(query_device_string(devices[i], EGL_EXTENSIONS),
                       "EGL_MESA_device_software")) {
      return true;
    }
  }
  return false;
}

std::unique_ptr<Context> create_egl_surfaceless_context(const ContextOptions& options) {
  const char* client = egl().query_string(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_MESA_platform_surfaceless")) {
    throw GLError("EGL has no EGL_MESA_platform_surfaceless");
  }
  auto get_platform_display =
      egl_function<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
  if (!get_platform_display) throw GLError("eglGetPlatformDisplayEXT missing");
  EGLDisplay display =
      get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (display == EGL_NO_DISPLAY) {
    throw GLError("no surfaceless EGL display (" + egl_error() + ")");
  }
  auto context = std::make_unique<EglContext>(Backend::EglSurfaceless, display);
  context->create(options);
  return context;
}

}  // namespace snow::gl::detail
