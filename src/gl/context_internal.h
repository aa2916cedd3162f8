#pragma once
// Shared between context.cpp and the backend files. It includes no GL, EGL,
// OSMesa or GLFW header, so each backend file can include its own native
// headers without clashing with glad.
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "gl/context.h"

namespace snow::gl::detail {

/// A get-proc-address function (eglGetProcAddress, OSMesaGetProcAddress,
/// glfwGetProcAddress), in glad's GLADloadfunc shape.
using ProcAddressFn = void (*(*)(const char* name))();

/// The first of the shared libraries `names` that dlopen opens (RTLD_NOW |
/// RTLD_LOCAL), kept open for the program's life; nullptr when none does.
/// The EGL and OSMesa backends open their libraries so, on first use.
void* open_library(std::initializer_list<const char*> names);

/// The address of `symbol` in `library` (from open_library); nullptr where
/// the library lacks it.
void* library_symbol(void* library, const char* symbol);
/// The same, cast to the function pointer type of `fn` and stored there;
/// whether the library has it.
template <class Fn>
bool find_symbol(void* library, Fn& fn, const char* symbol) {
  static_assert(std::is_pointer_v<Fn>);
  fn = reinterpret_cast<Fn>(library_symbol(library, symbol));
  return fn != nullptr;
}

/// Loads the GL functions through `loader` (skipped when the functions
/// already came from this loader), so contexts of different backends can
/// live in one process. Throws GLError naming `backend` if loading fails.
void load_functions(ProcAddressFn loader, Backend backend);

/// True when the GL functions now loaded came from `loader`.
bool functions_loaded_from(ProcAddressFn loader);

/// Forgets which loader the GL functions came from (a backend's library may
/// be unloaded or its context destroyed); the next load_functions reloads.
void forget_loaded_functions(ProcAddressFn loader);

/// Runs once on a freshly created and current context: loads the functions,
/// checks for GL >= 4.3 and turns on KHR_debug output when asked for (or in
/// builds without NDEBUG). Throws GLError naming `backend`.
void init_new_context(ProcAddressFn loader, Backend backend, const ContextOptions& options);

/// True when KHR_debug output should be on for these options.
bool want_debug(const ContextOptions& options);

/// Tries each backend of `order` in turn and returns the first context that
/// works (current). Otherwise throws GLError("no usable OpenGL: <backend>:
/// <reason>; <backend>: <reason>...") with the same list in log().
std::unique_ptr<Context> try_backends(const std::vector<Backend>& order,
                                      const ContextOptions& options);

/// Whether EGL lists a hardware device (one without EGL_MESA_device_software),
/// without creating a display; false without asking EGL where the machine
/// has no GPU device node (/dev/dri, /dev/nvidiactl); empty where EGL cannot
/// list devices.
std::optional<bool> egl_lists_hardware_device();

/// Backend factories: create, make current and init_new_context(), or throw
/// GLError whose message is the short reason (used in the Auto summary).
std::unique_ptr<Context> create_egl_device_context(const ContextOptions& options);
std::unique_ptr<Context> create_egl_surfaceless_context(const ContextOptions& options);
std::unique_ptr<Context> create_osmesa_context(const ContextOptions& options);
std::unique_ptr<Context> create_glfw_context(const ContextOptions& options);

}  // namespace snow::gl::detail
