// Backend-independent part of the GL contexts: backend names, the Auto
// fallback order, function loading through glad, the version check and
// KHR_debug output.
#include "gl/context.h"

#include <dlfcn.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/log.h"
#include "gl/context_internal.h"
#include "gl/gl.h"

namespace snow::gl {
namespace {

constexpr int kMinMajor = 4;
constexpr int kMinMinor = 3;

// The loader whose functions glad holds now (nullptr: none or unknown).
detail::ProcAddressFn g_loaded_from = nullptr;
// Whether create_context has made a context in this process (on any thread).
std::atomic<bool> g_context_made{false};

const char* debug_type_name(GLenum type) {
  switch (type) {
    case GL_DEBUG_TYPE_ERROR:
      return "error";
    case GL_DEBUG_TYPE_DEPRECATED_BEHAVIOR:
      return "deprecated";
    case GL_DEBUG_TYPE_UNDEFINED_BEHAVIOR:
      return "undefined behaviour";
    case GL_DEBUG_TYPE_PORTABILITY:
      return "portability";
    case GL_DEBUG_TYPE_PERFORMANCE:
      return "performance";
    default:
      return "other";
  }
}

void GLAD_API_PTR debug_callback(GLenum source, GLenum type, GLuint id, GLenum severity,
                                 GLsizei length, const GLchar* message, const void* /*user*/) {
  std::string text(message, length > 0 ? static_cast<size_t>(length) : std::strlen(message));
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  const std::string line =
      std::string("GL ") + debug_type_name(type) + " " + std::to_string(id) + ": " + text;
  // Shader compile errors come back as GLError with the log: no warning twice.
  const bool reported_elsewhere = source == GL_DEBUG_SOURCE_SHADER_COMPILER;
  if (!reported_elsewhere && (type == GL_DEBUG_TYPE_ERROR || severity == GL_DEBUG_SEVERITY_HIGH)) {
    log_warn(line);
  } else {
    log_debug(line);
  }
}

// "?" also where no context has loaded the functions yet.
const char* gl_string(GLenum name) {
  if (glGetString == nullptr) return "?";
  const GLubyte* s = glGetString(name);
  return s ? reinterpret_cast<const char*>(s) : "?";
}

}  // namespace

std::string to_string(Backend backend) {
  switch (backend) {
    case Backend::Auto:
      return "auto";
    case Backend::EglDevice:
      return "egl-device";
    case Backend::EglSurfaceless:
      return "egl-surfaceless";
    case Backend::OSMesa:
      return "osmesa";
    case Backend::Glfw:
      return "glfw";
  }
  return "unknown";
}

Backend parse_backend(const std::string& name) {
  for (Backend b : {Backend::Auto, Backend::EglDevice, Backend::EglSurfaceless, Backend::OSMesa,
                    Backend::Glfw}) {
    if (name == to_string(b)) return b;
  }
  throw InputError("unknown GL backend '" + name +
                   "' (valid: auto, egl-device, egl-surfaceless, osmesa, glfw)");
}

std::string Context::description() const {
  return std::string(gl_string(GL_VENDOR)) + " | " + gl_string(GL_RENDERER) + " | " +
         gl_string(GL_VERSION);
}

namespace {
thread_local OnDemandContext* t_on_demand = nullptr;  // this thread's, if installed
}  // namespace

OnDemandContext::OnDemandContext(std::function<std::unique_ptr<Context>()> make, bool software)
    : make_(std::move(make)), software_(software) {
  if (t_on_demand) throw std::logic_error("an OnDemandContext is already installed");
  t_on_demand = this;
}

OnDemandContext::~OnDemandContext() {
  context_.reset();
  t_on_demand = nullptr;
}

void OnDemandContext::make() {
  if (!context_) context_ = make_();
}

void require_context() {
  if (t_on_demand) t_on_demand->make();
}

Backend requested_backend(const ContextOptions& options) {
  const char* env = std::getenv("SNOWMODEL_GL_BACKEND");
  if (options.backend != Backend::Auto || !env || !*env) return options.backend;
  try {
    return parse_backend(env);
  } catch (const InputError& e) {
    throw InputError(std::string("SNOWMODEL_GL_BACKEND: ") + e.what());
  }
}

std::optional<bool> probe_software(const ContextOptions& options) {
  switch (requested_backend(options)) {
    case Backend::OSMesa:
      return true;
    case Backend::Glfw:
      return std::nullopt;
    default: {
      const std::optional<bool> hardware = detail::egl_lists_hardware_device();
      if (!hardware) return std::nullopt;
      return !*hardware;
    }
  }
}

bool renderer_is_software() {
  if (t_on_demand && !t_on_demand->made()) return t_on_demand->software();
  const std::string renderer = gl_string(GL_RENDERER);
  for (const char* name :
       {"llvmpipe", "softpipe", "swrast", "Software Rasterizer", "SwiftShader"}) {
    if (renderer.find(name) != std::string::npos) return true;
  }
  return false;
}

namespace detail {

void* open_library(std::initializer_list<const char*> names) {
  for (const char* name : names) {
    if (void* library = dlopen(name, RTLD_NOW | RTLD_LOCAL)) return library;
  }
  return nullptr;
}

void* library_symbol(void* library, const char* symbol) { return dlsym(library, symbol); }

void load_functions(ProcAddressFn loader, Backend backend) {
  if (loader == g_loaded_from) return;
  g_loaded_from = nullptr;
  const int version = gladLoadGL(reinterpret_cast<GLADloadfunc>(loader));
  if (version == 0) {
    throw GLError(to_string(backend) + ": could not load the OpenGL functions");
  }
  g_loaded_from = loader;
}

bool functions_loaded_from(ProcAddressFn loader) { return g_loaded_from == loader; }

void forget_loaded_functions(ProcAddressFn loader) {
  if (g_loaded_from == loader) g_loaded_from = nullptr;
}

bool want_debug(const ContextOptions& options) {
#ifndef NDEBUG
  (void)options;
  return true;
#else
  return options.debug;
#endif
}

void init_new_context(ProcAddressFn loader, Backend backend, const ContextOptions& options) {
  g_loaded_from = nullptr;  // a new context: always reload
  load_functions(loader, backend);
  GLint major = 0;
  GLint minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major < kMinMajor || (major == kMinMajor && minor < kMinMinor)) {
    throw GLError(to_string(backend) + ": OpenGL " + std::to_string(major) + "." +
                  std::to_string(minor) + " (" + gl_string(GL_RENDERER) + "), need 4.3 or newer");
  }
  // The RAII creators and the passes use direct state access (core in 4.5).
  if (!glCreateTextures || !glNamedBufferStorage || !glTextureStorage3D) {
    throw GLError(to_string(backend) + ": OpenGL " + std::to_string(major) + "." +
                  std::to_string(minor) + " (" + gl_string(GL_RENDERER) +
                  ") lacks direct state access, need 4.5");
  }
  if (want_debug(options) && glDebugMessageCallback) {
    glEnable(GL_DEBUG_OUTPUT);
    glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
    glDebugMessageCallback(debug_callback, nullptr);
    glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DEBUG_SEVERITY_NOTIFICATION, 0, nullptr,
                          GL_FALSE);
  }
  while (glGetError() != GL_NO_ERROR) {
  }
  log_debug("GL context (" + to_string(backend) + "): " + gl_string(GL_VENDOR) + " | " +
            gl_string(GL_RENDERER) + " | " + gl_string(GL_VERSION));
}

std::unique_ptr<Context> try_backends(const std::vector<Backend>& order,
                                      const ContextOptions& options) {
  std::string reasons;
  for (Backend b : order) {
    try {
      switch (b) {
        case Backend::EglDevice:
          return create_egl_device_context(options);
        case Backend::EglSurfaceless:
          return create_egl_surfaceless_context(options);
        case Backend::OSMesa:
          return create_osmesa_context(options);
        case Backend::Glfw:
          return create_glfw_context(options);
        case Backend::Auto:
          break;
      }
    } catch (const GLError& e) {
      std::string why = e.what();
      const std::string prefix = to_string(b) + ": ";
      if (why.compare(0, prefix.size(), prefix) == 0) why.erase(0, prefix.size());
      if (!reasons.empty()) reasons += "; ";
      reasons += prefix + why;
      log_debug("GL backend " + prefix + why);
    }
  }
  throw GLError("no usable OpenGL: " + reasons, reasons);
}

}  // namespace detail

std::unique_ptr<Context> create_context(const ContextOptions& options) {
  const Backend backend = requested_backend(options);
  std::unique_ptr<Context> context =
      backend == Backend::Auto
          ? detail::try_backends({Backend::EglDevice, Backend::EglSurfaceless, Backend::OSMesa},
                                 options)
          : detail::try_backends({backend}, options);
  g_context_made.store(true, std::memory_order_relaxed);
  return context;
}

bool context_made() { return g_context_made.load(std::memory_order_relaxed); }

}  // namespace snow::gl
