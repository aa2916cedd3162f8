#pragma once
// The batch job's OpenGL: the renderer probed beside the scene's load, a
// throwaway warm-up context where the plan allows one, and a context of
// its own for each stage. It tracks the GL facts the planner needs.
#include <cstdint>
#include <future>
#include <memory>
#include <optional>

#include "app/commands.h"
#include "gl/context.h"
#include "plan/machine.h"

namespace snow::app {

class RunGl {
 public:
  /// Starts probing the renderer of `machine` (plan::probe_renderer, which
  /// may load libEGL) on another thread, and then, where plan::warm_up_gl
  /// allows for an input of `input_bytes`, a warm-up context: EGL displays
  /// stay initialized for the process, so the first stage's own context
  /// comes cheaply. Any GL trouble is reported when a stage makes its
  /// context.
  RunGl(const GlobalOptions& global, const plan::MachineInfo& machine, uint64_t input_bytes);
  /// Waits for the probe and the warm-up.
  ~RunGl();
  RunGl(const RunGl&) = delete;
  RunGl& operator=(const RunGl&) = delete;

  /// The machine with its renderer as probed (waits for the probe).
  const plan::MachineInfo& machine();
  /// Whether a warm-up context is being made.
  bool warming();
  /// Where the probe could not tell the renderer, asks the current context
  /// (a stage's, made up front) and returns true; else returns false.
  bool learn_renderer();

  /// A stage's context, current on this thread until it goes: where the
  /// probe told the renderer, made only when a pass needs it
  /// (gl::OnDemandContext, which answers `software` until then), so small
  /// scenes never load the driver; else made now, as only a context can
  /// tell the renderer. Mesa keeps much of what a stage deleted allocated
  /// in its context: a context per stage frees it for the next.
  std::unique_ptr<gl::OnDemandContext> stage_context(bool software);
  /// A context made now (after the warm-up), current on this thread.
  std::unique_ptr<gl::Context> context();
  /// Whether the run has made a context (the warm-up's included).
  bool used() { return used_ || warming(); }

 private:
  void wait_for_probe();

  const GlobalOptions& global_;
  plan::MachineInfo machine_;
  bool probed_ = false;          // the probe has been waited for
  bool renderer_known_ = false;  // the probe told the renderer
  bool warming_ = false;
  bool described_ = false;
  bool used_ = false;
  // The probe's task sets warm_up_: declared first, it goes after the probe.
  std::future<void> warm_up_;
  std::future<std::optional<bool>> probe_;
};

/// The machine as `snowmodel snow` would find it, for `snowmodel info`:
/// probed, and where only a context can tell, the current context's
/// renderer (with `context_current`).
plan::MachineInfo probe_machine_for_info(const gl::ContextOptions& options, bool context_current);

}  // namespace snow::app
