#pragma once
// Stage 2: snow coverage from jittered multi-direction shadow maps (Tokoi
// 2006, section 4; flake flutter after Fearing 2000, section 4.1).
//
// Snow falls along directions d (unit vectors pointing down, along the
// flakes' travel). A flake's velocity is the wind plus its fall speed:
// v = (wind.x, -fall_speed, wind.y), so the mean direction is tilted
// downwind by tilt = atan(|wind| / fall_speed) from the vertical, at most
// kMaxFallAngleDeg - flutter (flakes that would travel flatter are drawn
// at that tilt: what a strong wind blows along the surface is transport's
// part, not the fall's); flutter
// spreads the directions uniformly (in solid angle) over a cone of half-angle
// flutter_deg around it. Coverage p of a surface point = the share of the K
// directions from which the point sees the sky (nothing above it along -d).
//
// Receivers that nothing can shade from any of the directions (a
// conservative max-height pyramid of the scene shows every point of geometry
// below the steepest line of fall) are lit without GPU work. GPU method for
// the others: one orthographic depth map per direction (a shear along d onto
// the horizontal plane, so shadow texels line up with the snow map's; texel
// matched to it; origin jittered by a sub-texel offset), rendered in batches
// into a 2D array texture. A compute pass per batch classifies every
// (surface texel, direction) pair from the four shadow texels around the
// point, against the point's own plane extended to each of them (a
// receiver-plane, hence slope-scaled, depth bias): all below -> lit, all
// above -> blocked, mixed (a silhouette or the foot of a wall passes within
// a texel) -> queued. A second pass casts the queued pairs' rays exactly
// through a BVH of the scene (and the snow heightfield). No CPU readback
// until the end. Results match the ray-cast reference up to occluders or
// gaps thinner than a shadow texel.
// Where the receivers left are few against the scene's triangles (see
// choose_coverage_method), no shadow maps are drawn: every pair is cast
// exactly, by the exact pass or on the CPU, and the result is the
// reference's. Where GL runs in software, the shadow-map method may run on
// the CPU cores instead: each core draws a direction's map (the highest
// surface at each texel centre), classifies every receiver on it as the
// compute pass does and casts the uncertain pairs; no GL is used.
// The parts (one file per method, the sky cull, the receivers) are in
// src/snow/coverage/; coverage/internal.h lists them.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "plan/machine.h"
#include "plan/rules.h"
#include "scene/scene.h"
#include "snow/bvh.h"
#include "snow/maps.h"

namespace snow {

struct CoverageSettings {
  int directions = 64;          // K, shadow maps (1..4096)
  float flutter_deg = 15.0f;    // degrees, half-angle of the cone of fall directions (0..60)
  glm::vec2 wind{0.0f};         // m/s, horizontal wind along world x and z
  float fall_speed = 1.0f;      // m/s, flakes' still-air fall speed (dry snow about 1, wet 1.5..2)
  uint64_t seed = 1;            // seed of the direction and shadow-origin jitter; same seed, same
                                // result bit for bit
  int batch = 0;                // shadow maps per GPU batch (1..32; 0 = automatic: as many as
                                // fit in 64 MiB, 8 at least); memory: batch * 4 B per shadow
                                // texel
  float bias = -1.0f;           // metres, receiver-plane depth bias: a shadow-map surface less
                                // than this above the receiver's own plane (extended to that
                                // shadow texel, so the bias follows the slope) is the receiver
                                // itself; < 0 = automatic: 0.25 texel + 1e-5 of the height range
  std::string method = "auto";  // "shadow-maps", "rays" (every pair cast exactly on the GPU, no
                                // shadow maps), "cpu-rays" (the same on the CPU) or "auto": the
                                // cheapest (choose_coverage_method)
};

using plan::CoverageMethod;
using plan::CoverageWork;

/// The method settings.method asks for, or for "auto" the cheapest for
/// `work` (plan::choose_coverage_method, where the costs live).
inline CoverageMethod choose_coverage_method(const CoverageSettings& settings,
                                             const CoverageWork& work) {
  return plan::choose_coverage_method(settings.method, settings.directions, work);
}

/// Shadow maps per batch for maps of `shadow_texels` texels: settings.batch,
/// or automatic where it is 0; at most settings.directions.
int shadow_batch(const CoverageSettings& settings, double shadow_texels);

/// Largest tilt + flutter (degrees): directions closer than 15 degrees to the
/// horizon would need shadow maps many times the scene's size, so the mean
/// direction's tilt is capped at this minus the flutter.
constexpr float kMaxFallAngleDeg = 75.0f;
/// Strongest wind accepted (m/s, the length of settings.wind): a storm's.
constexpr float kMaxWind = 25.0f;

/// Mean fall direction (unit, pointing down) for the settings' wind and fall
/// speed, its tilt capped at kMaxFallAngleDeg - flutter_deg. Throws
/// InputError for fall_speed <= 0, a non-finite wind or one over kMaxWind.
glm::vec3 mean_fall_direction(const CoverageSettings& settings);

/// K unit vectors pointing down along the flakes' travel, in a cone of
/// half-angle flutter_deg around mean_fall_direction. Stratified jittered
/// sampling, uniform in solid angle: direction k has cos(angle) in stratum k
/// of [cos(flutter), 1] (jittered within it) and azimuth 2*pi*frac(k * golden
/// ratio + rotation), with a random rotation per seed. Uses its own RNG
/// (splitmix64), so the same settings give bit-identical directions.
/// Throws InputError for directions outside 1..4096, flutter outside 0..60,
/// bad wind or fall speed.
std::vector<glm::vec3> fall_directions(const CoverageSettings& settings);

/// Sub-texel jitter of each shadow map's origin, in [0, 1)^2 shadow texels,
/// one per direction; deterministic in the seed (a stream separate from the
/// directions').
std::vector<glm::vec2> shadow_origin_jitter(const CoverageSettings& settings);

/// The BVH a CoverageRenderer builds over `triangles` triangles for maps of
/// `receivers` layer texels with a surface: Morton order where the
/// triangles far outnumber them (more than 16 per texel), whose rays are
/// few, else SAH splits. Either gives the same coverage.
Bvh::Build coverage_bvh_build(size_t triangles, size_t receivers);

/// A CoverageRenderer's BVH built ahead, e.g. on another thread while the
/// maps are peeled (it needs the scene alone); `seconds` is its build time.
struct CoverageBvh {
  Bvh bvh;
  Bvh::Build build = Bvh::Build::Sah;
  double seconds = 0.0;
};
/// Builds it. Throws InputError for a scene with more triangles than one
/// draw call takes, std::bad_alloc when memory runs out.
CoverageBvh build_coverage_bvh(const Scene& scene, Bvh::Build build);

/// Shadow-map renderer kept between calls (the live preview recomputes
/// coverage every few frames while snow accumulates): owns the uploaded
/// scene, the shadow-map array, the programs and the receiver buffers. Once
/// a compute has used GL (made through gl::require_context where a
/// gl::OnDemandContext is installed), that context must be current in every
/// later call, including destruction; the CPU methods use none.
class CoverageRenderer {
 public:
  /// Builds the scene's BVH (CPU, O(n log n)). Given the maps that compute()
  /// will be given, its build suits their size: a Morton-order BVH where the
  /// triangles far outnumber the maps' layer texels, whose rays are few (the
  /// coverage is the same either way). The first compute() that needs GL
  /// (shadow maps, or rays on the GPU) makes the programs and uploads the
  /// triangles in leaf order (the vertex buffer of the one draw call per
  /// shadow map, and the exact pass's storage buffer) and nodes; compute()
  /// throws GLError when GL fails (GL_OUT_OF_MEMORY included). `gl`: what
  /// GL renders on and whether it has started, as the caller's plan knows
  /// it (the method choice and the shadow passes depend on it; set_gl
  /// updates it).
  CoverageRenderer(const Scene& scene, const plan::GlFacts& gl, const SnowMaps* maps = nullptr);
  /// The same with the BVH built ahead (build_coverage_bvh over `scene`).
  CoverageRenderer(const Scene& scene, CoverageBvh bvh, const plan::GlFacts& gl);
  /// The one or the other: with `bvh` where it is given (taken from), else
  /// building its own for `maps`.
  static std::unique_ptr<CoverageRenderer> make(const Scene& scene, const SnowMaps& maps,
                                                const plan::GlFacts& gl, CoverageBvh* bvh);
  ~CoverageRenderer();
  CoverageRenderer(const CoverageRenderer&) = delete;
  CoverageRenderer& operator=(const CoverageRenderer&) = delete;

  /// Coverage per layer texel in [0,1] (the maps' layout, size
  /// maps.layers * maps.grid.texels()); 0 where there is no surface; the
  /// point of a texel is its centre at the surface height. K directions from
  /// fall_directions(settings), shadow origins jittered by
  /// shadow_origin_jitter(settings); the method is the one in this file's
  /// head comment. Shadow texels are the snow map's, coarser only where a
  /// map would exceed GL_MAX_TEXTURE_SIZE (16384 at most). One readback at
  /// the end; progress is reported.
  /// With snow_depth (the maps' layout, metres, >= 0) the snow surface
  /// ground + depth (a heightfield per layer through the texel centres, cut
  /// where neighbours differ by more than 6 texels or lack a surface) is also
  /// drawn into the shadow maps, and points are evaluated at ground + depth.
  /// Throws InputError for bad settings, a snow_depth of the wrong size or
  /// host memory running out, GLError for GL trouble (GL_OUT_OF_MEMORY
  /// included).
  std::vector<float> compute(const SnowMaps& maps, const CoverageSettings& settings,
                             const std::vector<float>* snow_depth = nullptr);

  /// Same with explicit fall directions (unit, pointing down, at least 11.5
  /// degrees below the horizon) and shadow-origin offsets (in [0,1)^2
  /// shadow texels, one per direction); settings.directions, flutter, wind,
  /// fall_speed and seed are then unused. For tests and experiments.
  std::vector<float> compute(const SnowMaps& maps, const std::vector<glm::vec3>& directions,
                             const std::vector<glm::vec2>& jitter, const CoverageSettings& settings,
                             const std::vector<float>* snow_depth = nullptr);

  /// Wall seconds of the last compute(), by stage. With profiling off (the
  /// default; glFinish at every stage boundary stalls the pipeline) shadow
  /// holds shadow and counting together and composite is 0.
  struct Timings {
    double setup = 0;       // receivers, buffers, uploads
    double shadow = 0;      // K shadow-map depth passes
    double composite = 0;   // counting: classification and exact ray casts (compute passes)
    double readback = 0;    // one readback of the counts
    uint64_t culled = 0;    // receivers lit or shaded along every direction (no GPU work)
    uint64_t shaded = 0;    // of those, the ones shaded (under a solid's top; shades_cone)
    uint64_t queued = 0;    // receivers sent to the exact pass, summed over batches (profiling;
                            // CPU shadow maps: the uncertain pairs cast exactly)
    uint64_t pairs = 0;     // (receiver, direction) pairs classified
    uint64_t settled = 0;   // CPU shadow maps: pairs settled by runs of receivers at once
    uint64_t left_out = 0;  // CPU shadow maps: triangles not drawn, far from what receivers
                            // read, summed over the maps
    CoverageMethod method = CoverageMethod::ShadowMaps;
  };
  const Timings& timings() const;
  void set_profiling(bool on);
  /// Updates what GL renders on and whether it has started (see the
  /// constructor).
  void set_gl(const plan::GlFacts& gl);
  /// CPU shadow maps: settle runs of neighbouring receivers at once where
  /// their texels bound them, and draw only the triangles near texels that
  /// receivers read (the default); or classify every receiver alone on
  /// whole maps, for comparisons. The same coverage either way.
  void set_run_bounds(bool on);
  /// Size (texels) of each shadow map in the last compute().
  glm::ivec2 shadow_map_size() const;
  /// How the scene's BVH was built (see the constructor).
  Bvh::Build bvh_build() const;

 private:
  std::vector<float> compute_checked(const SnowMaps& maps, const std::vector<glm::vec3>& directions,
                                     const std::vector<glm::vec2>& jitter,
                                     const CoverageSettings& settings,
                                     const std::vector<float>* snow_depth);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// One-off coverage: CoverageRenderer(scene, gl).compute(maps, settings,
/// snow_depth). Needs a current GL context, or a gl::OnDemandContext, unless
/// a CPU method runs.
std::vector<float> compute_coverage(const Scene& scene, const SnowMaps& maps,
                                    const CoverageSettings& settings, const plan::GlFacts& gl,
                                    const std::vector<float>* snow_depth = nullptr);

/// Multiplies coverage by 0 on every layer texel whose object does not
/// receive snow (receives[object] == 0), and under every bridge (its snow
/// falls on the bridge, snow/bridge.h); `receives` is indexed by scene
/// object and may be empty (everything receives).
void mask_coverage(const SnowMaps& maps, const std::vector<uint8_t>& receives,
                   std::vector<float>& coverage);

/// Cut of the snow-surface heightfield (texels of height difference within
/// one heightfield triangle), shared by the GPU pass and the reference.
constexpr float kSnowSurfaceCutTexels = 6.0f;

}  // namespace snow
