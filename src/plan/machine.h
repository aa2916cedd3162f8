#pragma once
// How the planner finds the machine's facts (plan::MachineInfo,
// plan::GlFacts): the only place besides src/gl that asks GL what it
// renders on. Every stage receives these facts, or the choices made from
// them, as arguments.
#include <optional>

#include "gl/context.h"
#include "plan/plan.h"

namespace snow::plan {

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
bool current_gl_is_software();

}  // namespace snow::plan
