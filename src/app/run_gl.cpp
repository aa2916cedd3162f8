#include "app/run_gl.h"

#include "core/log.h"
#include "plan/plan.h"

namespace snow::app {

RunGl::RunGl(const GlobalOptions& global, const plan::MachineInfo& machine, uint64_t input_bytes)
    : global_(global), machine_(machine) {
  gl::ContextOptions options;
  options.backend = gl::parse_backend(global.gl_backend);
  probe_ = std::async(std::launch::async, [this, options, input_bytes] {
    plan::MachineInfo probed = machine_;
    probed.software = plan::probe_renderer(options);
    warming_ = plan::warm_up_gl(probed, input_bytes);
    if (warming_) {
      warm_up_ = std::async(std::launch::async, [this] {
        const QuietThread quiet;
        try {
          make_headless_context(global_);
        } catch (const std::exception&) {
        }
      });
    }
    return probed.software;
  });
}

RunGl::~RunGl() {
  if (probe_.valid()) probe_.wait();
  if (warm_up_.valid()) warm_up_.wait();
}

void RunGl::wait_for_probe() {
  if (probed_) return;
  machine_.software = probe_.get();
  renderer_known_ = machine_.software.has_value();
  probed_ = true;
}

const plan::MachineInfo& RunGl::machine() {
  wait_for_probe();
  return machine_;
}

bool RunGl::warming() {
  wait_for_probe();
  return warming_;
}

std::unique_ptr<gl::Context> RunGl::context() {
  wait_for_probe();
  if (warm_up_.valid()) warm_up_.wait();
  auto context = make_headless_context(global_);
  if (!described_) log_info("OpenGL: " + context->description());
  described_ = used_ = true;
  return context;
}

std::unique_ptr<gl::OnDemandContext> RunGl::stage_context(bool software) {
  wait_for_probe();
  auto context =
      std::make_unique<gl::OnDemandContext>([this] { return this->context(); }, software);
  if (!renderer_known_) context->make();
  return context;
}

bool RunGl::learn_renderer() {
  wait_for_probe();
  if (machine_.software) return false;
  machine_.software = plan::current_gl_is_software();
  return true;
}

plan::MachineInfo probe_machine_for_info(const gl::ContextOptions& options, bool context_current) {
  plan::MachineInfo machine = plan::probe_machine(options);
  machine.software = plan::probe_renderer(options);
  if (!machine.software && context_current) machine.software = plan::current_gl_is_software();
  return machine;
}

}  // namespace snow::app
