// OSMesa backend: Mesa's off-screen GL (gallium llvmpipe), a GL 4.5 core
// context (or the highest core version >= 4.3) rendering into a small
// malloc'd colour buffer. Passes render to framebuffer objects anyway.
#include <GL/osmesa.h>

#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"
#include "gl/context_internal.h"

namespace snow::gl::detail {
namespace {

constexpr int kBufferSize = 16;  // pixels per side of the default buffer

ProcAddressFn osmesa_loader() { return reinterpret_cast<ProcAddressFn>(&OSMesaGetProcAddress); }

class OSMesaContextImpl final : public Context {
 public:
  ~OSMesaContextImpl() override {
    if (context_) {
      if (OSMesaGetCurrentContext() == context_) {
        OSMesaMakeCurrent(nullptr, nullptr, 0, 0, 0);
      }
      OSMesaDestroyContext(context_);
    }
  }

  Backend backend() const override { return Backend::OSMesa; }

  void make_current() override {
    if (!OSMesaMakeCurrent(context_, buffer_.data(), GL_UNSIGNED_BYTE, kBufferSize, kBufferSize)) {
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
      context_ = OSMesaCreateContextAttribs(attribs, nullptr);
      if (context_) break;
    }
    if (!context_) throw GLError("OSMesaCreateContextAttribs for OpenGL 4.3+ core failed");
    buffer_.assign(static_cast<size_t>(kBufferSize) * kBufferSize, 0u);
    if (!OSMesaMakeCurrent(context_, buffer_.data(), GL_UNSIGNED_BYTE, kBufferSize, kBufferSize)) {
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
