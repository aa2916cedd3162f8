#pragma once
// Stage 3: the snow stabilizer. Snow steeper than its angle of repose moves
// downhill; snow leaving an edge falls through to the highest free surface
// below in the neighbouring column (docs/ARCHITECTURE.md, "Stabilizer"; the
// angle of repose relaxation of Fearing 2000, section 5, on Tokoi's snow
// amount maps). Fresh snow is cohesive (snow/cohesion.h): per layer texel,
// snow deeper than the holding depth of its support's slope is routed off
// (the erosion starts no higher than ground + holding depth), and of the
// snow that fell there (set_depth, add_snow), up to min(holding depth,
// standing height) is held: neither the erosion nor the relaxation moves
// it. Snow that arrives by sliding, routing or pouring is loose.
//
// This header is the stage's interface; the code is in snow/stabilize/:
//   stabilize.cpp  where the passes run (stabilizes_on_cpu), stabilize()
//   common.cpp     what both backends share: settings, cells, strides,
//                  drains, volumes (CPU only)
//   gpu.cpp        the GPU backend: fragment passes (Stabilizer)
//   cpu.cpp        the CPU backend: the same passes on all cores
//                  (CpuStabilizer, snow/stabilize_cpu.h; CPU only)
//   deposit.cpp    the piles poured where routed snow comes to rest
//                  (snow/deposit.h; CPU only)
//   pour_units.cpp which terminals pour as one pile (pour_units.h)
//   spill.cpp      the drains' fill and spill (snow/deposit.h; CPU only)
//
// Two kinds of passes, on the GPU as fragment passes over the layer texture
// arrays and on the CPU in snow::CpuStabilizer with the same float math:
//  - relaxation: an outflow pass (per layer texel: for each of the 8
//    neighbour columns, the landing layer by snow::landing (column.h) at the
//    snow surface height, and the amount moved there: half the largest
//    excess over distance * tan(repose), split over the neighbours by their
//    excess, so no pair overshoots) and a gather pass
//    (depth minus what the texel sent plus what its neighbours sent to it,
//    read from the same outflow textures, so every amount leaves one texel
//    and arrives at another bit for bit). Snow that goes off the map or into
//    the void below the lowest surface is lost and counted.
//  - routing: snow that cannot stay where it lies is sent in one go down a
//    chain of receivers (pointer jumping) to the first texel where it can rest,
//    as hydrology routes water over a terrain. What a texel can keep comes from
//    erosion passes (a distance transform): the highest surface no more than
//    distance * tan(repose) above what its downhill neighbours keep, nothing
//    where a neighbour is the void; where snow lands is decided on those kept
//    heights, as if what will leave had left (else snow about to slide off a
//    slab's edge would stand as a wall behind it, and the relaxation would
//    drain it for hundreds of passes). So snow on a support steeper than the
//    repose angle leaves at once, and the edges of a table or an eave round off
//    at once. What arrives at a terminal is then poured there as a cone at the
//    repose angle (snow/deposit.h; under a ceiling it fills the gap and spreads
//    on), not left as a spike metres deep on one texel, so the relaxation only
//    finishes the piles. Routing runs at the start of each stabilize call and
//    after snow is added. At the convergence checks it runs again where the
//    snow creeps (creep_route_due): loose snow that slid trickles a texel per
//    pass over the steps of held snow and along slopes near the repose angle,
//    in passes that grow with the distance in texels; routed again on the kept
//    heights of the repose angle alone (the rule the relaxation moves loose
//    snow by), it goes down its whole path at once. Between those, a check
//    drains (drain_due): where much of what moves goes into the void, the
//    excess (over the kept heights of the repose angle) whose path ends there
//    runs down it at once, filling on its way the room each texel has under
//    its neighbours' kept heights plus the repose slope (snow::spill_excess),
//    and the rest leaves: snow creeping over a ledge of held snow to an edge
//    then leaves in one drain, where draining only what lies on a path to
//    the edge left the snow behind to creep on, drain after drain.
// Relaxation passes cycle through strides up to max_stride, ..., 2, 1
// (multi-scale, see StrideSchedule), so creeping piles spread in few passes.
// A strided pass moves only snow that a single step would move (the stride-1
// rule on the path's first steps), farther.
// On the GPU the relaxation and erosion passes draw only the active tiles
// (4 x 4 columns) whose inputs changed since the last pass of the same kind
// and stride (for strided passes: or of stride 1, if later), in the layers
// that have a surface there (settings.active_tiles); a skipped tile would
// repeat a pass that moved nothing there, so the result is bit for bit that
// of full passes. The CPU
// stabilizer skips tiles by the same rule (stabilize_cpu.h), erodes in place
// to the same kept heights in fewer rounds, and is what the batch job runs
// unless settings.device asks for the GPU (stabilizes_on_cpu).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/zeroed.h"
#include "plan/rules.h"
#include "snow/cohesion.h"
#include "snow/maps.h"

namespace snow {

struct StabilizeSettings {
  float repose_deg = 45.0f;        // degrees, angle of repose of loose snow (5..85)
  float repose_jitter_deg = 3.0f;  // degrees, +- deterministic per-texel jitter of the repose
                                   // angle, against terracing (>= 0; repose +- jitter in 1..89)
  float tolerance = 1e-4f;         // metres: converged when the largest move of a pass is below
                                   // this (>= 0; 0 runs max_iterations passes)
  float min_move = -1.0f;          // metres: a relaxation move smaller than this is not made
                                   // (0 makes every move; negative: automatic,
                                   // kAutoMinMoveShare x tolerance, see min_move_of).
                                   // Without it, float rounding keeps moving micrometres of
                                   // snow in settled piles, and their tiles stay active
  int max_iterations = 4000;       // relaxation passes at most per call (>= 0)
  int check_every = 4;             // passes between convergence checks (a small GPU reduction
                                   // and readback), which also decide on strides and drains;
                                   // >= 1. A run stops and drains up to check_every - 1
                                   // passes late
  int max_stride = 4;              // texels, largest stride of the multi-scale relaxation
                                   // passes (a power of two, 1..64; 1 = single steps only).
                                   // Not scaled with the map size: longer strides only add
                                   // passes where the snow settles fast
  bool adaptive_stride = true;     // start with single steps and lengthen the strides where
                                   // the snow creeps (StrideSchedule); false: cycle from
                                   // max_stride from the first pass
  bool route_steep = true;         // route what cannot stay (steep supports, edges) in one go
                                   // before relaxing (off: relaxation only, for comparisons)
  bool deposit_piles = true;       // lay the routed snow as a cone at the repose angle around
                                   // where it comes to rest (snow/deposit.h), a warm start
                                   // for the relaxation; off: all of it on that one texel
  bool drain_edges = true;         // with route_steep: once snow creeps off an edge into the
                                   // void, drain what will leave in one go (drain_due)
  bool route_creep = true;         // with route_steep: where the snow creeps, route the loose
                                   // snow again down its whole path (creep_route_due); off:
                                   // the relaxation carries it a texel per pass
  uint32_t seed = 1;               // seed of the repose jitter; same seed, same result
  bool active_tiles = true;        // GPU: relaxation and erosion passes compute only the
                                   // 4 x 4-column tiles that can still change (bit-identical
                                   // results; off: every texel every pass, for comparisons;
                                   // also off where GL points cannot be 4 pixels wide)
  std::string device = "auto";     // where the passes run: "gpu" (fragment passes), "cpu"
                                   // (snow::CpuStabilizer: the same passes on all cores, within
                                   // the backends' tolerance, snow/stabilize_cpu.h), or
                                   // "auto": plan::stabilizer_on_cpu (the CPU for
                                   // the batch job; for the live preview the CPU where the GL
                                   // renderer is a software rasterizer, else the GPU)
  bool count_tiles = false;        // GPU: count the active tiles (a small readback per pass)
                                   // into StabilizeResult::tile_share, for benchmarks
  Cohesion cohesion = cohesion_of(SnowKind::Fresh);  // what holds where it fell
                                                     // (snow/cohesion.h; loose_snow(): none)
  ObjectGrip grip;  // per scene object, the grip of its surface (empty: normal)
};

/// Snow without cohesion, as dry sand: nothing stands at edges, and no
/// slope sheds snow that its surface's repose angle would keep.
inline Cohesion loose_snow() {
  Cohesion c;
  c.stand_height = 0.0f;
  c.hold_depth = kMaxHoldDepth;
  return c;
}

struct StabilizeResult {
  int iterations = 0;          // relaxation passes run (outflow + gather pairs), count
  float residual = 0.0f;       // metres, largest move (snow leaving one texel) in the last
                               // checked pass, less what went into full gaps (no surface moves)
  bool converged = false;      // residual < tolerance was seen at a check after a single step
  int route_passes = 0;        // erosion passes (CPU: rounds) plus pointer-jumping passes of
                               // the routing, count
  double routed_volume = 0.0;  // m^3 moved by routing (not drains: their snow is lost_volume)
  int drains = 0;              // draining routings run (drain_due), count
  int creep_routes = 0;        // routings of creeping snow run (creep_route_due), count
  int pours = 0;               // pours of pressed snow (pressed_snow_due), count
  double lost_volume = 0.0;    // m^3 that left the scene during the call (off the map or into
                               // the void below the lowest surface)
  double volume = 0.0;         // m^3 of snow lying on the maps after the call
  double route_seconds = 0.0;  // s, wall time of the routing (both stabilizers)
  double tile_share = 0.0;     // share (0..1) of the tiles times layers the relaxation passes
                               // computed (the CPU's tiles are 4 x 4 columns, all layers):
                               // 1 with active_tiles off, 0 unless count_tiles

  /// Folds in the result of a later call on the same stabilizer, as one
  /// call running both would report: counts, times and moved volumes add up;
  /// residual, converged and volume are the later call's; tile_share is
  /// weighted by passes.
  void add(const StabilizeResult& later);
};

/// Per layer texel inputs of the passes, shared by the GPU upload and the CPU
/// stabilizer (maps' layout): x = ground (m; 0 where no surface), y = ceiling
/// (m; 3e38 for open sky), z = tan(repose angle + jitter; 0 where no
/// surface), w = flags
/// (kCellSurface | kCellSolid | kCellDown, stored as a float).
constexpr int kCellSurface = 1;  // the texel has a surface
constexpr int kCellSolid = 2;    // its gap is the inside of a solid (snow::gap_is_solid)
constexpr int kCellDown = 4;     // its surface faces down (normal.y < 0)
constexpr float kCellOpenSky = 3.0e38f;
/// Snow fills a gap up to this far (m) under its ceiling; deeper snow is
/// squeezed out sideways into the neighbouring columns' gaps.
constexpr float kCeilingClearance = 1e-4f;

/// The holding depth (m, snow/cohesion.h) of every layer texel with a
/// surface, from its slope (maps.normal) and its object's grip; 0 elsewhere.
/// Snow deeper than its texel's holding depth is routed off; of the snow
/// that fell on the texel, up to min(holding depth, cohesion.stand_height)
/// is held: neither erosion nor relaxation moves it (both stabilizers).
ZeroedArray<float> stabilize_holds(const SnowMaps& maps, const StabilizeSettings& settings);

/// Throws InputError naming the first setting out of range.
void check_stabilize_settings(const StabilizeSettings& settings);

/// The automatic min_move: this share of the tolerance. Moves that far
/// below the tolerance mostly keep settled tiles computing, in the same
/// passes, with the same volumes. Snow creeping slower than this stops
/// sooner: with drains off, a little more stays on a box's edge
/// (StabilizeReference.SnowCreepingOffAnEdgeIsDrained bounds it).
constexpr float kAutoMinMoveShare = 0.1f;
/// settings.min_move, or the automatic one where it is negative.
inline float min_move_of(const StabilizeSettings& settings) {
  return settings.min_move >= 0.0f ? settings.min_move : kAutoMinMoveShare * settings.tolerance;
}

/// The repose angle of layer texel (l, i, j) in degrees: repose_deg plus a
/// jitter in [-repose_jitter_deg, +repose_jitter_deg] hashed from (l, i, j,
/// seed). Throws InputError for settings out of range.
float texel_repose_deg(const StabilizeSettings& settings, int l, int i, int j);

/// The cells above for `maps`. Throws InputError for inconsistent maps
/// (array sizes), layers outside 1..64, a non-positive texel, or settings out
/// of range.
std::vector<glm::vec4> stabilize_cells(const SnowMaps& maps, const StabilizeSettings& settings);
/// The same cells where the maps have a surface and zeros elsewhere (no
/// flags), in memory that is never touched where whole pages of the layers
/// have no surface (core/zeroed.h); for the CPU stabilizer, which reads
/// nothing but the flags of a texel without a surface.
ZeroedArray<glm::vec4> stabilize_surface_cells(const SnowMaps& maps,
                                               const StabilizeSettings& settings);

/// The strides (texels) of the relaxation passes. A strided pass moves snow
/// `stride` columns at once along a path of single steps that neither fall
/// over an edge nor rise, against the sum of the path's repose slopes, so
/// piles spread over long distances in few passes while a state at rest for
/// single steps stays at rest. Strides help where piles creep and add passes
/// where single steps settle the snow fast. So the passes start with single
/// steps, and a convergence check after a single step at which the largest
/// move fell by less than half per check_every passes since the previous
/// such check doubles the largest stride, up to max_stride; passes cycle
/// through that stride, its half, ..., 1. Snow set or added starts over with
/// single steps. With settings.adaptive_stride off, the passes cycle from
/// max_stride from the first. The GPU stabilizer and the CPU stabilizer
/// share this.
class StrideSchedule {
 public:
  explicit StrideSchedule(const StabilizeSettings& settings)
      : max_(settings.max_stride),
        every_(settings.check_every),
        adaptive_(settings.adaptive_stride),
        cap_(adaptive_ ? 1 : max_) {}
  /// Back to the first stride: single steps, or max_stride when not adaptive
  /// (snow set or added).
  void restart();
  /// The stride of the next pass.
  int next();
  /// A convergence check after a pass of `stride` found `residual` (m).
  void checked(int stride, float residual);
  int largest() const { return cap_; }
  /// The last check found the largest move falling by less than half per
  /// check_every passes (only checks after a single step count).
  bool creeping() const { return creeping_; }
  /// Passes since pressed snow was last looked for (pressed_looked_for).
  int since_pressed() const { return since_pressed_; }
  void pressed_looked_for() { since_pressed_ = 0; }
  /// Whether a check after the last pass is the first at or after a
  /// multiple of kCreepRouteEvery passes since construction: where routing
  /// creeping snow is decided (creep_route_due). Checks run at the same
  /// passes with asynchronous ones, so both decide at the same passes.
  bool creep_point() const { return passes_ >= creep_next_; }

 private:
  int max_, every_;
  bool adaptive_;
  int cap_;           // largest stride now
  int cycle_ = 0;     // passes since cap_ was set
  int since_ = 0;     // passes since the last single-step check that counted
  double last_ = -1;  // its residual (m); < 0: none yet
  bool creeping_ = false;
  int since_pressed_ = 0;  // passes since pressed snow was looked for; not reset by restart()
  bool creeping_before_ = false;  // creeping_ at the check before the last
  float residual_now_ = 0.0f;     // residual of the last check (m)
  float residual_before_ = 0.0f;  // and of the one before (m)
  int passes_ = 0;                // passes since construction; not reset by restart()
  int creep_next_ = 0;            // the pass from which the next check is a creep point
  friend bool creep_route_due(const StabilizeSettings&, StrideSchedule&, bool);
};

/// Draining (settings.drain_edges): snow creeping off an edge into the void
/// is a slope relaxing by diffusion, in passes that grow with the square of
/// its length. So at a check where the snow creeps and the snow leaving one
/// texel into the void is at least kDrainShare of the largest move, the
/// routing runs again, but moves only the excess whose path ends in the void:
/// it is lost at once, and the snow elsewhere stays (no mounds where the
/// relaxation would spread it).
/// `residual_void`: the largest sum a texel sent into the void in that pass.
/// Shared by both stabilizers, which measure both maxima alike.
constexpr float kDrainShare = 0.25f;
bool drain_due(const StabilizeSettings& settings, const StrideSchedule& schedule, float residual,
               float residual_void);
/// Routing creeping snow (settings.route_creep): at a check that is a creep
/// point (StrideSchedule::creep_point; called at every check, it passes the
/// point) where the check before found the snow creeping and still moving
/// more than the tolerance, the routing runs again with the kept heights of
/// the angle of repose alone: the holding depth, which sheds the snow as it
/// fell from steep supports in the first routing, is not applied again, as
/// the relaxation does not apply it to loose snow (with it, snow resting
/// loose in a fold of a steep support is routed out, poured back by the
/// relaxation and routed out again). What the relaxation would carry a
/// texel per pass goes down its whole path to where it rests, and is poured
/// there. It takes precedence over draining, which it includes. Shared by
/// both stabilizers. `late` (asynchronous checks, whose last check read is
/// the one before the pass just checked) takes the last check read instead
/// of the one before, so both kinds of checks decide on the moves of the
/// same pass.
constexpr int kCreepRouteEvery = 32;
bool creep_route_due(const StabilizeSettings& settings, StrideSchedule& schedule, bool late);
/// The three routings: after snow is set or added (kept heights capped at
/// the holding depth), draining (drain_due: the excess whose path ends in
/// the void runs down it, filling the room on its way, snow::spill_excess),
/// and of creeping snow (creep_route_due). Drains and creep routings keep
/// heights of the angle of repose alone, the rule the relaxation moves
/// loose snow by.
enum class Routing { Settle, Drain, Creep };
/// Metres: a routing of `kind` routes the snow of a texel whose top lies
/// more than this above its kept height. Drains and creep routings leave
/// loose snow less than min_move above it, as the relaxation does (routing
/// it poured tens of thousands of micrometre piles); the first routing
/// routes any excess. Both backends.
inline float routed_excess_of(const StabilizeSettings& settings, Routing kind) {
  return kind == Routing::Settle ? 0.0f : min_move_of(settings);
}
/// Snow pressed above its ceilings is poured (snow::pour_pressed_snow) at a
/// check where the snow creeps and still moves more than the tolerance, at
/// most once per kPressedEvery passes (schedule.pressed_looked_for() then
/// counts from there), before a drain, which runs at that check only if
/// nothing was poured (pressed snow squeezed into the void at an edge keeps
/// drains due, which move none of it); where none lies more than the
/// tolerance above its ceiling's clearance, nothing changes. Looking scans
/// every layer texel, after a full readback on the GPU, hence not at every
/// check. Shared by both stabilizers.
constexpr int kPressedEvery = 16;
bool pressed_snow_due(const StabilizeSettings& settings, const StrideSchedule& schedule,
                      float residual);

/// The routings a check runs once its moves are read, in the order above,
/// for both stabilizers: the creep routing where due (creep_route_due, with
/// `late`), else a pour of pressed snow where due, then a drain where due
/// and nothing was poured. `residual` and `residual_void` are the check's
/// largest moves (all, into the void). The backend's own steps: creep(),
/// pour() (whether it moved snow) and drain(); the counts go to `result`.
template <class Creep, class Pour, class Drain>
void run_check_routings(const StabilizeSettings& settings, StrideSchedule& schedule, bool late,
                        float residual, float residual_void, StabilizeResult& result, Creep creep,
                        Pour pour, Drain drain) {
  if (creep_route_due(settings, schedule, late)) {
    creep();
    ++result.creep_routes;
    return;
  }
  bool poured = false;
  if (pressed_snow_due(settings, schedule, residual)) {
    schedule.pressed_looked_for();
    poured = pour();
    if (poured) ++result.pours;
  }
  if (!poured && drain_due(settings, schedule, residual, residual_void)) {
    drain();
    ++result.drains;
  }
}
/// Layer texels per part of the sums over the maps (parallel_sum: the same
/// bits on any number of cores).
constexpr size_t kSumChunk = size_t(1) << 16;

/// Snow volume (m^3): sum of depth (m) over the layer texels that have a
/// surface times texel^2, in double (parts of kSumChunk texels).
double snow_volume(const SnowMaps& maps, const std::vector<float>& depth);

using plan::StabilizerUse;

/// Where settings.device puts the passes of `use` on the GL that `gl`
/// describes: true for the CPU (plan::stabilizer_on_cpu). The GPU's passes
/// need a current GL context, or a gl::OnDemandContext.
bool stabilizes_on_cpu(const StabilizeSettings& settings, StabilizerUse use,
                       const plan::GlFacts& gl);

/// Stabilizes `depth` (metres per layer texel, maps' layout; NaN, negative
/// or depth on texels without a surface is treated as 0 and cleared) in
/// place on the GPU: routing, then relaxation passes until the largest
/// move is below settings.tolerance (checked every check_every passes) or
/// max_iterations passes. Mass is conserved up to float rounding, minus the
/// counted losses. Needs a current GL context. Throws InputError for bad
/// maps, depth size or settings, GLError for GL trouble.
StabilizeResult stabilize(const SnowMaps& maps, std::vector<float>& depth,
                          const StabilizeSettings& settings);

/// The stabilizer with its state kept on the GPU between calls, for the live
/// preview and for time-stepped accumulation: the maps are uploaded once;
/// snow is added, a few passes run per frame, and the depth is read back on
/// demand. Needs the GL context that was current at construction to be
/// current in every call, including destruction.
class Stabilizer {
 public:
  /// Uploads the maps (cells) and allocates the pass textures (80 B per
  /// layer texel); the snow starts empty. Throws like stabilize().
  Stabilizer(const SnowMaps& maps, const StabilizeSettings& settings);
  ~Stabilizer();
  Stabilizer(Stabilizer&&) noexcept;
  Stabilizer& operator=(Stabilizer&&) noexcept;

  /// Replaces the snow (metres per layer texel, maps' layout; cleaned as in
  /// stabilize()), all of it as fallen where it lies (cohesion holds it up
  /// to the held cap), and resets the lost volume. Routing runs before the
  /// next pass. Throws InputError for a wrong size.
  void set_depth(const std::vector<float>& depth);
  /// depth += scale * amount on every texel with a surface (e.g. amount =
  /// coverage, scale = metres of fresh snow); negative or NaN products add
  /// nothing. Routing runs before the next pass. Throws InputError for a
  /// wrong size.
  void add_snow(const std::vector<float>& amount, float scale);
  /// Keeps `amount` (maps' layout, e.g. the coverage; negative, NaN or on
  /// texels without a surface: 0) on the GPU for add_snow(scale), so that
  /// repeated snowfalls upload nothing (the live preview). Throws
  /// InputError for a wrong size, GLError when it cannot be allocated.
  void set_snow_amount(const std::vector<float>& amount);
  /// depth += scale * the kept amount (set_snow_amount; none kept: adds
  /// nothing), as add_snow(amount, scale) adds it. Routing runs before the
  /// next pass.
  void add_snow(float scale);

  /// Runs the pending routing, then up to `passes` relaxation passes,
  /// stopping early once converged (checked every check_every passes and
  /// after the last). Fills every field; volume and lost_volume come from a
  /// GPU sum (float per block, double over blocks), unless volume sums are
  /// off.
  StabilizeResult iterate(int passes);
  /// Off: iterate() leaves volume and lost_volume 0, for a caller that sums
  /// them once at the end (each is a sum over the maps).
  void set_volume_sums(bool on);
  /// On: each convergence check asks the GPU for its largest moves and
  /// reads those of the check before (its fence long passed), so no check
  /// waits for the passes just queued; the decisions (convergence, strides,
  /// drains) come a check late, and a call reports the last check read. A
  /// call's first check reads its own when no earlier one is pending (after
  /// construction, set_depth or add_snow). For the live preview, whose
  /// frames each end with a check; off (the default): every check reads its
  /// own pass, which the batch job and the tests compare passes by.
  void set_async_checks(bool on);
  /// iterate(settings.max_iterations), with volume and lost_volume summed
  /// exactly (double) from a full readback.
  StabilizeResult run();

  /// Current depth (metres per layer texel, maps' layout); a full readback.
  std::vector<float> depth() const;
  /// Lost volume (m^3) since construction or set_depth (full readback).
  double lost_volume() const;
  /// The current depth texture (GL name of a GL_TEXTURE_2D_ARRAY, RG32F,
  /// one layer per map layer, r = depth in metres, g = lost metres) for
  /// renderers; valid until the next call that runs passes.
  unsigned depth_texture() const;
  const MapGrid& grid() const;
  int layers() const;
  const StabilizeSettings& settings() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace snow
