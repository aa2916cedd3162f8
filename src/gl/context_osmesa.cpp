// OSMesa backend: Mesa's off-screen GL (gallium llvmpipe), a GL 4.5 core
// context (or the highest core version >= 4.3) rendering into a small
// malloc'd colour buffer. Passes render to framebuffer objects anyway.
//
// libOSMesa is opened when this backend is first asked for, not linked:
// it links LLVM and its dependencies, whose loading (thousands of page
// faults of the relocations) every run would pay at start otherwise, twice
// with the huge-pages re-execution (core/heap.h), though most runs
// use EGL.
#include <GL/osmesa.h>
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"
#include "gl/context_internal.h"

namespace snow::gl::detail {
namespace {

constexpr int kBufferSize = 16;  // pixels per side of the default buffer

// The OSMesa entry points this backend calls, from the library opened once.
struct OSMesaApi {
  decltype(&OSMesaCreateContextAttribs) create_context_attribs = nullptr;
  decltype(&OSMesaMakeCurrent) make_current = nullptr;
  decltype(&OSMesaGetCurrentContext) get_current_context = nullptr;
  decltype(&OSMesaDestroyContext) destroy_context = nullptr;
  decltype(&OSMesaGetProcAddress) get_proc_address = nullptr;
  bool complete = false;  // every entry point found
};

const OSMesaApi& osmesa() {
  static const OSMesaApi api = [] {
    void* lib = open_library({"libOSMesa.so.8", "libOSMesa.so"});
    OSMesaApi a;
    if (!lib) return a;
    a.complete = find_symbol(lib, a.create_context_attribs, "OSMesaCreateContextAttribs") &&
                 find_symbol(lib, a.make_current, "OSMesaMakeCurrent") &&
                 find_symbol(lib, a.get_current_context, "OSMesaGetCurrentContext") &&
                 find_symbol(lib, a.destroy_context, "OSMesaDestroyContext") &&
                 find_symbol(lib, a.get_proc_address, "OSMesaGetProcAddress");
    return a;
  }();
  if (!api.complete) {
    throw GLError(
        "osmesa: libOSMesa.so.8 with OSMesaCreateContextAttribs not found (install "
        "libosmesa6)");
  }
  return api;
}

ProcAddressFn osmesa_loader() { return reinterpret_cast<ProcAddressFn>(osmesa().get_proc_address); }

class OSMesaContextImpl final : public Context {
 public:
  ~OSMesaContextImpl() override {
    if (context_) {
      const OSMesaApi& api = osmesa();
      if (api.get_current_context() == context_) api.make_current(nullptr, nullptr, 0, 0, 0);
      api.destroy_context(context_);
    }
  }

  Backend backend() const override { return Backend::OSMesa; }

  void make_current() override {
    if (!osmesa().make_current(context_, buffer_.data(), GL_UNSIGNED_BYTE, kBufferSize,
                               kBufferSize)) {
      throw GLError("osmesa: OSMesaMakeCurrent failed");
    }
    load_functions(osmesa_loader(), Backend::OSMesa);
  }

  void create(const ContextOptions& options) {
    for (int minor : {5, 4, 3}) {
      const int attribs[] = {OSMESA_FORMAT,
                             OSMESA_RGBA,
                             OSMESA_DEPTH_BITS,
                             24,
                             OSMESA_STENCIL_BITS,
                             8,
                             OSMESA_PROFILE,
                             OSMESA_CORE_PROFILE,
                             OSMESA_CONTEXT_MAJOR_VERSION,
                             4,
                             OSMESA_CONTEXT_MINOR_VERSION,
                             minor,
                             0};
      context_ = osmesa().create_context_attribs(attribs, nullptr);
      if (context_) break;
    }
    if (!context_) throw GLError("OSMesaCreateContextAttribs for OpenGL 4.3+ core failed");
    buffer_.assign(static_cast<size_t>(kBufferSize) * kBufferSize, 0u);
    if (!osmesa().make_current(context_, buffer_.data(), GL_UNSIGNED_BYTE, kBufferSize,
                               kBufferSize)) {
      throw GLError("OSMesaMakeCurrent failed");
    }
    init_new_context(osmesa_loader(), Backend::OSMesa, options);
  }

 private:
  OSMesaContext context_ = nullptr;
  std::vector<uint32_t> buffer_;  // RGBA8 pixels
};

}  // namespace

std::unique_ptr<Context> create_osmesa_context(const ContextOptions& options) {
  auto context = std::make_unique<OSMesaContextImpl>();
  context->create(options);
  return context;
}

}  // namespace snow::gl::detail
