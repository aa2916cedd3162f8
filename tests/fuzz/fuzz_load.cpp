// libFuzzer target: glTF loading (.glb and .gltf JSON, detected by content)
// from arbitrary bytes. Every input must give a Scene or an InputError;
// anything else (crash, other exception, sanitizer report, hang) is a
// finding. Loaded scenes are checked against the Scene contract.
#include <cmath>
#include <cstdint>

#include "core/error.h"
#include "core/log.h"
#include "fuzz_common.h"
#include "scene/load_gltf.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  snow::set_log_level(snow::LogLevel::Quiet);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = snow::fuzz::write_input(data, size);
  snow::LoadSettings settings;
  // Keep single inputs cheap: the limits are the loader's own, scaled down.
  settings.limits.max_triangles = 2'000'000;
  settings.limits.max_image_pixels = 1 << 20;
  // Lines and animations (the tracks' sources) are read too.
  settings.lines = settings.motions = true;
  settings.limits.max_line_segments = 1'000'000;
  settings.limits.max_motion_samples = 100'000;
  try {
    const snow::Scene scene = snow::load_scene(path, settings);
    if (scene.positions.size() % 3 != 0 || scene.normals.size() != scene.positions.size() ||
        (!scene.uvs.empty() && scene.uvs.size() != scene.positions.size()) ||
        scene.triangle_count() == 0) {
      __builtin_trap();
    }
    size_t covered = 0;
    for (const snow::SceneObject& o : scene.objects) {
      if (o.first_triangle != covered) __builtin_trap();
      covered += o.triangle_count;
      if (o.material >= int(scene.materials.size())) __builtin_trap();
    }
    if (covered != scene.triangle_count()) __builtin_trap();
    for (const glm::vec3& p : scene.positions) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
    }
    (void)snow::scene_summary_json(scene);
    (void)snow::scene_summary_text(scene);
  } catch (const snow::InputError&) {
  }
  return 0;
}
