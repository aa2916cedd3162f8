#pragma once
// The parts of the coverage stage (snow/coverage.h), private to
// src/snow/coverage/: what they share and the functions each offers the
// renderer.
//
//   directions.cpp  validate_settings, mean_fall_direction, fall_directions,
//                   shadow_origin_jitter (the settings' fall directions)
//   receivers.cpp   list_receivers: every layer texel with a surface
//   sky_cull.cpp    cull_receivers: those lit or shaded along every
//                   direction, settled without shadow maps or rays
//   cpu_rays.cpp    cast_rays_on_cpu (CoverageMethod::CpuRays)
//   cpu_shadow_maps.cpp  shadow_maps_on_cpu (CoverageMethod::CpuShadowMaps)
//   gpu.h, gpu.cpp  the GL side: GpuSide and count_on_gpu
//                   (CoverageMethod::ShadowMaps and GpuRays)
//   renderer.cpp    CoverageRenderer: the steps of a compute, the method
//                   chosen through the plan, and the dispatch to it
//
// Only gpu.h, gpu.cpp and renderer.cpp include GL headers; this header and
// the CPU parts include none.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include <glm/glm.hpp>

#include "snow/bvh.h"
#include "snow/maps.h"

namespace snow {
struct CoverageSettings;
class Progress;
}  // namespace snow

namespace snow::cov {

/// Shadow maps per GPU batch at most (a 32-bit direction mask per receiver).
constexpr int kMaxBatch = 32;

/// Throws InputError for settings outside their ranges (CoverageSettings'
/// fields), an unknown method, or tilt + flutter over kMaxFallAngleDeg.
void validate_settings(const CoverageSettings& settings);

// --- Receivers (receivers.cpp) -----------------------------------------------

/// A receiver as packed for the passes (shaders/coverage_common.glsl's
/// Receivers): x = i | j << 16 (its texel), y = the bits of its height
/// (float, metres), z = its normal's (x, y) and w = (z, 0) as halves.
inline glm::ivec2 receiver_texel(const glm::uvec4& r) {
  return {int(r.x & 0xffffu), int(r.x >> 16)};
}
inline float receiver_height(const glm::uvec4& r) {
  float y;
  std::memcpy(&y, &r.y, sizeof y);
  return y;
}
/// Its point: the texel's centre at its height.
inline glm::vec3 receiver_point(const MapGrid& grid, const glm::uvec4& r) {
  const glm::ivec2 t = receiver_texel(r);
  const glm::vec2 xz = grid.center(t.x, t.y);
  return {xz.x, receiver_height(r), xz.y};
}

/// The receivers of one compute: every layer texel with a surface, at the
/// surface (the snow's top where a snow depth lies on it).
struct Receivers {
  std::vector<glm::uvec4> recv;             // packed as above; layer, row, column order
  std::vector<uint32_t> recv_index;         // layer texel index of each receiver
  std::vector<float> top;                   // with a snow depth: ground + depth per layer
                                            // texel (kNoSurface where none); else empty
  std::vector<int> snowy_layers;            // layers with snow on them (snow on snow)
  std::vector<glm::ivec4> snowy_quads;      // per snowy layer: the heightfield's quads to draw,
                                            // i in [x, y), j in [z, w)
  float y_lo = kOpenSky, y_hi = -kOpenSky;  // metres, the receivers' lowest and highest
};

/// Lists the receivers of `maps` (with snow_depth, metres per layer texel,
/// the snow surface's) into `out`, which must be empty. The maps must be
/// consistent and under 2^32 layer texels. Throws std::bad_alloc when
/// memory runs out.
void list_receivers(const SnowMaps& maps, const std::vector<float>* snow_depth, Receivers& out);

// --- Sky cull (sky_cull.cpp) -------------------------------------------------

/// What the sky cull settled for a receiver.
constexpr uint8_t kKept = 0;    // neither: left for the method
constexpr uint8_t kOpen = 1;    // lit along every direction
constexpr uint8_t kShaded = 2;  // shaded along every direction (under a solid's top)

/// The largest tan(angle from the vertical) of the fall directions (unit,
/// pointing down).
double steepest_tan(const std::vector<glm::vec3>& dirs);

/// kKept, kOpen or kShaded per receiver, for fall directions at most
/// atan(tan_max) from the vertical: kOpen only where no triangle of `bvh`
/// (nor, given snow_top, the snow surface through it) can be in the way of
/// any line of fall, kShaded only where one triangle blocks every one of
/// them (shades_cone), as the reference's rays find (surfaces less than
/// reference::own_surface above a receiver are its own). On all cores.
std::vector<uint8_t> cull_receivers(const Bvh& bvh, const SnowMaps& maps,
                                    const std::vector<float>* snow_top,
                                    const std::vector<glm::uvec4>& recv,
                                    const std::vector<uint32_t>& recv_index, double tan_max);

/// Sets the coverage of the receivers culled (1 for kOpen, 0 for kShaded;
/// `coverage` per layer texel) and removes them from recv and recv_index,
/// the others keeping their order.
void drop_culled(const std::vector<uint8_t>& culled, std::vector<glm::uvec4>& recv,
                 std::vector<uint32_t>& recv_index, std::vector<float>& coverage);

// --- Shadow frames ----------------------------------------------------------

/// Where a direction's shadow map lies: (a, b, u0, v0) as in shadow.vert
/// (shadow-map metres u = x - a y - u0, v = z - b y - v0), texels of st
/// metres, `size` texels.
struct ShadowFrame {
  glm::dvec4 params;
  double st;
  glm::ivec2 size;
  double inv_st = 1.0 / st;
  glm::dvec2 texel_of(const glm::vec3& q) const {  // texel coordinates (centres at i + 0.5)
    return glm::dvec2((double(q.x) - params.z - double(q.y) * params.x) * inv_st,
                      (double(q.z) - params.w - double(q.y) * params.y) * inv_st);
  }
};

// --- CPU rays (cpu_rays.cpp) -------------------------------------------------

/// reference::sees_sky from p along up = -d (up.y > 0; t_min as there), for
/// rays cast in turn from neighbouring receivers in the same direction: the
/// scene triangle that blocked the last of them (`last`, kept up to date) is
/// tried first, unless it is `tried` already. Where Bvh::reaches finds it
/// hit, the walk would find the ray blocked too, so the answer is the
/// reference's. `snow_bvh`: the snow surface's triangles, or null.
bool sees_sky_after(const Bvh& bvh, const Bvh* snow_bvh, const glm::vec3& p, const glm::vec3& up,
                    float t_min, uint32_t& last, uint32_t tried = Bvh::kNone);

/// CoverageMethod::CpuRays: the reference's casts (reference::compute_coverage)
/// for the receivers given, on all cores; with a snow depth the snow
/// surface's triangles get a BVH of their own. Sets coverage[recv_index[r]]
/// of each receiver r. Progress is reported between rounds (Progress is not
/// thread-safe), in directions as by the other methods.
void cast_rays_on_cpu(const Bvh& bvh, const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
                      const std::vector<float>* snow_depth, const std::vector<glm::uvec4>& recv,
                      const std::vector<uint32_t>& recv_index, std::vector<float>& coverage,
                      Progress& progress);

// --- CPU shadow maps (cpu_shadow_maps.cpp) ------------------------------------

/// What shadow_maps_on_cpu counted, summed over the directions.
struct CpuShadowMapCounts {
  uint64_t uncertain = 0;  // pairs cast exactly
  uint64_t settled = 0;    // pairs settled by runs of receivers at once
  uint64_t left_out = 0;   // triangles not drawn, far from what receivers read
};

/// CoverageMethod::CpuShadowMaps on all cores: each worker draws a
/// direction's map (frames[k]: the scene, and with a snow depth the snow
/// surface's triangles), classifies every receiver on it (with run_bounds,
/// runs of receivers at once where their texels bound them, and only the
/// triangles near texels that receivers read drawn) and casts the uncertain
/// pairs exactly (reference::sees_sky, as CPU rays). As many workers as
/// maps fit in `memory_bytes` (plan::kCpuShadowBytes). Sets
/// coverage[recv_index[r]] of each receiver r; the same coverage with
/// run_bounds on or off. Throws InputError when memory runs out.
CpuShadowMapCounts shadow_maps_on_cpu(
    const Bvh& bvh, const SnowMaps& maps, const std::vector<glm::vec3>& dirs,
    const std::vector<ShadowFrame>& frames, float bias, const std::vector<float>* snow_depth,
    const std::vector<glm::uvec4>& recv, const std::vector<uint32_t>& recv_index, bool run_bounds,
    double memory_bytes, std::vector<float>& coverage, Progress& progress);

/// About how many triangles a CPU shadow map draws once those far from what
/// the receivers read are left out, for choose_coverage_method: seen from
/// straight above, those in leaves whose box comes within `reach` metres
/// (the lines of fall's sideways travel over the scene's heights) of a
/// column holding a receiver that `culled` keeps (kKept), on a grid of
/// 16-texel tiles.
size_t triangles_near_receivers(const Bvh& bvh, const MapGrid& grid,
                                const std::vector<glm::uvec4>& recv,
                                const std::vector<uint8_t>& culled, double reach);

}  // namespace snow::cov
