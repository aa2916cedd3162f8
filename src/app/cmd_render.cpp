// `snowmodel render SCENE -o OUT.png`: a headless preview image of a scene.
#include "app/commands.h"
#include "app/settings.h"
#include "core/log.h"
#include "mesh/output_policy.h"
#include "render/preview.h"
#include "scene/load_gltf.h"

namespace snow::app {

void register_render(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string scene;
    std::string output;
    std::string view = "three-quarter";
    int width = 1280;
    int height = 800;
    float memory_budget_gib = 4.0f;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand("render", "Render a preview PNG of a scene (headless)");
  cmd->add_option("scene", options->scene, "glTF 2.0 scene (.gltf or .glb)")->required();
  cmd->add_option("-o,--output", options->output, "Output PNG file")->required();
  cmd->add_option("--view", options->view, "Camera: three-quarter or top")
      ->check(CLI::IsMember({"three-quarter", "top"}))
      ->capture_default_str();
  cmd->add_option("--width", options->width, "Image width in pixels")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  cmd->add_option("--height", options->height, "Image height in pixels")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  cmd->add_option(
         "--memory-budget", options->memory_budget_gib,
         "Memory budget in GiB for the scene's data and images " + range_text(kMemoryBudgetGib))
      ->capture_default_str();
  cmd->callback([options, &global] {
    check_range("--memory-budget", "", options->memory_budget_gib, kMemoryBudgetGib, true);
    check_output_paths(options->scene, {{"-o", options->output, OutputKind::File, {}, {}}});
    LoadSettings load;
    load.limits.memory_budget = memory_budget_bytes(options->memory_budget_gib);
    const Scene scene = load_scene(options->scene, load);
    auto context = make_headless_context(global);
    render::PreviewSettings settings;
    settings.width = options->width;
    settings.height = options->height;
    settings.view = options->view == "top" ? render::View::Top : render::View::ThreeQuarter;
    const render::ImageRGBA8 image = render::render_preview(scene, {}, glm::vec4(1.0f), settings);
    render::write_png(image, options->output);
    log_info("wrote " + options->output);
  });
}

}  // namespace snow::app
