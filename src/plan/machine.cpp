#include "plan/machine.h"

#include <algorithm>

#include "core/heap.h"
#include "core/parallel.h"

namespace snow::plan {

MachineInfo probe_machine(const gl::ContextOptions& options) {
  MachineInfo machine;
  const gl::Backend backend = gl::requested_backend(options);
  machine.window_backend = backend == gl::Backend::Glfw;
  machine.cores = std::max(1u, default_threads());
  machine.reports_free_pages = free_pages_reported();
  return machine;
}

std::optional<bool> probe_renderer(const gl::ContextOptions& options) {
  if (gl::requested_backend(options) != gl::Backend::Auto) return std::nullopt;
  return gl::probe_software(options);
}

GlFacts current_gl() { return {gl::renderer_is_software(), gl::context_made()}; }

bool current_gl_is_software() { return gl::renderer_is_software(); }

}  // namespace snow::plan
