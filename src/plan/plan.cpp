#include "plan/plan.h"

#include <algorithm>
#include <cstdio>

namespace snow::plan {
namespace {

std::string describe_peel(const Settings& settings, const GlFacts& gl) {
  if (settings.peel_device == "cpu") return "a vertical ray per texel on the CPU (--peel-device)";
  if (settings.peel_device == "gpu") return "depth passes on the GPU (--peel-device)";
  if (gl.software) return "a vertical ray per texel on the CPU, unless the triangles stack deep";
  if (!gl.started) return "a vertical ray per texel on the CPU for a small scene, else the GPU";
  return "depth passes on the GPU";
}

std::string describe_coverage(const Settings& settings, const GlFacts& gl) {
  if (settings.coverage_method != "auto") return settings.coverage_method + " (--coverage-method)";
  if (gl.software) {
    return "shadow maps or rays on the CPU cores, or GL's shadow maps, whichever costs less";
  }
  if (!gl.started) {
    return "shadow maps, or rays on the GPU where they cost less (the CPU where that takes "
           "under the driver's start)";
  }
  return "shadow maps, or rays on the GPU where they cost less";
}

}  // namespace

int side_for_depth(int side, float texel, float fall_depth) {
  return std::max(kMinAutoSide, int(float(side) * kAimTexels * texel / fall_depth));
}

bool warm_up_gl(const MachineInfo& machine, uint64_t input_bytes) {
  if (machine.window_backend || machine.software == true) return false;
  // On a GPU, a small input's load hides little of the driver's start, and
  // its passes may all run on the CPU before it (choose_peel,
  // choose_coverage_method): the process would only wait for the warm-up.
  return !(machine.software == false && input_bytes < kWarmUpInputBytes);
}

bool huge_pages_off(const MachineInfo& machine, uint64_t input_bytes, size_t columns) {
  return machine.reports_free_pages &&
         (columns >= kLargeJobColumns || input_bytes >= kLargeJobInputBytes);
}

MapPlan plan_maps(const Settings& settings, int grid_side, float grid_texel) {
  MapPlan plan;
  plan.texel = settings.texel;
  plan.max_side = settings.max_side;
  if (settings.texel > 0.0f || settings.max_side != 0) return plan;
  plan.max_side = settings.auto_side;
  const float depth_texels = settings.fall_depth / grid_texel;
  if (!(depth_texels > kDeepTexels)) return plan;
  plan.max_side = side_for_depth(grid_side, grid_texel, settings.fall_depth);
  char line[300];
  std::snprintf(line, sizeof line,
                "maps: automatic side %d texels, so the %.3g m of snow lies %.0f texels deep (%.0f "
                "on %d; --max-side or --texel sets the resolution)",
                plan.max_side, double(settings.fall_depth), double(kAimTexels),
                double(depth_texels), grid_side);
  plan.note = line;
  return plan;
}

RunPlan plan_run(const SceneStats& stats, const MachineInfo& machine, const Settings& settings,
                 bool gl_started) {
  RunPlan plan;
  plan.maps = plan_maps(settings, stats.asked_grid_side, stats.asked_grid_texel);
  // A renderer only a context can tell is found by making the peel's
  // context up front.
  plan.gl.software = machine.software.value_or(false);
  plan.gl.started = gl_started || !machine.software.has_value();
  plan.bvh_ahead = machine.software == false;
  plan.bvh_morton = coverage_bvh_morton(stats.triangles, stats.grid_columns);
  plan.huge_pages_off = huge_pages_off(machine, stats.input_bytes, stats.grid_columns);
  plan.stabilizer_on_cpu = stabilizer_on_cpu(settings.stabilizer, StabilizerUse::Batch, plan.gl);
  plan.preview_stabilizer_on_cpu =
      stabilizer_on_cpu(settings.stabilizer, StabilizerUse::Live, plan.gl);
  plan.peel = describe_peel(settings, plan.gl);
  plan.coverage = describe_coverage(settings, plan.gl);
  return plan;
}

std::vector<std::string> describe(const RunPlan& plan) {
  return {
      plan.maps.texel <= 0.0f
          ? "plan: maps of " + std::to_string(plan.maps.max_side) + " texels on the longer side" +
                (plan.maps.note.empty() ? "" : " (the snow would lie too deep on more)")
          : "plan: maps of " + std::to_string(plan.maps.texel) + " m texels (--texel)",
      "plan: peel: " + plan.peel,
      "plan: coverage: " + plan.coverage +
          (plan.bvh_ahead ? "; its BVH built beside the peel" : ""),
      std::string("plan: stabilizer: ") + (plan.stabilizer_on_cpu ? "CPU passes" : "GPU passes") +
          " (the preview: " + (plan.preview_stabilizer_on_cpu ? "CPU passes" : "GPU passes") + ")",
      std::string("plan: renderer: ") + (plan.gl.software ? "software rasterizer" : "a GPU") +
          (plan.gl.started ? ", started" : ", started only when a pass needs it"),
      std::string("plan: heap: ") + (plan.huge_pages_off ? "huge pages off (a large job on a "
                                                           "machine that hands memory back)"
                                                         : "as set at start"),
  };
}

}  // namespace snow::plan
