#pragma once
// Facts about the machine that the planner's choices depend on. Only the
// planner (src/plan) and src/gl ask GL what it renders on; every stage
// receives these facts, or the choices made from them, as arguments.
#include <optional>

#include "gl/context.h"

namespace snow::plan {

/// What GL renders on, and whether the process has started it, as known
/// when a stage begins.
struct GlFacts {
  bool software = false;  // a software rasterizer (Mesa's llvmpipe, softpipe, swrast): its
                          // "GPU" passes run on the CPU cores
  bool started = false;   // a GL context has been made in this process: the driver is loaded
                          // and further contexts come cheaply
};

/// What the batch job knows of the machine before any context is made.
struct MachineInfo {
  /// Whether GL renders in software (gl::probe_software): empty where only
  /// a context can tell (GLFW, EGL without device enumeration) and where
  /// the backend is named (--gl-backend, SNOWMODEL_GL_BACKEND).
  std::optional<bool> software;
  /// The GL backend is a window (GLFW), which must start on the main thread.
  bool window_backend = false;
  /// CPU cores the stages may use (parallel_for's default_threads()), >= 1.
  unsigned cores = 1;
  /// The (virtual) machine hands free memory back to its host in 2 MiB
  /// blocks (core/heap.h, free_pages_reported): huge pages cost more there.
  bool reports_free_pages = false;
};

/// Probes the machine for a run whose contexts are made with `options`:
/// the cores, the free-page reporting and whether the backend is a window.
/// MachineInfo::software is left empty: probe_renderer fills it. Throws
/// InputError for a bad SNOWMODEL_GL_BACKEND.
MachineInfo probe_machine(const gl::ContextOptions& options);

/// MachineInfo::software for `options`: gl::probe_software (which may load
/// libEGL, but makes no context) where the backend is automatic, else
/// empty (a named backend is always started, so that a missing one is
/// reported). Throws InputError for a bad SNOWMODEL_GL_BACKEND.
std::optional<bool> probe_renderer(const gl::ContextOptions& options);

/// The facts of this thread's GL state now: the current context's renderer
/// (or what an uninstantiated gl::OnDemandContext was told) and
/// gl::context_made(). For callers without a plan of their own (tests,
/// benchmark tools): the batch job tracks these facts itself.
GlFacts current_gl();

/// Whether the current context renders in software (gl::renderer_is_software).
bool current_renderer_is_software();

}  // namespace snow::plan
