#include "plan/rules.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"

namespace snow::plan {

PeelChoice choose_peel(const std::string& device, const GlFacts& gl, size_t layer_texels) {
  PeelChoice choice;
  if (device != "auto") {
    choice.always_cpu = device == "cpu";
  } else if (gl.software) {
    choice.cpu_box_texels = std::max(kCpuPeelHits, kCpuPeelHitsPerLayerTexel * layer_texels);
  } else if (!gl.started) {
    choice.cpu_box_texels = kCpuPeelHitsBeforeGl;
  }
  return choice;
}

double cpu_ray_cost(double triangles) {
  return kCpuRayCost * std::clamp(std::log2(std::max(triangles, 2.0)) / 16.0, 0.0625, 1.0);
}

CoverageMethod choose_coverage_method(const std::string& method, int directions,
                                      const CoverageWork& w) {
  if (method == "shadow-maps") return CoverageMethod::ShadowMaps;
  if (method == "rays") return CoverageMethod::GpuRays;
  if (method == "cpu-rays") return CoverageMethod::CpuRays;
  if (method == "cpu-shadow-maps") return CoverageMethod::CpuShadowMaps;
  // Per direction: shadow maps draw the triangles, clear and sample the
  // maps' texels and count the receivers; rays cost per receiver (a snow
  // surface adds a walk of each snowy layer's heightfield to a GPU ray).
  // The CPU methods are not chosen with a snow surface: they would build a
  // BVH of its triangles, two per snowy texel.
  const double receivers = double(w.receivers);
  const double texels = w.shadow_texels * kShadowTexelCost;
  const double shadow =
      w.triangles + texels + receivers * kGpuCountCost + (w.software ? kGpuPassCost : 0.0);
  const double gpu_rays = receivers * kGpuRayCost * (w.snow ? 2.0 : 1.0);
  const double gpu = std::min(shadow, gpu_rays);
  if ((w.software || w.gl_cold) && !w.snow) {
    // CPU shadow maps take a map per core; beyond kCpuShadowBytes fewer cores.
    const unsigned threads = w.threads > 0 ? w.threads : default_threads();
    const bool maps_fit = 4.0 * w.shadow_texels * threads <= kCpuShadowBytes;
    const double cpu_shadow = (w.drawn >= 0.0 ? w.drawn : w.triangles) * kCpuTriangleCost + texels +
                              receivers * kCpuCountCost;
    const double cpu_rays = receivers * cpu_ray_cost(w.triangles);
    const bool rays = cpu_rays <= cpu_shadow || !maps_fit;
    if (w.software) {
      if (rays && cpu_rays < gpu) return CoverageMethod::CpuRays;
      if (maps_fit && cpu_shadow < gpu) return CoverageMethod::CpuShadowMaps;
    } else {
      // The costs were fitted on 2 cores; a GPU's passes cost next to
      // nothing beside its driver's start.
      const double seconds =
          (rays ? cpu_rays : cpu_shadow) * directions * kCostUnitSeconds * 2.0 / threads;
      if (seconds <= kCpuSecondsBeforeGl) {
        return rays ? CoverageMethod::CpuRays : CoverageMethod::CpuShadowMaps;
      }
    }
  }
  return gpu_rays < shadow ? CoverageMethod::GpuRays : CoverageMethod::ShadowMaps;
}

int choose_shadow_batch(int requested, int directions, double shadow_texels, int max_batch) {
  const double fit = kAutoShadowBatchBytes / (4.0 * std::max(shadow_texels, 1.0));  // DEPTH32F
  const int batch = requested > 0
                        ? requested
                        : int(std::clamp(fit, double(kMinAutoShadowBatch), double(max_batch)));
  return std::max(1, std::min(batch, directions));
}

bool coverage_bvh_morton(size_t triangles, size_t receivers) {
  return triangles > kMortonTrianglesPerReceiver * receivers;
}

bool weld_shadow_vertices(const GlFacts& gl) { return gl.software; }

bool stabilizer_on_cpu(const std::string& device, StabilizerUse use, const GlFacts& gl) {
  if (device != "auto") return device == "cpu";
  return use == StabilizerUse::Batch || gl.software;
}

int preview_grid_side(const GlFacts& gl) {
  return gl.software ? kPreviewGridSideSoftware : kPreviewGridSide;
}

int preview_add_every(const GlFacts& gl) {
  return gl.software ? kPreviewAddEverySoftware : kPreviewAddEvery;
}

float preview_quad_pixels(const GlFacts& gl) {
  return gl.software ? kPreviewQuadPixelsSoftware : kPreviewQuadPixels;
}

double drift_transport(double speed, double threshold) {
  if (!(threshold > 0.0) || !(speed > threshold)) return 0.0;
  const double r = speed / threshold;
  return kDriftTransportScale * r * (r * r - 1.0);
}

}  // namespace snow::plan
