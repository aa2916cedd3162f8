#pragma once
// The stabilizer passes (snow/stabilize.h) on the CPU: the same outflow,
// gather, erosion, receiver, jump, scatter and apply passes as the GPU
// fragment passes, in the same order, on the cells of
// snow::stabilize_cells (zeros where there is no surface: only the flags of
// those are read). The two agree within the backends' tolerance (1 mm per
// layer texel, 0.1 % of the volume; docs/ARCHITECTURE.md, "Stabilizer"),
// each deterministic on its own. The erosion alone
// runs differently, in place (CpuStabilizer::erode), to the same kept
// heights in fewer rounds than the GPU's passes; StabilizeResult's
// route_passes counts those rounds.
//
// Two uses:
//  - the reference that the GPU passes are tested against (with
//    settings.active_tiles off it computes every layer texel in every pass,
//    as the passes are specified);
//  - the stabilizer of the batch job and the live preview on a software
//    rasterizer (StabilizeSettings::device),
//    where the "GPU" passes run on the same CPU cores anyway: here the passes
//    run natively on all cores, over 4 x 4-column tiles, and skip the tiles
//    whose inputs did not change since they last moved nothing, which
//    llvmpipe's fragment passes cannot do (a fragment that does nothing
//    costs it nearly what one that works does). Same results as full passes,
//    bit for bit.
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include <algorithm>

#include <glm/glm.hpp>

#include "core/zeroed.h"
#include "snow/maps.h"
#include "snow/stabilize.h"

namespace snow {

/// Neighbour direction n (0..7): column offset (kDirI[n], kDirJ[n]); 0..3 are
/// the edge neighbours (distance texel), 4..7 the diagonal ones (texel*sqrt2).
constexpr int kDirI[8] = {1, -1, 0, 0, 1, -1, 1, -1};
constexpr int kDirJ[8] = {0, 0, 1, -1, 1, 1, -1, -1};

/// The snow surface of a layer texel with cell `cell` and depth s (m) as far
/// as it is free to move: ground + depth, kept kCeilingClearance under the
/// ceiling (column.glsl free_top).
inline float free_top(const glm::vec4& cell, float s) {
  return std::max(cell.x, std::min(cell.x + s, cell.y - kCeilingClearance));
}

/// A column (i, j) of the stabilizer's cells (maps' layout, `per_layer`
/// texels a layer) for land_in_column (snow/column.h), its snow tops
/// top(k) of layer texel k: the depth's, or the routing's kept heights.
template <class Top>
struct CellColumn {
  const glm::vec4* cells;
  size_t per_layer, column;  // column: j * width + i
  Top top_of;
  size_t k(int l) const { return size_t(l) * per_layer + column; }
  bool has(int l) const { return (int(cells[k(l)].w) & kCellSurface) != 0; }
  float ground(int l) const { return cells[k(l)].x; }
  float ceiling(int l) const { return cells[k(l)].y; }
  float top(int l) const { return top_of(k(l)); }
  bool solid(int l) const { return (int(cells[k(l)].w) & kCellSolid) != 0; }
  bool faces_down(int l) const { return (int(cells[k(l)].w) & kCellDown) != 0; }
};

/// The CPU twin of snow::Stabilizer: same contract, same passes, same float
/// math.
class CpuStabilizer {
 public:
  /// Throws InputError like snow::Stabilizer. `threads`: worker threads of
  /// the passes (0 = default_threads()); the results do not depend on it.
  CpuStabilizer(const SnowMaps& maps, const StabilizeSettings& settings, unsigned threads = 0);

  void set_depth(const std::vector<float>& depth);
  void add_snow(const std::vector<float>& amount, float scale);
  /// As Stabilizer::set_snow_amount and add_snow(scale).
  void set_snow_amount(const std::vector<float>& amount);
  void add_snow(float scale);
  /// Pending routing, then up to `passes` relaxation passes (early stop as
  /// on the GPU). volume and lost_volume are exact (double) sums;
  /// route_seconds is the routing's wall time; tile_share, with
  /// settings.count_tiles, the share of tiles times layers computed.
  StabilizeResult iterate(int passes);
  /// As Stabilizer::set_volume_sums (the batch job sums once at the end: a
  /// sum reads every layer texel, and iterate() runs many times a run).
  void set_volume_sums(bool on) { volume_sums_ = on; }
  StabilizeResult run() { return iterate(settings_.max_iterations); }

  std::vector<float> depth() const { return {depth_.begin(), depth_.end()}; }
  /// The same depth in place (layer texels in the maps' layout), valid
  /// until the next call that changes it.
  const float* depth_data() const { return depth_.data(); }
  double lost_volume() const;

 private:
  struct Tile {
    int i0, j0, i1, j1;  // columns [i0, i1) x [j0, j1)
  };
  /// Outflow: amount (8 per layer texel, metres) and code (8 per layer
  /// texel: landing layer, kCodeNone or kCodeVoid; kCodeNone where nothing
  /// moves) from the current depth; residual_ = the largest move,
  /// residual_seen_ = the largest the convergence test sees.
  void outflow_pass(int stride);
  /// Gather: depth -= own outflow, += neighbours' outflow landing here; lost
  /// += own outflow to kCodeVoid. `stride` is the last outflow's.
  void gather_pass(int stride);
  /// Routing (erosion until stable, receiver, jumps until every pointer
  /// reaches a terminal, scatter, apply); returns the erosion rounds plus
  /// jump passes run. Adds the routed volume (m^3) to *routed_volume. With
  /// Routing::Drain (drain_due; routed_volume unused), the excess fills and
  /// spills down its paths after the erosion (spill_excess); with Routing::Creep
  /// (creep_route_due) the kept heights start at the free tops.
  int route(double* routed_volume, Routing kind = Routing::Settle);
  /// route() of `kind` (not Drain) adding its passes, routed volume and wall
  /// time to `result`.
  void route_into(Routing kind, StabilizeResult& result);
  [[gnu::always_inline]] int land(int i, int j, float h, float support, float rise,
                                  bool kept = false) const;
  int gap_at(int i, int j, float h) const;
  /// land and gap_at past the `count` surfaces of column (i, j):
  /// kLandBlocked or kLandVoid.
  int past_column(int i, int j, int count) const;
  /// Whether a single step moves snow from layer texel (i, j) with this cell,
  /// depth s, free top he and snow over the ceiling (the rule strided passes
  /// move by).
  bool single_step_moves(int i, int j, const glm::vec4& cell, float movable, float he,
                         float over) const;
  /// Outflow of one layer texel into out[8] and code[8]; returns the sum of
  /// its amounts, adds the sum of those into the void to *to_void and of
  /// those squeezed into full gaps (unseen by the convergence test) to
  /// *hidden.
  /// kStrided: stride > 1 (compiled apart: single steps are most passes).
  template <bool kStrided>
  float outflow_texel(int l, int i, int j, int stride, float* to_void, float* out, uint8_t* code,
                      float* hidden);
  /// Gather of the layer texels of one column; true when a depth changed.
  bool gather_column(int i, int j, int stride);
  /// Erosion of one layer texel: its next kept height from stable_.
  float erode_texel(int l, int i, int j) const;
  /// The kept height layer texel k starts the erosion from: its free top,
  /// no higher than its holding depth above its ground (snow deeper than
  /// that slides off its slope, snow/cohesion.h) unless `repose_only`
  /// (Routing::Creep). Mirrors column.glsl kept_height with u_start.
  float start_height(size_t k, bool repose_only) const;
  /// stable_ from start_height, eroded until no texel changes; returns the
  /// rounds that changed a texel.
  int erode(bool repose_only);
  /// Erosion sweeps over tile t in place until none changes a texel; true
  /// when one did.
  bool erode_tile(int t);
  /// A set of tiles: a flag per tile and the list of those set.
  struct TileSet {
    std::vector<uint8_t> in;
    std::vector<int> list;
    void reset(size_t tiles);
    void add(int t) {
      if (!in[size_t(t)]) {
        in[size_t(t)] = 1;
        list.push_back(t);
      }
    }
    void clear();
  };
  /// Adds the tiles with a surface within `reach` tiles of tile t (t itself
  /// only with `self`).
  void add_near(TileSet& set, int t, int reach, bool self = true) const;
  /// The same, for the tiles u that keep(u) accepts.
  template <class Keep>
  void add_near(TileSet& set, int t, int reach, Keep keep) const;
  /// Tiles within this many of a tile hold the columns a pass of `stride`
  /// reads.
  static int reach(int stride) { return (stride + kTile - 1) / kTile; }
  /// Runs fn(tile index, slot) over `tiles` on the worker threads.
  template <class Fn>
  void for_tiles(const std::vector<int>& tiles, Fn fn);
  Tile tile(int t) const;
  /// Every tile dirty for every stride (snow set, added or routed), and
  /// every gate stale.
  void touch_all();
  /// Whether no column within one of (i, j) changed at pass `pass` or later.
  bool quiet_since(int i, int j, uint32_t pass) const;
  /// Tile t changed: the tiles within each stride's reach are dirty for it.
  void touch(int t);
  /// The columns of `box` (inclusive bounds) in tile t changed: the tiles
  /// within each stride of them are dirty for it.
  void touch(int t, const Tile& box);
  /// Pours the snow pressed above its ceilings (pour_pressed_snow with the
  /// settings' tolerance), looking only at the tiles whose depth changed
  /// since the last call: the same piles as looking at every texel. The
  /// first call lists every texel under a ceiling and looks at all of them.
  size_t pour_pressed();
  double snow_volume() const;
  size_t index(int l, int i, int j) const {
    return (size_t(l) * size_t(height_) + size_t(j)) * size_t(width_) + size_t(i);
  }

  StabilizeSettings settings_;
  float min_move_ = 0.0f;  // min_move_of(settings_), metres
  StrideSchedule schedule_{settings_};
  unsigned threads_ = 0;
  int width_ = 0, height_ = 0, layers_ = 0;
  float texel_ = 0.0f;
  float distance_[8] = {};              // metres, per direction
  float rise_ = 0.0f;                   // metres, kSurfaceContinuityTexels * texel
  ZeroedArray<glm::vec4> cells_;        // stabilize_surface_cells
  ZeroedArray<float> hold_;             // metres, stabilize_holds
  ZeroedArray<float> held_cap_;         // metres: what cohesion may hold of each texel's snow,
                                        // min(hold_, standing height, the snow that fell there
                                        // by set_depth and add_snow); snow that arrives by
                                        // sliding or routing is loose
  float stand_ = 0.0f;                  // metres, settings_.cohesion.stand_height
  std::vector<uint8_t> column_layers_;  // surfaces per column (layers are packed from the top)
  std::vector<uint8_t> column_sent_;    // per column: its last outflow moved snow
  // Per layer texel arrays that start at zero hold zero pages where the
  // layers have no surface (core/zeroed.h).
  ZeroedArray<float> depth_;
  ZeroedArray<float> lost_;  // metres lost per layer texel (accumulated at the source)
  // Outflow of the layer texels with a surface (written by a pass before
  // any read; only the columns that send snow are written, so most pages
  // are never touched).
  ZeroedArray<float> amount_;  // 8 per layer texel, metres
  ZeroedArray<uint8_t> code_;  // 8 per layer texel
  ZeroedArray<float> stable_;  // metres, highest snow surface each texel can keep (routing)
  // The single-step rule of each layer texel (single_step_moves) as the last
  // stride-1 outflow that computed it found it: pass << 1 | moves. A strided
  // pass reads it instead of walking the eight landings again while no
  // column around the texel changed since that pass (column_changed_): most
  // texels of a late strided pass rest.
  ZeroedArray<uint32_t> gate_;
  std::vector<uint32_t> column_changed_;  // per column: the pass whose gather last changed it
  uint32_t pass_id_ = 0;                  // relaxation passes so far, counted from 1
  uint32_t gates_from_ = 1;     // gates of earlier passes are stale (depth set, routed or poured)
  float residual_ = 0.0f;       // largest move of the last outflow pass
  float residual_void_ = 0.0f;  // and the largest into the void
  float residual_seen_ = 0.0f;  // and the largest the convergence test sees
  bool route_pending_ = false;
  bool volume_sums_ = true;
  bool populated_ = false;          // add_snow faulted in the pages of its snow (once)
  std::vector<float> kept_amount_;  // set_snow_amount's (empty: none)
  // The layer texels with a surface under a ceiling, by tile: those of tile
  // t are under_ceilings_[under_start_[t], under_start_[t + 1]), listed at
  // the first check for pressed snow (pour_pressed).
  std::vector<uint32_t> under_ceilings_, under_start_;
  // The tiles whose depth changed since the last check for pressed snow.
  TileSet pressed_stale_;

  // Tiles of kTile x kTile columns, all layers.
  static constexpr int kTile = 4;
  int tiles_x_ = 0, tiles_y_ = 0;
  std::vector<int> surface_tiles_;    // the tiles with a surface
  std::vector<uint8_t> has_surface_;  // per tile
  int levels_ = 1;                    // strides 1, 2, ..., max_stride
  TileSet dirty_[7];  // per log2(stride): the tiles whose next outflow of that stride may move
                      // snow (a column it reads changed since its last one moved nothing
                      // there, or that one moved snow)
  TileSet sent_;      // the tiles whose last outflow moved snow
  TileSet near_;      // scratch: the tiles a gather or erosion pass computes
  std::vector<uint8_t> changed_;     // per tile: its last erosion pass changed it
  std::vector<Tile> changed_box_;    // per tile: the columns its last gather changed
  std::vector<int> work_;            // the tiles a pass computes
  std::vector<glm::vec3> slot_max_;  // per tile of work_: largest move, into the void, seen
  double tile_work_ = 0.0;           // tiles computed by the relaxation passes (count_tiles)
};

/// One-off CPU stabilize (same contract as snow::stabilize): a CpuStabilizer
/// run for max_iterations (or max_iterations_override when >= 0) passes at
/// most. Negative rounding residues are cleared in the output.
StabilizeResult stabilize_cpu(const SnowMaps& maps, std::vector<float>& depth,
                              const StabilizeSettings& settings, int max_iterations_override = -1);

}  // namespace snow
