#pragma once
// The planner's rules: every automatic choice of the pipeline, with its
// constants named and their units stated. Choices that depend only on the
// scene and the machine are made up front by plan_run (plan/plan.h); those
// that depend on what a stage finds (the coverage's receivers left after
// its sky cull, the triangles' boxes over the peel's grid) are made by the
// functions here, which the stages call with those figures. The constants
// were fitted on the scenes and machines named in tools/RESULTS.md
// ("Constants of the automatic choices"); refit them there, not in the stages.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

namespace snow::plan {

/// What GL renders on, and whether the process has started it, as known
/// when a stage begins.
struct GlFacts {
  bool software = false;  // a software rasterizer (Mesa's llvmpipe, softpipe, swrast): its
                          // "GPU" passes run on the CPU cores
  bool started = false;   // a GL context has been made in this process: the driver is loaded
                          // and further contexts come cheaply
};

// --- Scene: what the run leaves out ---

/// An object that holds the rest of the scene horizontally, rises above it,
/// and covers at least this share of its footprint from above is a sky
/// enclosure (a dome, a sky box; snow::find_sky_enclosures): the run leaves
/// it out unless told to keep it. Below 1 so that a dome's seams and a box
/// whose top has a hole still count; high enough that a roof over part of
/// a scene does not.
constexpr double kSkyEnclosureCover = 0.9;  // share of the footprint, 0..1

/// A scene whose median object is more than this many units across is
/// probably not in metres (glTF's unit): centimetres up to
/// kMillimetreObjectUnits, millimetres beyond; the run suggests
/// --unit-scale. Real objects (benches, cars, houses) are 0.3 to 30 m.
constexpr float kCentimetreObjectUnits = 60.0f;    // units
constexpr float kMillimetreObjectUnits = 3000.0f;  // units
/// A scene with this many times more area facing +-Z than facing +-Y
/// (grounds, floors and roofs face up) is probably +Z up; the run
/// suggests --up z.
constexpr double kZUpAreaRatio = 3.0;

/// The frame the scene's figures suggest (snow::frame_figures): metres per
/// unit (1 where they look like metres) and whether +Z looks up.
struct FrameAdvice {
  float unit_scale = 1.0f;
  bool z_up = false;
};
/// The size rule needs this many objects (a lone terrain is any size).
constexpr size_t kFrameMinObjects = 3;
inline FrameAdvice advise_frame(size_t objects, float median_object_units, double area_facing_y,
                                double area_facing_z) {
  FrameAdvice a;
  if (objects < kFrameMinObjects) {
  } else if (median_object_units > kMillimetreObjectUnits) {
    a.unit_scale = 0.001f;
  } else if (median_object_units > kCentimetreObjectUnits) {
    a.unit_scale = 0.01f;
  }
  a.z_up = area_facing_z > kZUpAreaRatio * area_facing_y;
  return a;
}

/// Small objects on a big flat ground (snow::find_flat_ground): where the
/// ground's longer side is at least kDetailGroundRatio times that of the
/// detail plus its margins, the maps cover the detail and a margin around
/// it alone, at the detail's resolution, and the open ground beyond gets an
/// even cover of the fallen depth (as Neukom et al. 2018 nest a fine grid
/// in a coarse one). The margin holds the detail's shadows under the
/// steepest fall (twice its height times the tangent of the fall's tilt
/// plus flutter), the piles of what slides off it, and at least
/// kDetailMarginShare of its size or kDetailMarginMin.
constexpr double kDetailGroundRatio = 4.0;   // ground side over detail side (with margins)
constexpr double kDetailMarginShare = 0.25;  // of the detail's longer side
constexpr double kDetailMarginMin = 2.0;     // metres
/// The margin (m) around the detail, or a negative number where the maps
/// should cover the whole ground. Sides and height in metres, the tilt in
/// degrees (fall tilt plus flutter, below 90).
inline double detail_margin(double ground_side, double detail_side, double detail_height,
                            double tilt_deg) {
  const double tilt = std::min(tilt_deg, 80.0) * 3.14159265358979 / 180.0;
  const double margin = std::max(
      {kDetailMarginMin, kDetailMarginShare * detail_side, 2.0 * detail_height * std::tan(tilt)});
  return ground_side >= kDetailGroundRatio * (detail_side + 2.0 * margin) ? margin : -1.0;
}

// --- Peel: the GPU's depth passes or a vertical ray per texel on the CPU ---

/// The CPU peel keeps every hit of a texel's ray before sorting (20 bytes
/// each while it groups them). Where GL renders in software, "auto" takes
/// it where the triangles' xz boxes hold at most this many texel centres,
/// or at most kCpuPeelHitsPerLayerTexel per layer texel of the maps (80
/// bytes, less than the later stages take per layer texel). A scene of many
/// large stacked triangles keeps the GPU's passes, which hold one surface
/// per texel at a time.
constexpr size_t kCpuPeelHits = size_t(1) << 22;  // texel centres in triangles' boxes
constexpr size_t kCpuPeelHitsPerLayerTexel = 4;
/// On a GPU whose driver has not started, "auto" takes the CPU peel where
/// the boxes hold at most this many texel centres: the CPU peel of such a
/// scene is cheaper than loading the driver, and a small scene then may
/// need no GL at all.
constexpr size_t kCpuPeelHitsBeforeGl = size_t(1) << 19;  // texel centres

/// Where the peel runs: always on one device, or on the CPU where the
/// triangles' boxes hold at most `cpu_box_texels` texel centres.
struct PeelChoice {
  bool always_cpu = false;
  size_t cpu_box_texels = 0;  // 0 with always_cpu false: always the GPU
};

/// The peel's choice for `device` ("auto", "cpu" or "gpu") on maps of
/// `layer_texels` texels x layers.
PeelChoice choose_peel(const std::string& device, const GlFacts& gl, size_t layer_texels);

// --- Coverage: shadow maps or rays, on the GPU or the CPU cores ---

/// How a coverage pass tests the lines of fall (CoverageSettings::method).
enum class CoverageMethod {
  ShadowMaps,     // a depth map per direction; exact GPU ray casts only near silhouettes
  GpuRays,        // every (receiver, direction) pair cast exactly by the GPU's compute pass
  CpuRays,        // the same casts on all CPU cores (snow::Bvh::occluded)
  CpuShadowMaps,  // the shadow maps drawn, classified and cast on the CPU cores (runs of
                  // receivers settled at once; only triangles near them drawn)
};

/// What a coverage pass costs each way, in triangles drawn into one shadow
/// map (per direction). The inputs come from the pass: `triangles` drawn
/// per shadow map (the scene, plus the snow surface's), the shadow map's
/// texels, the receivers left after the sky cull, whether a snow surface
/// is drawn, whether the GL renderer is a software rasterizer, and for a
/// GPU, whether no GL context has been made in the process yet (its driver
/// still to load).
struct CoverageWork {
  double triangles = 0;
  double shadow_texels = 0;
  size_t receivers = 0;
  bool snow = false;
  bool software = false;
  bool gl_cold = false;
  unsigned threads = 0;  // CPU cores the CPU methods run on (0: default_threads())
  double drawn = -1.0;   // triangles a CPU shadow map draws, those far from the receivers
                         // left out (< 0: every triangle)
};

/// Costs of choose_coverage_method, in units of one triangle drawn into one
/// shadow map by a software rasterizer; kCostUnitSeconds is that unit on
/// the machine the costs were fitted on (tools/RESULTS.md, "Constants of
/// the automatic choices").
constexpr double kCostUnitSeconds = 80e-9;       // s, the cost unit
constexpr double kShadowTexelCost = 1.0 / 40.0;  // clearing and sampling one shadow texel
constexpr double kGpuRayCost = 16.0;             // one ray in the GPU's exact pass
constexpr double kCpuRayCost = 2.0;       // one CPU ray from 2^16 triangles up (cpu_ray_cost)
constexpr double kGpuCountCost = 0.28;    // classifying a receiver on a GPU shadow map
constexpr double kGpuPassCost = 11000.0;  // llvmpipe's fixed cost per direction
constexpr double kCpuCountCost = 0.155;   // classifying a receiver on a CPU shadow map
constexpr double kCpuTriangleCost = 0.3;  // a triangle drawn into a CPU shadow map
/// CPU shadow maps in flight at once take at most this much memory (a map each).
constexpr double kCpuShadowBytes = 256.0 * 1024 * 1024;  // bytes
/// On a GPU whose driver has not started (CoverageWork::gl_cold), "auto"
/// takes a CPU method where it is estimated to take at most this long: a
/// small scene then needs no GL at all.
constexpr double kCpuSecondsBeforeGl = 0.05;  // s

/// A CPU ray walks the BVH down its depth, log2 of the triangles:
/// kCpuRayCost from 2^16 triangles up, proportionally less below.
double cpu_ray_cost(double triangles);

/// The method `method` asks for: "shadow-maps", "cpu-shadow-maps", "rays"
/// (GpuRays), "cpu-rays", or "auto": the cheapest by the costs above for
/// K = `directions`. A shadow map draws every triangle however small the
/// map, a ray walks the BVH: so small, dense models and terrains (most
/// receivers culled) cast rays, and scenes mapped finer than their
/// triangles draw shadow maps. Where GL runs in software, both are done on
/// the CPU cores when that costs less, or on a GPU whose driver has not
/// started, when they take at most kCpuSecondsBeforeGl; never with a snow
/// surface (its triangles would need a BVH of their own), nor where a
/// shadow map per core would take more than kCpuShadowBytes. A CPU shadow
/// map draws only the triangles near the receivers left
/// (CoverageWork::drawn).
CoverageMethod choose_coverage_method(const std::string& method, int directions,
                                      const CoverageWork& work);

/// Automatic shadow maps per GPU batch: as many as fit in
/// kAutoShadowBatchBytes, at least kMinAutoShadowBatch (fewer batches save
/// per-pass costs where the maps are small).
constexpr double kAutoShadowBatchBytes = 64.0 * 1024 * 1024;  // bytes of DEPTH32F maps
constexpr int kMinAutoShadowBatch = 8;                        // shadow maps

/// Shadow maps per batch: `requested` (> 0), or automatic for 0; between 1
/// and min(`max_batch`, `directions`).
int choose_shadow_batch(int requested, int directions, double shadow_texels, int max_batch);

/// The coverage's BVH: Morton order where the triangles outnumber the
/// maps' layer texels with a surface more than kMortonTrianglesPerReceiver
/// times (its rays are few, its build is cheap), else binned SAH splits.
/// Either gives the same coverage.
constexpr size_t kMortonTrianglesPerReceiver = 16;
bool coverage_bvh_morton(size_t triangles, size_t receivers);

/// GL's shadow passes draw through an index buffer. llvmpipe runs the
/// vertex shader once per index, so in software the corners are welded
/// first; a GPU shades the three corners of each triangle faster than the
/// CPU welds them.
bool weld_shadow_vertices(const GlFacts& gl);

// --- Stabilizer ---

/// Who runs the stabilizer: the batch job (passes to convergence, depth read
/// once) or the live preview (a few passes a frame, depth drawn every frame).
enum class StabilizerUse { Batch, Live };

/// Where `device` ("auto", "cpu" or "gpu") puts the stabilizer's passes:
/// true for the CPU. "auto" takes the CPU for the batch job everywhere (its
/// passes beat the GPU's fragment passes, and skip the textures' set-up);
/// the live preview takes the CPU where the GL renderer is software, else
/// the GPU, whose depth texture is drawn without an upload per frame.
bool stabilizer_on_cpu(const std::string& device, StabilizerUse use, const GlFacts& gl);

// --- Wind transport (snow/drift.h) ---

/// Wind speed (m/s, at the reference height of 10 m) below which the wind
/// does not move lying snow, by the snow's kind (snow/cohesion.h). Li and
/// Pomeroy (1997) observed thresholds of 4 to 11 m/s for dry snow, the low
/// end for fresh, loose snow; wet snow sticks and hardly drifts.
constexpr double kDriftThresholdPowder = 3.5;  // m/s
constexpr double kDriftThresholdFresh = 4.0;   // m/s
constexpr double kDriftThresholdWet = 9.0;     // m/s
/// The storm's transport (DriftSettings::transport, metres of fallen snow
/// carried per metre of width over the fallen depth) grows with the wind as
/// the saltation flux does, u (u^2 - u_t^2) (Pomeroy and Gray 1990):
/// kDriftTransportScale * r (r^2 - 1) for r = speed / threshold, 0 at or
/// below the threshold.
constexpr double kDriftTransportScale = 3.5;  // m
double drift_transport(double speed, double threshold);
/// The flux relaxes to the capacity over this distance (erosion and
/// deposition outside shelters).
constexpr double kDriftSaturationLength = 8.0;  // m
/// Turbulent spreading of the carried snow across the wind: its lateral
/// variance grows by this many m^2 per metre travelled.
constexpr double kDriftMixingLength = 0.5;  // m
/// An obstacle of height h shelters h / kDriftShelterSlope downwind (and in
/// front of it): EN 1991-1-3's drift length at a step, ls = 2h.
constexpr double kDriftShelterSlope = 0.5;  // tan of the horizon angle
/// The height of the drifting layer: an obstacle of height h catches
/// h^2 / (h^2 + kDriftLayerHeight^2) of the flux in its shelter (a step far
/// taller than the layer nearly all, a ripple of the snow next to nothing);
/// one narrower across the wind than twice it (a post, a rail) none.
constexpr double kDriftLayerHeight = 0.3;  // m
/// Share of the flux reaching a windward face that settles in front of it;
/// the rest goes over. ASCE 7 takes windward drifts as 3/4 the height of
/// leeward ones from the same fetch, so about half their volume.
constexpr double kDriftWindwardCapture = 0.5;  // share, 0..1
/// The wind's capacity beside an obstacle, where the flow goes round it (the
/// scour at a cube's windward corners and sides, Tominaga et al. 2011),
/// grows by up to this share.
constexpr double kDriftSpeedupGain = 1.0;  // share
/// The flow speeds up beside an obstacle, and slows down past it, over this
/// distance along the wind.
constexpr double kDriftSpeedupLength = 2.0;  // m
/// The wind takes at most this share of the snow lying (and of the depth
/// that fell, so a snowfall in steps is scoured as one): what it scours
/// packs into a crust that resists. Set so that the drift behind a roof
/// step, fed by the higher roof's scour, follows EN 1991-1-3
/// (tests/test_wind.cpp).
constexpr double kDriftMaxScour = 0.7;  // share, 0..1
/// What settles in a shelter spreads across the wind so that the drift's
/// flanks are no steeper than this: the angle of repose (45 degrees), so
/// they stand as the stabilizer finds them.
constexpr double kDriftFlankSlope = 1.0;  // tan of the angle
/// No drift grows deeper than this many times the fallen depth: EN
/// 1991-1-3 caps the drift coefficient mu_w at a step at 4 (section 5.3.6).
constexpr double kDriftMaxCoefficient = 4.0;  // times the fallen depth
/// The storm in this many parts, each on the surface the last left.
constexpr int kDriftSubsteps = 3;
/// Cornices: at lee edges the snow's lip reaches out over the air by up to
/// this share of the storm's transport (PolygonizeSettings::cornice), as
/// far as the snow's thickness there allows (poly::kCorniceShare).
constexpr double kCorniceShareOfTransport = 0.05;  // of DriftSettings::transport
constexpr double kMaxCornice = 1.0;                // m
/// The cornice's reach (m) for a storm of `transport` metres.
inline double cornice_length(double transport) {
  return std::min(kMaxCornice, kCorniceShareOfTransport * std::max(transport, 0.0));
}

// --- Weather over time (snow/accumulate.h, accumulate_weather) ---

/// A weather step's snowfall reuses the last coverage while its wind
/// differs from that coverage's by at most this (m/s, vector difference):
/// a coverage is most of a step's time, and hourly winds wander.
constexpr double kWeatherWindChange = 0.5;  // m/s
/// The sun's shadow is reused while the sun moved by at most this.
constexpr double kWeatherSunChange = 1.0;  // degrees

// --- Tiles (snowmodel snow --tiles, snowmodel merge) ---

/// Each tile's maps reach this far past the tile on every side (the halo),
/// so that the snow on the tile itself is the untiled run's. Without wind,
/// snow that ends on a tile comes from a roof or slope reaching over its
/// border and slides at most to the foot of it, where it piles: within
/// kTileSlideHalo. A wind that moves snow carries it further: drifts reach
/// about twice the height of what shelters them downwind (EN 1991-1-3 at a
/// step), and the flux takes its saturation length (kDriftSaturationLength)
/// to build up. The shadows need no halo: the coverage draws every caster
/// of the scene over the maps.
constexpr double kTileSlideHalo = 5.0;    // m
constexpr double kTileHaloHeights = 2.0;  // times the scene's height, with wind
/// The halo (m) for a scene `height` metres from its lowest to its highest
/// point, with (`wind`) or without a wind that moves snow.
inline double tile_halo(double height, bool wind) {
  return kTileSlideHalo +
         (wind ? kTileHaloHeights * std::max(height, 0.0) + kDriftSaturationLength : 0.0);
}

// --- Tracks (snow/tracks.h) ---

/// A moving contact is pressed at poses no point of it moves more than this
/// many texels between, so that its track has no gaps.
constexpr double kTrackPoseSpacingTexels = 0.5;  // texels
/// At most this many poses per contact (its triangles are drawn at each).
constexpr size_t kMaxTrackPoses = 200000;  // count
/// At most this much work per contact: its poses times its triangles and
/// segments plus the texels under its bounds (minutes of one core).
constexpr double kMaxTrackWork = 2e9;  // triangle or texel visits

// --- Live preview ---

/// The live preview's automatic --snow-stride draws its snow grid with at
/// most this many vertices per map side at its finest level of detail,
/// fewer where the renderer is software (the grid's triangles are a large
/// share of its frame).
constexpr int kPreviewGridSide = 768;          // vertices
constexpr int kPreviewGridSideSoftware = 256;  // vertices
int preview_grid_side(const GlFacts& gl);
/// The snow grid's level of detail: each chunk is drawn at the coarsest
/// level whose quads span at most this on screen, coarser where the renderer
/// is software.
constexpr float kPreviewQuadPixels = 3.0f;          // pixels
constexpr float kPreviewQuadPixelsSoftware = 8.0f;  // pixels
float preview_quad_pixels(const GlFacts& gl);
/// The live preview adds its snow every this many frames (each addition
/// that many frames' worth), more where the stabilizer's passes run on the
/// CPU beside a software renderer: the routing after each addition is most
/// of a frame's simulation there.
constexpr int kPreviewAddEvery = 1;          // frames
constexpr int kPreviewAddEverySoftware = 4;  // frames
int preview_add_every(const GlFacts& gl);

}  // namespace snow::plan
