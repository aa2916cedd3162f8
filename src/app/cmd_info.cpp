// `snowmodel info [SCENE] [--json]`: the GL context in use, the run plan
// (where each stage runs, and why) and a scene summary.
#include <cstdio>

#include "app/commands.h"
#include "app/run_gl.h"
#include "app/settings.h"
#include "core/heap.h"
#include "core/log.h"
#include "plan/plan.h"
#include "scene/load_gltf.h"
#include "snow/peel.h"

namespace snow::app {
namespace {

/// The plan `snowmodel snow SCENE` would make with its defaults (every
/// stage's line; the maps' only with a scene).
void print_plan(const plan::MachineInfo& machine, const Scene* scene, uint64_t input_bytes) {
  PipelineSettings settings;
  settings.peel.max_side = 0;  // as `snow` has it: automatic
  const plan::Settings wanted = plan_settings(settings);
  plan::SceneStats stats;
  const bool maps = scene && !scene->bounds.empty() && scene->triangle_count() > 0;
  if (maps) stats = scene_stats(*scene, settings.peel, wanted, input_bytes);
  const plan::RunPlan run = plan::plan_run(stats, machine, wanted, false);
  const std::vector<std::string> lines = plan::describe(run);
  for (size_t i = maps ? 0 : 1; i < lines.size(); ++i) std::printf("%s\n", lines[i].c_str());
}

}  // namespace

void register_info(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string scene;
    bool json = false;
    bool no_gl = false;
    float memory_budget_gib = 4.0f;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "info", "Print the OpenGL context in use, the run plan and a summary of a scene");
  cmd->add_option("scene", options->scene, "glTF 2.0 scene (.gltf or .glb)");
  cmd->add_flag("--json", options->json, "Print the scene summary as JSON");
  cmd->add_flag("--no-gl", options->no_gl, "Do not create an OpenGL context");
  cmd->add_option("--memory-budget", options->memory_budget_gib,
                  "Memory budget in GiB for the scene's data " + range_text(kMemoryBudgetGib))
      ->capture_default_str();
  cmd->callback([options, &global] {
    check_range("--memory-budget", "", options->memory_budget_gib, kMemoryBudgetGib, true);
    gl::ContextOptions context_options;
    context_options.backend = gl::parse_backend(global.gl_backend);
    std::unique_ptr<gl::Context> context;
    if (!options->no_gl && !options->json) {
      context = make_headless_context(global);
      std::printf("OpenGL: %s (%s)\n", context->description().c_str(),
                  gl::to_string(context->backend()).c_str());
    }
    const plan::MachineInfo machine =
        options->json ? plan::MachineInfo{}
                      : probe_machine_for_info(context_options, context != nullptr);
    if (!options->json) {
      std::printf("Huge pages for the heap: %s\n", huge_pages_status().c_str());
      std::printf("mmap threshold: %s\n", mmap_threshold_status().c_str());
    }
    if (options->scene.empty()) {
      if (!options->json) print_plan(machine, nullptr, 0);
      return;
    }
    LoadSettings load;
    load.limits.memory_budget = memory_budget_bytes(options->memory_budget_gib);
    const Scene scene = load_scene(options->scene, load);
    if (!options->json) print_plan(machine, &scene, gltf_input_bytes(options->scene));
    std::printf("%s\n", options->json ? scene_summary_json(scene).c_str()
                                      : scene_summary_text(scene).c_str());
  });
}

}  // namespace snow::app
