// `snowmodel info [SCENE] [--json]`: the GL context in use, and a scene summary.
#include <cstdio>

#include "app/commands.h"
#include "core/heap.h"
#include "scene/load_gltf.h"

namespace snow::app {

void register_info(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string scene;
    bool json = false;
    bool no_gl = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd =
      app.add_subcommand("info", "Print the OpenGL context in use and a summary of a scene");
  cmd->add_option("scene", options->scene, "glTF 2.0 scene (.gltf or .glb)");
  cmd->add_flag("--json", options->json, "Print the scene summary as JSON");
  cmd->add_flag("--no-gl", options->no_gl, "Do not create an OpenGL context");
  cmd->callback([options, &global] {
    if (!options->no_gl && !options->json) {
      auto context = make_headless_context(global);
      std::printf("OpenGL: %s (%s)\n", context->description().c_str(),
                  gl::to_string(context->backend()).c_str());
      const bool software = gl::renderer_is_software();
      std::printf("Stabilizer (--stabilizer auto): CPU passes (the preview: %s)\n",
                  software ? "CPU passes, the GL renderer is software" : "GPU passes");
      std::printf("Peel (--peel-device auto): %s\n",
                  software ? "the CPU, unless the triangles stack deep"
                           : "the GPU's passes (the CPU for a small scene in `snow`, which then "
                             "may never start the driver)");
      std::printf("Coverage (--coverage-method auto): %s\n",
                  software ? "shadow maps or rays on the CPU, or GL's shadow maps, whichever costs "
                             "less"
                           : "shadow maps, or rays on the GPU where they cost less (the CPU where "
                             "`snow` has not started the driver and the CPU takes under 0.05 s)");
    }
    if (!options->json) {
      std::printf("Huge pages for the heap: %s\n", huge_pages_status().c_str());
      std::printf("mmap threshold: %s\n", mmap_threshold_status().c_str());
    }
    if (options->scene.empty()) return;
    const Scene scene = load_scene(options->scene);
    std::printf("%s\n", options->json ? scene_summary_json(scene).c_str()
                                      : scene_summary_text(scene).c_str());
  });
}

}  // namespace snow::app
