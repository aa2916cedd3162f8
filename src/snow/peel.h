#pragma once
// Stage 1: snow amount maps by depth peeling from straight above (Tokoi
// 2006, section 3; height spans after Onoue and Nishita 2004). The result is
// the SnowMaps contract of snow/maps.h. The backends: the GPU's passes
// (snow/peel/gpu.cpp) and a vertical ray per texel on the CPU
// (snow/reference/peel_ref.h); snow/peel/internal.h lists the stage's files.
#include <cstdint>
#include <string>

#include "plan/plan.h"
#include "scene/scene.h"
#include "snow/coverage.h"
#include "snow/maps.h"

namespace snow {

struct PeelSettings {
  float texel = 0.0f;    // metres, texel edge; 0 = automatic: the longer horizontal side of the
                         // scene plus margins divided by max_side
  int max_side = 1024;   // texels, longest map side when texel is automatic (1..65536)
  int layers = 8;        // L, surfaces kept per texel from the top down (1..64)
  float margin = -1.0f;  // metres, border around the scene's horizontal bounds; < 0 = automatic:
                         // 2 % of the longer horizontal side, at least 2 texels
  float merge_distance = 1e-3f;  // metres: a surface less than this below the one above it is
                                 // the same layer (coplanar duplicates, decals); >= 0
  float bridge_width = 0.05f;    // metres: snow bridges gaps up to this wide (bench slats,
                                 // grates; snow/bridge.h); 0 = none
  uint64_t memory_budget = 4ull << 30;  // bytes; peel_layers throws InputError before
                                        // allocating when estimate_memory exceeds it
  // "gpu" (depth passes), "cpu" (a vertical ray per texel:
  // snow::reference::peel_layers) or "auto" (plan::choose_peel).
  std::string device = "auto";
};

/// Whether peel_layers peels on the CPU: plan::choose_peel for
/// settings.device and `gl` (what GL renders on and whether it has started,
/// as the caller's plan knows it), the texel centres in the triangles' xz
/// boxes counted against its bound.
bool peels_on_cpu(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                  const plan::GlFacts& gl);

/// The map grid over the scene's horizontal (x, z) bounds plus the margin,
/// centred on them. With settings.texel > 0 the texel is that size; with 0
/// it is chosen so that the longer side has max_side texels. Throws
/// InputError for an empty or non-finite scene, bad settings (negative texel
/// or margin, max_side < 1, layers outside 1..64) or an absurd grid (a side
/// over 2^30 texels). Large but representable grids pass: the memory check is
/// check_memory_budget's job.
MapGrid make_grid(const Bounds& scene_bounds, const PeelSettings& settings);

/// The planner's facts about `scene` (plan::SceneStats): its triangles, the
/// grid at the side `settings` asks for (wanted.auto_side where texel and
/// max_side are 0) and the texel columns of the grid at the side
/// plan::plan_maps picks for `wanted`. Throws what make_grid throws.
plan::SceneStats scene_stats(const Scene& scene, const PeelSettings& settings,
                             const plan::Settings& wanted, uint64_t input_bytes);

/// Bytes that the maps pipeline needs for `grid` with `layers` layers, CPU
/// and GPU memory together (on a software rasterizer both are host memory):
/// the SnowMaps (24 B per layer texel) and coverage (4 B); the peel's GPU
/// targets (2 ping-pong sets of 20 B + depth 4 B + readback 16 B per texel);
/// coverage's receivers, counts, snow surface and exact-pass queue (36 B per
/// layer texel); one batch of
/// shadow maps (4 B per shadow texel; a shadow map is the grid grown by
/// scene_height * tan(tilt + flutter) on each side); the scene on the GPU
/// and its BVH (about 140 B per triangle); later stages (stabilizer
/// ping-pong, snow depth, polygonize scratch: 48 B per layer texel). An
/// upper bound (every layer counted full), saturating at UINT64_MAX.
uint64_t estimate_memory(const MapGrid& grid, int layers, const CoverageSettings& coverage,
                         float scene_height = 0.0f, uint64_t triangles = 0);

/// Throws InputError when estimate_memory(...) > budget: one line naming the
/// maps' size, what they need and the budget, a coarser --texel that fits,
/// and --memory-budget to raise it. Allocates nothing.
void check_memory_budget(const MapGrid& grid, int layers, const CoverageSettings& coverage,
                         uint64_t budget, float scene_height = 0.0f, uint64_t triangles = 0);

/// Depth peeling, by the GPU's passes or, where settings.device picks the
/// CPU, snow::reference::peel_layers (the same maps up to ties on triangle
/// edges, which the GPU resolves by its fill rule). Needs a current GL
/// context (snow::gl::create_context), or a gl::OnDemandContext that the
/// GPU's passes make, unless the device is "cpu".
/// Makes the grid with make_grid, checks the memory budget (with default
/// CoverageSettings) before allocating anything, then renders L+1 passes of
/// the scene from straight above: pass l keeps, per texel, the highest
/// surface lying more than merge_distance below layer l-1 (every triangle
/// counts, whatever its winding). Fills ground, ceiling (ceiling[l] =
/// ground[l-1], +inf on layer 0), the geometric normal as wound (unit,
/// possibly facing down) and the object index; counts the columns holding
/// more than L surfaces in overflow_columns and warns once if any. Reports
/// progress. Then lays bridges across gaps up to settings.bridge_width wide
/// (bridge_gaps, snow/bridge.h). Returns the layers down to the lowest one holding a surface
/// (1..L; one empty layer for an empty scene), so later stages neither store
/// nor compute layers no column reaches; the layers a scene does not fill
/// take no memory. Throws InputError (grid, budget, a side over GL_MAX_TEXTURE_SIZE)
/// or GLError (GL_OUT_OF_MEMORY, shaders).
/// `gl`: what GL renders on and whether it has started, as the caller's
/// plan knows it (peels_on_cpu).
SnowMaps peel_layers(const Scene& scene, const PeelSettings& settings, const plan::GlFacts& gl);

/// Same on a given grid (settings.texel, max_side and margin are ignored).
SnowMaps peel_layers(const Scene& scene, const MapGrid& grid, const PeelSettings& settings,
                     const plan::GlFacts& gl);

/// Benchmark helper: renders the whole scene `passes` times from straight
/// above into a depth-only target of width x height texels (no peeling test,
/// no readback) and returns the wall seconds from the first draw to glFinish
/// (uploads excluded). This is the raw rasterization work a peel pass
/// (indexed = false: the triangle soup, as peel_layers draws it) or a shadow
/// pass (indexed = true: welded vertices, as CoverageRenderer draws them) of
/// that size costs.
double time_depth_passes(const Scene& scene, int width, int height, int passes,
                         bool indexed = false);

}  // namespace snow
