// The stabilizer passes on the CPU (the stage's contract: snow/stabilize.h;
// angle of repose relaxation after Fearing 2000, section 5; steep routing as
// steepest-descent flow routing over a terrain). Every per-texel function
// here mirrors one fragment shader of shaders/stabilize_*.frag statement by
// statement, so that the GPU and the CPU agree to the bit.
//
// Active tiles: a pass computes a tile (kTile x kTile columns, all layers)
// only when something it reads changed (for an outflow of stride s, a column
// within s of its own; after routing, any tile within reach) since the
// tile's last pass of the same kind and stride moved nothing there;
// a skipped tile would repeat that pass's result (no move), so the results
// are those of full passes. Each stride keeps its set of such (dirty) tiles,
// and each pass lists the tiles it computes, so a pass costs what it
// computes, not the map's size. Uncomputed tiles keep zero amounts and no
// codes: a tile whose outflow moved snow stays dirty and is changed by its
// gather, so its next outflow is computed.
#include "snow/stabilize_cpu.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <new>
#include <string>
#include <utility>

#include "core/error.h"
#include "core/parallel.h"
#include "snow/column.h"
#include "snow/deposit.h"

namespace snow {
namespace {

/// Landing codes of the outflow pass besides a layer index (0..63).
constexpr uint8_t kCodeNone = 254;  // no flow in that direction
constexpr uint8_t kCodeVoid = 255;  // flow off the map or into the void below: lost
/// Receiver pointers of the routing passes besides a texel index.
constexpr uint32_t kPointerVoid = 0xffffffffu;

int cell_flags(const glm::vec4& cell) { return int(cell.w); }

// The snow of a texel that cohesion holds in place (snow/cohesion.h): its
// depth s up to `cap`, what of the snow that fell there cohesion can hold
// (held_cap_), and never above its free top (snow pressed out from under a
// ceiling moves). Mirrors column.glsl held.
float held_snow(const glm::vec4& cell, float s, float cap) {
  return std::min(std::min(s, free_top(cell, s) - cell.x), cap);
}

// Sends `amount` into the `voids` directions whose code is kCodeVoid, in
// equal shares, the last taking what rounding leaves (so out sums to it
// exactly). Mirrors stabilize_outflow.frag fall_off.
void fall_off(const uint8_t* code, int voids, float amount, float* out) {
  const float share = amount / float(voids);
  float left = amount;
  int seen = 0;
  for (int n = 0; n < 8; ++n) {
    if (code[n] != kCodeVoid) continue;
    ++seen;
    out[n] = seen == voids ? left : share;
    left -= share;
  }
}

int log2_of(int stride) {
  int b = 0;
  while ((2 << b) <= stride) ++b;
  return b;
}

}  // namespace

CpuStabilizer::CpuStabilizer(const SnowMaps& maps, const StabilizeSettings& settings,
                             unsigned threads)
    : settings_(settings),
      min_move_(min_move_of(settings)),
      threads_(threads),
      width_(maps.grid.width),
      height_(maps.grid.height),
      layers_(maps.layers),
      texel_(maps.grid.texel) {
  rise_ = kSurfaceContinuityTexels * texel_;
  stand_ = settings_.cohesion.stand_height;
  distance_[0] = distance_[1] = distance_[2] = distance_[3] = texel_;
  distance_[4] = distance_[5] = distance_[6] = distance_[7] =
      float(double(texel_) * std::sqrt(2.0));
  try {
    cells_ = stabilize_surface_cells(maps, settings);
    hold_ = stabilize_holds(maps, settings);
    const size_t n = cells_.size();
    depth_ = ZeroedArray<float>(n);
    held_cap_ = ZeroedArray<float>(n);
    lost_ = ZeroedArray<float>(n);
    amount_ = ZeroedArray<float>(8 * n);
    code_ = ZeroedArray<uint8_t>(8 * n);
    gate_ = ZeroedArray<uint32_t>(n);
  } catch (const std::bad_alloc&) {
    throw InputError("stabilize: out of memory for maps of " + std::to_string(width_) + " x " +
                     std::to_string(height_) + " texels x " + std::to_string(layers_) +
                     " layers (72 B per layer texel); use a coarser texel size");
  }

  const size_t columns = size_t(width_) * size_t(height_);
  column_layers_.assign(columns, 0);
  column_sent_.assign(columns, 0);
  column_changed_.assign(columns, 0);
  parallel_for_ranges(columns, kSumChunk, [&](size_t begin, size_t end) {
    for (size_t c = begin; c < end; ++c) {
      int l = 0;
      while (l < layers_ && (cell_flags(cells_[size_t(l) * columns + c]) & kCellSurface)) ++l;
      column_layers_[c] = uint8_t(l);
    }
  });
  tiles_x_ = (width_ + kTile - 1) / kTile;
  tiles_y_ = (height_ + kTile - 1) / kTile;
  const size_t tiles = size_t(tiles_x_) * size_t(tiles_y_);
  for (size_t t = 0; t < tiles; ++t) {
    const Tile b = tile(int(t));
    bool any = false;
    for (int j = b.j0; j < b.j1 && !any; ++j) {
      for (int i = b.i0; i < b.i1 && !any; ++i) any = column_layers_[size_t(j) * width_ + i] > 0;
    }
    if (any) surface_tiles_.push_back(int(t));
  }
  has_surface_.assign(tiles, 0);
  for (int t : surface_tiles_) has_surface_[size_t(t)] = 1;
  levels_ = log2_of(settings_.max_stride) + 1;
  for (int level = 0; level < levels_; ++level) dirty_[level].reset(tiles);
  sent_.reset(tiles);
  near_.reset(tiles);
  pressed_stale_.reset(tiles);
  changed_.assign(tiles, 0);
  changed_box_.assign(tiles, Tile{});
}

CpuStabilizer::Tile CpuStabilizer::tile(int t) const {
  const int ti = t % tiles_x_, tj = t / tiles_x_;
  return {ti * kTile, tj * kTile, std::min(width_, (ti + 1) * kTile),
          std::min(height_, (tj + 1) * kTile)};
}

void CpuStabilizer::TileSet::reset(size_t tiles) {
  in.assign(tiles, 0);
  list.clear();
}

void CpuStabilizer::TileSet::clear() {
  for (int t : list) in[size_t(t)] = 0;
  list.clear();
}

void CpuStabilizer::add_near(TileSet& set, int t, int reach, bool self) const {
  add_near(set, t, reach, [&](int u) { return self || u != t; });
}

template <class Keep>
void CpuStabilizer::add_near(TileSet& set, int t, int reach, Keep keep) const {
  const int ti = t % tiles_x_, tj = t / tiles_x_;
  for (int b = std::max(0, tj - reach); b <= std::min(tiles_y_ - 1, tj + reach); ++b) {
    for (int a = std::max(0, ti - reach); a <= std::min(tiles_x_ - 1, ti + reach); ++a) {
      const int u = b * tiles_x_ + a;
      if (has_surface_[size_t(u)] && keep(u)) set.add(u);
    }
  }
}

void CpuStabilizer::touch_all() {
  gates_from_ = pass_id_ + 1;
  for (int level = 0; level < levels_; ++level) {
    dirty_[level].clear();
    for (int t : surface_tiles_) dirty_[level].add(t);
  }
  for (int t : surface_tiles_) pressed_stale_.add(t);
}

void CpuStabilizer::touch(int t) {
  for (int level = 0; level < levels_; ++level) add_near(dirty_[level], t, reach(1 << level));
  pressed_stale_.add(t);
}

void CpuStabilizer::touch(int t, const Tile& box) {
  // An outflow of stride s reads the columns within s (Chebyshev distance)
  // of its own, so only tiles that near the changed columns are dirty for
  // it. Snow creeping inside a tile then leaves its neighbours clean for
  // single steps, where touch(t) made all eight dirty: fewer tiles
  // computed, the same passes, bit for bit.
  for (int level = 0; level < levels_; ++level) {
    const int stride = 1 << level;
    add_near(dirty_[level], t, reach(stride), [&](int u) {
      const Tile c = tile(u);
      const int dx = std::max({0, c.i0 - box.i1, box.i0 - (c.i1 - 1)});
      const int dy = std::max({0, c.j0 - box.j1, box.j0 - (c.j1 - 1)});
      return std::max(dx, dy) <= stride;
    });
  }
  pressed_stale_.add(t);
}

template <class Fn>
void CpuStabilizer::for_tiles(const std::vector<int>& tiles, Fn fn) {
  // Tiles are handed out in chunks (a hand-out costs about what a small tile
  // does), and a thread start about what a few chunks do: small passes stay
  // on one thread.
  constexpr size_t kChunk = 16;
  const size_t chunks = (tiles.size() + kChunk - 1) / kChunk;
  parallel_for(
      chunks,
      [&](size_t chunk) {
        const size_t end = std::min(tiles.size(), (chunk + 1) * kChunk);
        for (size_t slot = chunk * kChunk; slot < end; ++slot) fn(tiles[slot], slot);
      },
      chunks < 4 ? 1u : threads_);
}

void CpuStabilizer::set_depth(const std::vector<float>& depth) {
  if (depth.size() != cells_.size()) {
    throw InputError("stabilize: depth has " + std::to_string(depth.size()) +
                     " entries, the maps have " + std::to_string(cells_.size()) + " layer texels");
  }
  // Zeros are written only over what is not zero, so pages that stay zero
  // are never touched (core/zeroed.h).
  for (size_t k = 0; k < cells_.size(); ++k) {
    const float d = depth[k];
    const float v = (cell_flags(cells_[k]) & kCellSurface) && d > 0.0f ? d : 0.0f;
    if (v != 0.0f || depth_[k] != 0.0f) depth_[k] = v;
    const float cap = std::min(v, std::min(stand_, hold_[k]));
    if (cap != 0.0f || held_cap_[k] != 0.0f) held_cap_[k] = cap;
    if (lost_[k] != 0.0f) lost_[k] = 0.0f;
  }
  touch_all();
  route_pending_ = true;
  schedule_.restart();
}

void CpuStabilizer::add_snow(const std::vector<float>& amount, float scale) {
  if (amount.size() != cells_.size()) {
    throw InputError("stabilize: snow amount has " + std::to_string(amount.size()) +
                     " entries, the maps have " + std::to_string(cells_.size()) + " layer texels");
  }
  // Mirrors shaders/stabilize_add.frag.
  const bool populate = !populated_;
  populated_ = true;
  parallel_for_ranges(cells_.size(), kSumChunk, [&](size_t begin, size_t end) {
    // At the first snowfall, the pages of depths this adds to, and of the
    // gates of those texels, are faulted in first, a run of them per call:
    // a page's first read maps the shared zero page, and its first write
    // then copies it and flushes the other cores' TLBs, several times what a
    // first write costs (core/zeroed.h).
    // Later snowfalls (steps, the live preview's frames) mostly land there.
    constexpr size_t kPage = 4096 / sizeof(float);
    size_t run = end;  // start of the open run of pages to fault in
    const auto fault_in = [&](size_t to) {
      depth_.populate(run, to);
      held_cap_.populate(run, to);
      gate_.populate(run, to);
      run = end;
    };
    for (size_t page = begin; populate && page < end; page += kPage) {
      const size_t page_end = std::min(end, page + kPage);
      bool adds = false;
      for (size_t k = page; k < page_end && !adds; ++k) adds = amount[k] * scale > 0.0f;
      if (adds && run == end) run = page;
      if (!adds && run != end) fault_in(page);
    }
    if (run != end) fault_in(end);
    for (size_t k = begin; k < end; ++k) {
      const float add = amount[k] * scale;
      if ((cell_flags(cells_[k]) & kCellSurface) && add > 0.0f) {
        depth_[k] = depth_[k] + add;
        held_cap_[k] = std::min(held_cap_[k] + add, std::min(stand_, hold_[k]));
      }
    }
  });
  touch_all();
  route_pending_ = true;
  schedule_.restart();
}

void CpuStabilizer::set_snow_amount(const std::vector<float>& amount) {
  if (amount.size() != cells_.size()) {
    throw InputError("stabilize: snow amount has " + std::to_string(amount.size()) +
                     " entries, the maps have " + std::to_string(cells_.size()) + " layer texels");
  }
  kept_amount_ = amount;
}

void CpuStabilizer::add_snow(float scale) {
  if (!kept_amount_.empty()) add_snow(kept_amount_, scale);
}

double CpuStabilizer::lost_volume() const {
  const double sum = parallel_sum(lost_.size(), kSumChunk, [&](size_t begin, size_t end) {
    double part = 0.0;
    for (size_t k = begin; k < end; ++k) part += double(lost_[k]);
    return part;
  });
  return sum * double(texel_) * double(texel_);
}

// Past the `count` surfaces of column (i, j), as column.glsl's landing
// walk ends: a wall (kLandBlocked) where all L layers hold a surface or the
// lowest faces up, else the void.
inline int CpuStabilizer::past_column(int i, int j, int count) const {
  if (count == layers_) return kLandBlocked;
  return count > 0 && (cell_flags(cells_[index(count - 1, i, j)]) & kCellDown) == 0 ? kLandBlocked
                                                                                    : kLandVoid;
}

// Mirrors shaders/column.glsl: snow::land_in_column on the cells, with the
// snow tops ground + depth, or with `kept` the routing's kept heights. The
// layers with a surface are the column's first column_layers_ (packed from
// the top), so the loop reads no cell past them and converts flags only
// where it needs them.
inline int CpuStabilizer::land(int i, int j, float h, float support, float rise, bool kept) const {
  if (i < 0 || j < 0 || i >= width_ || j >= height_) return kLandVoid;
  const int count = column_layers_[size_t(j) * width_ + i];
  for (int l = 0; l < count; ++l) {
    const size_t k = index(l, i, j);
    const glm::vec4& cell = cells_[k];
    if (h >= cell.y) return kLandBlocked;
    const float top = kept ? stable_[k] : cell.x + depth_[k];
    if (top <= h) {
      if ((cell_flags(cell) & kCellSolid) != 0 || cell.y - support < rise) return kLandBlocked;
      return l;
    }
    if (h >= cell.x) return kLandBlocked;
  }
  return past_column(i, j, count);
}

// Mirrors gap_at in shaders/stabilize_outflow.frag: the layer of column
// (i, j) whose gap (ground up to ceiling, not a solid's inside) contains
// height h, kLandBlocked or kLandVoid.
int CpuStabilizer::gap_at(int i, int j, float h) const {
  if (i < 0 || j < 0 || i >= width_ || j >= height_) return kLandVoid;
  const int count = column_layers_[size_t(j) * width_ + i];
  for (int l = 0; l < count; ++l) {
    const glm::vec4& cell = cells_[index(l, i, j)];
    if (h >= cell.y) return kLandBlocked;
    if (h >= cell.x) return (cell_flags(cell) & kCellSolid) != 0 ? kLandBlocked : l;
  }
  return past_column(i, j, count);
}

bool CpuStabilizer::quiet_since(int i, int j, uint32_t pass) const {
  for (int b = std::max(0, j - 1); b <= std::min(height_ - 1, j + 1); ++b) {
    for (int a = std::max(0, i - 1); a <= std::min(width_ - 1, i + 1); ++a) {
      if (column_changed_[size_t(b) * width_ + a] >= pass) return false;
    }
  }
  return true;
}

// The stride-1 rule of a strided pass (see outflow_texel): would a single
// step move snow from this texel? Most texels of a late strided pass stay,
// and this answers for them without walking the paths.
bool CpuStabilizer::single_step_moves(int i, int j, const glm::vec4& cell, float movable, float he,
                                      float over) const {
  float wmax1 = 0.0f;
  for (int n = 0; n < 8; ++n) {
    const int ni = i + kDirI[n], nj = j + kDirJ[n];
    const int land_l = land(ni, nj, he, cell.x, rise_);
    if (land_l == kLandVoid) return true;
    if (land_l < 0) continue;
    const size_t km = index(land_l, ni, nj);
    const float top = cells_[km].x + depth_[km];
    wmax1 = std::max(wmax1, he - top - distance_[n] * (0.0f + cell.z));
  }
  return wmax1 > 0.0f && std::min(movable, std::max(0.5f * wmax1, over)) >= min_move_;
}

// Mirrors shaders/stabilize_outflow.frag.
template <bool kStrided>
float CpuStabilizer::outflow_texel(int l, int i, int j, int stride, float* to_void, float* out,
                                   uint8_t* code, float* hidden) {
  const size_t k = index(l, i, j);
  for (int n = 0; n < 8; ++n) {
    out[n] = 0.0f;
    code[n] = kCodeNone;
  }
  const glm::vec4 cell = cells_[k];
  const float s = depth_[k];
  if ((cell_flags(cell) & kCellSurface) == 0 || !(s > 0.0f)) return 0.0f;
  const float h = cell.x + s;
  const float he = free_top(cell, s);  // snow above the ceiling is pressed out
  const float over = h - he;
  // What cohesion holds stays (snow/cohesion.h); only the rest moves.
  const float movable = s - held_snow(cell, s, held_cap_[k]);
  if (!(movable > 0.0f)) {
    gate_[k] = pass_id_ << 1;  // a single step moves nothing either
    return 0.0f;
  }
  // A strided pass moves only snow that a single step moves: snow at rest
  // for single steps stays, which the GPU passes' active tiles rely on. The
  // rule's answer is kept (gate_) while nothing around the texel changes; a
  // single step that it says moves nothing moves nothing, unless the snow
  // is pressed out from under its ceiling.
  const uint32_t gate = gate_[k], at = gate >> 1;
  const bool known = at >= gates_from_ && quiet_since(i, j, at);
  if (kStrided) {
    bool moves = (gate & 1) != 0;
    if (!known) {
      moves = single_step_moves(i, j, cell, movable, he, over);
      gate_[k] = pass_id_ << 1 | uint32_t(moves);
    }
    if (!moves) return 0.0f;
  } else if (known && (gate & 1) == 0 && !(over > 0.0f)) {
    return 0.0f;
  }
  float w[8];
  float wsum = 0.0f, wmax = 0.0f;
  int voids = 0;
  for (int n = 0; n < 8; ++n) {
    w[n] = 0.0f;
    // A strided pass moves snow `stride` columns at once along a path of
    // single steps that fine passes could take: each step lands by the
    // landing rule and goes down by at most the continuity rise (no
    // fall over an edge, never into the void). The threshold is the sum
    // of the path texels' repose slopes, so a state at rest for single
    // steps is at rest for strided ones.
    int ni = i, nj = j;
    int land_l = 0;
    float path_h = he, path_g = cell.x, path_tan = 0.0f;
    float step_tan = cell.z;
    for (int m = 1; m <= stride; ++m) {
      ni = i + m * kDirI[n];
      nj = j + m * kDirJ[n];
      land_l = land(ni, nj, path_h, path_g, rise_);
      path_tan += step_tan;
      if (!kStrided || land_l < 0) break;
      const size_t km = index(land_l, ni, nj);
      const float top = cells_[km].x + depth_[km];
      if (path_h - top > rise_) {
        land_l = kLandBlocked;
        break;
      }
      path_h = top;
      path_g = cells_[km].x;
      step_tan = cells_[km].z;
    }
    if (kStrided && land_l == kLandVoid) land_l = kLandBlocked;
    if (land_l == kLandVoid) {
      code[n] = kCodeVoid;
      ++voids;
    } else if (land_l >= 0) {
      code[n] = uint8_t(land_l);
      const size_t kt = index(land_l, ni, nj);
      const float ht = cells_[kt].x + depth_[kt];
      // A receiver under a ceiling takes at most its room: sliding snow never
      // presses a full gap (what it pressed in there, the squeeze and the
      // pours of pressed snow sent back out, to be pushed in again).
      const float room = (cells_[kt].y - kCeilingClearance) - ht;
      const float e = std::min(he - ht - distance_[n] * path_tan, room);
      w[n] = std::max(e, 0.0f);
      wsum += w[n];
      wmax = std::max(wmax, w[n]);
    }
  }
  // Single steps: whether this texel moves snow by single_step_moves' rule
  // (set below where it does).
  if (!kStrided) gate_[k] = pass_id_ << 1 | uint32_t(voids > 0);
  if (voids > 0) {
    // An edge of the world: everything that moves falls off, shared by the
    // void directions.
    fall_off(code, voids, movable, out);
  } else if (wmax > 0.0f) {
    // Half the largest excess moves, split over the receivers by their
    // excess: a receiver rises by at most half its excess, so the pair
    // never overshoots and piles end at the repose slope.
    // Moves under min_move are not made (rounding noise).
    float total = std::min(movable, std::max(0.5f * wmax, over));
    if (!kStrided) gate_[k] = pass_id_ << 1 | uint32_t(total >= min_move_);
    if (total < min_move_) total = 0.0f;
    for (int n = 0; n < 8; ++n) out[n] = total * (w[n] / wsum);
  } else if (over > 0.0f && !kStrided) {
    // Snow deeper than its gap with nowhere downhill to go is squeezed
    // out sideways into the gaps of the neighbouring columns at that
    // height; the void, where there is one, takes all of it. Otherwise it
    // goes out until this texel and the gaps taking end level: each gap of
    // room r (minus its own over where it is full) takes L + r, where L >=
    // 0, this texel's over left, solves over - L = sum of (L + r) over the
    // gaps with L + r > 0 (with one gap, half the difference of over and
    // r). Where the rooms hold it all (L would be negative), it fills them
    // in proportion to their room. (Given all its over whenever the offers
    // of half the difference summed past it, a texel pressed among nearly
    // full gaps handed its over around and got it back the next pass, for
    // ever.) What goes into a gap that is already full changes no snow
    // surface (it stays at its ceiling) and is not a move the convergence
    // test sees (*hidden): pressure passed around in a closed full gap
    // would otherwise keep the stabilizer from ever resting.
    float room[8];
    bool gap[8] = {}, taking[8] = {};
    int edges = 0;
    for (int n = 0; n < 8; ++n) {
      room[n] = 0.0f;
      code[n] = kCodeNone;
      const int ni = i + kDirI[n], nj = j + kDirJ[n];
      const int nl = gap_at(ni, nj, he);
      if (nl == kLandVoid) {
        code[n] = kCodeVoid;
        ++edges;
      } else if (nl >= 0) {
        code[n] = uint8_t(nl);
        const size_t kt = index(nl, ni, nj);
        // (Room past the over takes no more: capped, the sums stay finite
        // under the open sky.)
        room[n] = std::min((cells_[kt].y - kCeilingClearance) - (cells_[kt].x + depth_[kt]), over);
        gap[n] = taking[n] = true;
      }
    }
    if (edges > 0) {
      fall_off(code, edges, over, out);
    } else {
      // The level: drop the gaps that would take nothing until none is
      // left to drop (L only falls, so a dropped gap stays dropped).
      float level = 0.0f;
      for (bool dropped = true; dropped;) {
        float rooms = 0.0f;
        int count = 0;
        for (int n = 0; n < 8; ++n) {
          if (!taking[n]) continue;
          rooms += room[n];
          ++count;
        }
        level = (over - rooms) / float(count + 1);
        dropped = false;
        for (int n = 0; n < 8; ++n) {
          if (taking[n] && !(level + room[n] > 0.0f)) {
            taking[n] = false;
            dropped = true;
          }
        }
      }
      if (level > 0.0f) {
        for (int n = 0; n < 8; ++n) {
          if (!taking[n]) continue;
          out[n] = level + room[n];
          if (!(room[n] > 0.0f)) *hidden += out[n];
        }
      } else {  // the rooms hold it all: filled in proportion to their room
        float free = 0.0f;
        for (int n = 0; n < 8; ++n) free += gap[n] ? std::max(room[n], 0.0f) : 0.0f;
        for (int n = 0; n < 8; ++n) {
          if (gap[n] && room[n] > 0.0f) out[n] = over * (room[n] / free);
        }
      }
    }
  }
  // A direction that moves nothing has no landing code.
  for (int n = 0; n < 8; ++n) {
    if (out[n] == 0.0f) code[n] = kCodeNone;
  }
  float sum = 0.0f;
  for (int n = 0; n < 8; ++n) {
    sum += out[n];
    if (code[n] == kCodeVoid) *to_void += out[n];
  }
  return sum;
}

void CpuStabilizer::outflow_pass(int stride) {
  // Inputs: the depth within `stride` columns. The tiles: those dirty for
  // this stride (a tile within reach changed since the tile's last outflow
  // of this stride moved nothing there, or it moved something).
  TileSet& dirty = dirty_[log2_of(stride)];
  const bool active = settings_.active_tiles;
  if (++pass_id_ == (1u << 31)) {  // the gates' pass numbers would overflow: start over
    gate_ = ZeroedArray<uint32_t>(cells_.size());
    std::fill(column_changed_.begin(), column_changed_.end(), 0u);
    pass_id_ = 1;
    gates_from_ = 1;
  }
  work_ = active ? dirty.list : surface_tiles_;
  const std::vector<int>& tiles = work_;
  tile_work_ += double(tiles.size());
  slot_max_.assign(tiles.size(), glm::vec3(0.0f));
  for_tiles(tiles, [&](int t, size_t slot) {
    const Tile b = tile(t);
    float largest = 0.0f, largest_void = 0.0f, largest_seen = 0.0f;
    for (int j = b.j0; j < b.j1; ++j) {
      for (int i = b.i0; i < b.i1; ++i) {
        const size_t c = size_t(j) * width_ + i;
        const int col_layers = column_layers_[c];
        float column_largest = 0.0f, column_seen = 0.0f;
        float out[8 * 64];
        uint8_t code[8 * 64];
        for (int l = 0; l < col_layers; ++l) {
          float to_void = 0.0f, hidden = 0.0f;
          const float sent = stride > 1 ? outflow_texel<true>(l, i, j, stride, &to_void,
                                                              &out[8 * l], &code[8 * l], &hidden)
                                        : outflow_texel<false>(l, i, j, 1, &to_void, &out[8 * l],
                                                               &code[8 * l], &hidden);
          column_largest = std::max(column_largest, sent);
          column_seen = std::max(column_seen, sent - hidden);
          largest_void = std::max(largest_void, to_void);
        }
        // Only the amounts of a column that sends snow are read (by the
        // gathers), so only those are stored: most columns rest.
        column_sent_[c] = column_largest > 0.0f;
        if (column_sent_[c]) {
          for (int l = 0; l < col_layers; ++l) {
            const size_t k = index(l, i, j);
            std::memcpy(&amount_[8 * k], &out[8 * l], 8 * sizeof(float));
            std::memcpy(&code_[8 * k], &code[8 * l], 8);
          }
        }
        largest = std::max(largest, column_largest);
        largest_seen = std::max(largest_seen, column_seen);
      }
    }
    slot_max_[slot] = glm::vec3(largest, largest_void, largest_seen);
  });
  residual_ = 0.0f;
  residual_void_ = 0.0f;
  residual_seen_ = 0.0f;
  sent_.clear();
  if (active) dirty.list.clear();
  for (size_t slot = 0; slot < tiles.size(); ++slot) {
    const int t = tiles[slot];
    residual_ = std::max(residual_, slot_max_[slot].x);
    residual_void_ = std::max(residual_void_, slot_max_[slot].y);
    residual_seen_ = std::max(residual_seen_, slot_max_[slot].z);
    if (slot_max_[slot].x > 0.0f) {
      sent_.add(t);
      if (active) dirty.list.push_back(t);  // it moves snow: computed again next time
    } else if (active) {
      dirty.in[size_t(t)] = 0;
    }
  }
}

// Mirrors shaders/stabilize_gather.frag, which also works per column: each
// neighbour column's landing codes are read once for all layers, and every
// layer texel adds what it receives in the same order as one at a time.
// Columns that sent nothing are skipped: their amounts are all zero, and
// subtracting or adding zeros changes no depth.
bool CpuStabilizer::gather_column(int i, int j, int stride) {
  const size_t c = size_t(j) * width_ + i;
  const int col_layers = column_layers_[c];
  float s[64];
  bool changed = false;
  for (int l = 0; l < col_layers; ++l) s[l] = depth_[index(l, i, j)];
  if (column_sent_[c]) {
    for (int l = 0; l < col_layers; ++l) {
      const size_t k = index(l, i, j);
      // The lost snow is read and written only where some went into the
      // void: a page of these arrays that is read first maps the zero page,
      // and writing it afterwards copies it and flushes the other cores'
      // TLBs (add_snow).
      bool to_void = false;
      for (int n = 0; n < 8; ++n) to_void |= code_[8 * k + n] == kCodeVoid;
      float lost = to_void ? lost_[k] : 0.0f;
      for (int n = 0; n < 8; ++n) {
        const float a = amount_[8 * k + n];
        s[l] -= a;
        if (code_[8 * k + n] == kCodeVoid) lost += a;
      }
      if (to_void) lost_[k] = lost;
    }
  }
  for (int n = 0; n < 8; ++n) {
    const int mi = i - stride * kDirI[n], mj = j - stride * kDirJ[n];
    if (mi < 0 || mj < 0 || mi >= width_ || mj >= height_) continue;
    const size_t cm = size_t(mj) * width_ + mi;
    if (!column_sent_[cm]) continue;
    const int source_layers = column_layers_[cm];
    for (int lm = 0; lm < source_layers; ++lm) {
      const size_t km = index(lm, mi, mj);
      const uint8_t code = code_[8 * km + n];
      if (code < col_layers) s[code] += amount_[8 * km + n];
    }
  }
  for (int l = 0; l < col_layers; ++l) {
    float& d = depth_[index(l, i, j)];
    if (s[l] != d) {  // (written only where it changes, as the lost snow)
      d = s[l];
      changed = true;
    }
  }
  if (changed) column_changed_[c] = pass_id_;
  return changed;
}

void CpuStabilizer::gather_pass(int stride) {
  // Inputs: the amounts within `stride` columns (the depth read is the
  // texel's own, so the pass works in place): the tiles near one that sent.
  const bool active = settings_.active_tiles;
  if (active) {
    for (int t : sent_.list) add_near(near_, t, reach(stride));
  }
  const std::vector<int>& tiles = active ? near_.list : surface_tiles_;
  for_tiles(tiles, [&](int t, size_t) {
    const Tile b = tile(t);
    Tile box{b.i1, b.j1, b.i0 - 1, b.j0 - 1};  // the columns whose depth changed (inclusive)
    for (int j = b.j0; j < b.j1; ++j) {
      for (int i = b.i0; i < b.i1; ++i) {
        if (!gather_column(i, j, stride)) continue;
        box = {std::min(box.i0, i), std::min(box.j0, j), std::max(box.i1, i), std::max(box.j1, j)};
      }
    }
    changed_box_[size_t(t)] = box;
  });
  // The tiles whose outflow of each stride reads a changed column are dirty.
  if (active) {
    for (int t : tiles) {
      const Tile& box = changed_box_[size_t(t)];
      if (box.i0 <= box.i1) touch(t, box);
    }
    near_.clear();
  }
}

// Mirrors shaders/stabilize_erode.frag: H = max(ground, min(H, min over
// neighbours of H(landing) + distance * tan(repose))).
float CpuStabilizer::erode_texel(int l, int i, int j) const {
  const size_t k = index(l, i, j);
  const glm::vec4 cell = cells_[k];
  float hs = stable_[k];
  // What cohesion holds is kept whatever the neighbours keep.
  const float floor = cell.x + held_snow(cell, depth_[k], held_cap_[k]);
  if (hs > floor) {
    const float he = free_top(cell, depth_[k]);
    for (int n = 0; n < 8; ++n) {
      const int ni = i + kDirI[n], nj = j + kDirJ[n];
      const int land_l = land(ni, nj, he, cell.x, rise_, true);
      if (land_l == kLandVoid) {
        hs = floor;
      } else if (land_l >= 0) {
        hs = std::min(hs, stable_[index(land_l, ni, nj)] + distance_[n] * cell.z);
      }
    }
    hs = std::max(hs, floor);
  }
  return hs;
}

// The erosion's kept heights are the greatest fixed point of erode_texel
// below the free tops. erode_texel is monotone: it never raises a texel, and
// lower neighbours never raise it (one that falls under the texel's snow top
// is landed on, one more term of the minimum), with float sums that are
// monotone too. So any order of in-place updates ends at the same fixed
// point, bit for bit, as the GPU's passes, which compute every texel from the
// pass before until none changes. Here the tiles are updated in place in four
// colours (a tile's colour is the parity of its column and row of tiles), and
// a tile reads only its own columns and the next column around it, which
// belong to tiles of other colours: the tiles of one colour run in parallel
// with the same result as one after another. Each tile is swept until it is
// stable, so a change crosses several tiles in one round, where a GPU pass
// moves it one texel: far fewer rounds than the GPU's passes.
// A tile is computed again only when a neighbour tile changed since (with
// active tiles off: every tile every round).
bool CpuStabilizer::erode_tile(int t) {
  const Tile b = tile(t);
  bool changed = false;
  for (int sweep = 0;; ++sweep) {
    bool any = false;
    const bool forward = sweep % 2 == 0;
    for (int jj = b.j0; jj < b.j1; ++jj) {
      const int j = forward ? jj : b.j1 - 1 - (jj - b.j0);
      for (int ii = b.i0; ii < b.i1; ++ii) {
        const int i = forward ? ii : b.i1 - 1 - (ii - b.i0);
        const int col_layers = column_layers_[size_t(j) * width_ + i];
        for (int l = 0; l < col_layers; ++l) {
          const size_t k = index(l, i, j);
          const float v = erode_texel(l, i, j);
          if (v != stable_[k]) {
            stable_[k] = v;
            any = true;
          }
        }
      }
    }
    if (!any) return changed;
    changed = true;
  }
}

float CpuStabilizer::start_height(size_t k, bool repose_only) const {
  const glm::vec4 cell = cells_[k];
  const float top = free_top(cell, depth_[k]);
  return repose_only ? top : std::min(top, cell.x + hold_[k]);
}

int CpuStabilizer::erode(bool repose_only) {
  // The highest snow surface each texel can keep, from H = min(ground +
  // depth, ceiling). Only layer texels with a surface are set: free_top is 0
  // on the others.
  stable_ = ZeroedArray<float>(cells_.size());
  for_tiles(surface_tiles_, [&](int t, size_t) {
    const Tile b = tile(t);
    for (int j = b.j0; j < b.j1; ++j) {
      for (int i = b.i0; i < b.i1; ++i) {
        const int col_layers = column_layers_[size_t(j) * width_ + i];
        for (int l = 0; l < col_layers; ++l) {
          const size_t k = index(l, i, j);
          stable_[k] = start_height(k, repose_only);
        }
      }
    }
  });
  const bool active = settings_.active_tiles;
  TileSet& pending = near_;  // the tiles to compute (a neighbour changed since their last sweep)
  pending.clear();
  for (int t : surface_tiles_) pending.add(t);
  std::vector<int> colour_tiles;
  int rounds = 0;
  while (!pending.list.empty()) {
    bool round_changed = false;
    for (int colour = 0; colour < 4; ++colour) {
      colour_tiles.clear();
      size_t kept = 0;
      for (int t : pending.list) {
        if ((t % tiles_x_) % 2 + 2 * ((t / tiles_x_) % 2) == colour) {
          colour_tiles.push_back(t);
          pending.in[size_t(t)] = 0;
        } else {
          pending.list[kept++] = t;
        }
      }
      pending.list.resize(kept);
      for_tiles(colour_tiles, [&](int t, size_t) { changed_[size_t(t)] = erode_tile(t); });
      for (int t : colour_tiles) {
        if (!changed_[size_t(t)]) continue;
        round_changed = true;
        if (!active) continue;
        add_near(pending, t, 1, false);  // t itself is stable
      }
    }
    if (!round_changed) break;
    ++rounds;
    if (!active) {
      for (int t : surface_tiles_) pending.add(t);
    }
  }
  pending.clear();
  return rounds;
}

int CpuStabilizer::route(double* routed_volume, Routing kind) {
  const size_t count = cells_.size();
  const bool drain = kind == Routing::Drain;
  const int passes = erode(kind != Routing::Settle);
  const float min_excess = routed_excess_of(settings_, kind);
  if (drain) {
    // The excess fills and spills down its paths (snow/deposit.h); the
    // tiles it changed are computed again, and the gates around them read
    // again.
    for (const uint32_t k :
         spill_excess(cells_.data(), stable_.data(), depth_.data(), lost_.data(),
                      DepositGrid{width_, height_, layers_, texel_}, min_excess)) {
      const size_t column = k % (size_t(width_) * size_t(height_));
      column_changed_[column] = pass_id_;
      const int i = int(column % size_t(width_)), j = int(column / size_t(width_));
      touch((j / kTile) * tiles_x_ + i / kTile);
    }
    stable_ = ZeroedArray<float>();
    return passes;
  }
  // Receiver pass (shaders/stabilize_receiver.frag): a texel holding more
  // than it can keep sends the excess towards the neighbour that limits it
  // (the void when one neighbour is the void); H falls strictly along these
  // pointers, so they form a forest whose roots (terminals) point to
  // themselves. The routed texels are listed in texel order. Only texels
  // with a surface get a pointer, and only they are pointed at.
  const std::unique_ptr<uint32_t[]> pointer(new uint32_t[count]);
  std::vector<std::vector<uint32_t>> routed_rows(size_t(layers_) * size_t(height_));
  parallel_for(
      routed_rows.size(),
      [&](size_t row) {
        const int l = int(row / size_t(height_)), j = int(row % size_t(height_));
        for (int i = 0; i < width_; ++i) {
          if (column_layers_[size_t(j) * width_ + i] <= l) continue;
          const size_t k = index(l, i, j);
          const glm::vec4 cell = cells_[k];
          uint32_t p = uint32_t(k);
          const float hs = stable_[k];
          if (cell.x + depth_[k] > hs + min_excess) {
            const float he = free_top(cell, depth_[k]);
            float best = hs;
            for (int n = 0; n < 8; ++n) {
              const int ni = i + kDirI[n], nj = j + kDirJ[n];
              const int land_l = land(ni, nj, he, cell.x, rise_, true);
              if (land_l == kLandVoid) {
                p = kPointerVoid;
                break;
              }
              if (land_l < 0) continue;
              const size_t kt = index(land_l, ni, nj);
              const float via = stable_[kt] + distance_[n] * cell.z;
              if (stable_[kt] < hs && (p == uint32_t(k) || via < best)) {
                best = via;
                p = uint32_t(kt);
              }
            }
            if (p != uint32_t(k) && p != kPointerVoid) {
              // A receiver that sheds into the void (a neighbour lands in
              // it at the receiver's free top) keeps nothing that arrives:
              // the next pass sends it all off the edge. So the path ends
              // in the void here (snow creeping off tile edges then settles
              // in far fewer passes).
              const size_t col = p % (size_t(width_) * size_t(height_));
              const int pi = int(col % size_t(width_)), pj = int(col / size_t(width_));
              const glm::vec4 pc = cells_[p];
              const float phe = free_top(pc, depth_[p]);
              for (int n = 0; n < 8; ++n) {
                if (land(pi + kDirI[n], pj + kDirJ[n], phe, pc.x, rise_, true) == kLandVoid) {
                  p = kPointerVoid;
                  break;
                }
              }
            }
          }
          pointer[k] = p;
          if (p != uint32_t(k)) routed_rows[row].push_back(uint32_t(k));
        }
      },
      threads_);
  std::vector<uint32_t> routed;
  for (const auto& row : routed_rows) routed.insert(routed.end(), row.begin(), row.end());
  routed_rows = {};
  // Jump passes (shaders/stabilize_jump.frag) until every pointer reaches a
  // terminal (the GPU runs one more, which moves no pointer on and does not
  // count). Only routed texels point elsewhere than at themselves.
  auto unfinished = [&]() {
    for (uint32_t k : routed) {
      const uint32_t p = pointer[k];
      if (p != kPointerVoid && pointer[p] != p) return true;
    }
    return false;
  };
  int jumps = 0;
  std::vector<uint32_t> jumped(routed.size());
  while (unfinished()) {
    for (size_t r = 0; r < routed.size(); ++r) {
      const uint32_t p = pointer[routed[r]];
      jumped[r] = p == kPointerVoid ? p : pointer[p];
    }
    for (size_t r = 0; r < routed.size(); ++r) pointer[routed[r]] = jumped[r];
    ++jumps;
  }
  // A routed texel's excess: its snow top over its kept height, never more
  // than its snow. Far from the origin the top rounds: at a ground of 6.7e6 m
  // (floats 0.5 m apart) 0.3 m of snow tops out 0.5 m up, and the whole top
  // routed left -0.2 m behind (found by tools/fuzz).
  const auto excess = [&](uint32_t k) {
    return std::min((cells_[k].x + depth_[k]) - stable_[k], depth_[k]);
  };
  // Scatter (shaders/stabilize_scatter.*: one point per routed texel, added
  // in texel order into its terminal) and apply (stabilize_apply.frag).
  // Terminals are never routed, so the excess is read before any change.
  ZeroedArray<float> arrive(count);
  std::vector<uint32_t> terminals;
  double moved_volume = 0.0;
  for (uint32_t k : routed) {
    const float e = excess(k);
    const uint32_t p = pointer[k];
    if (p != kPointerVoid) {
      if (arrive[p] == 0.0f) terminals.push_back(p);
      arrive[p] += e;
    }
  }
  for (uint32_t k : routed) {
    const float e = excess(k);
    moved_volume += double(e);
    if (pointer[k] == kPointerVoid) lost_[k] = lost_[k] + e;
    depth_[k] = (depth_[k] - e) + arrive[k];
  }
  if (settings_.deposit_piles) {  // as piles around the terminals (snow/deposit.h)
    deposit_piles(cells_.data(), depth_.data(), arrive.data(), std::move(terminals),
                  DepositGrid{width_, height_, layers_, texel_});
  } else {
    for (uint32_t p : terminals) depth_[p] = depth_[p] + arrive[p];
  }
  *routed_volume += moved_volume * double(texel_) * double(texel_);
  stable_ = ZeroedArray<float>();
  route_pending_ = false;
  touch_all();
  return passes + jumps;
}

void CpuStabilizer::route_into(Routing kind, StabilizeResult& result) {
  const auto t0 = std::chrono::steady_clock::now();
  result.route_passes += route(&result.routed_volume, kind);
  result.route_seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

StabilizeResult CpuStabilizer::iterate(int passes) {
  StabilizeResult result;
  const double lost_before = volume_sums_ ? lost_volume() : 0.0;
  if (route_pending_) {
    if (settings_.route_steep) route_into(Routing::Settle, result);
    route_pending_ = false;
  }
  tile_work_ = 0.0;
  int last_check = 0;
  for (int pass = 1; pass <= passes; ++pass) {
    const int stride = schedule_.next();
    outflow_pass(stride);
    gather_pass(stride);
    ++result.iterations;
    if ((stride == 1 && pass - last_check >= settings_.check_every) || pass == passes) {
      last_check = pass;
      result.residual = residual_seen_;
      schedule_.checked(stride, residual_);
      // A strided pass's largest move says nothing of single steps (its
      // paths may be blocked where single steps still move snow).
      if (stride == 1 && residual_seen_ < settings_.tolerance) {
        result.converged = true;
        break;
      }
      run_check_routings(
          settings_, schedule_, false, residual_, residual_void_, result,
          [&] { route_into(Routing::Creep, result); },
          [&] {
            if (pour_pressed() == 0) return false;
            touch_all();
            return true;
          },
          [&] { result.route_passes += route(nullptr, Routing::Drain); });
    }
  }
  if (settings_.count_tiles && result.iterations > 0 && !surface_tiles_.empty()) {
    result.tile_share = tile_work_ / (double(result.iterations) * double(surface_tiles_.size()));
  }
  if (volume_sums_) {
    result.lost_volume = lost_volume() - lost_before;
    result.volume = snow_volume();
  }
  return result;
}

size_t CpuStabilizer::pour_pressed() {
  if (under_start_.empty()) {
    // The layer texels with a surface under a ceiling, by tile (texel order
    // within each): counted, then listed, on all cores.
    const size_t tiles = size_t(tiles_x_) * size_t(tiles_y_);
    under_start_.assign(tiles + 1, 0);
    const auto each_under = [&](int t, auto fn) {
      const Tile b = tile(t);
      for (int l = 0; l < layers_; ++l) {
        for (int j = b.j0; j < b.j1; ++j) {
          for (int i = b.i0; i < b.i1; ++i) {
            if (l >= column_layers_[size_t(j) * size_t(width_) + size_t(i)]) continue;
            const size_t k = index(l, i, j);
            if (cells_[k].y < kCellOpenSky) fn(uint32_t(k));
          }
        }
      }
    };
    for_tiles(surface_tiles_, [&](int t, size_t) {
      uint32_t count = 0;
      each_under(t, [&](uint32_t) { ++count; });
      under_start_[size_t(t) + 1] = count;
    });
    for (size_t t = 0; t < tiles; ++t) under_start_[t + 1] += under_start_[t];
    under_ceilings_.resize(under_start_[tiles]);
    for_tiles(surface_tiles_, [&](int t, size_t) {
      uint32_t at = under_start_[size_t(t)];
      each_under(t, [&](uint32_t k) { under_ceilings_[at++] = k; });
    });
  }
  // Only the texels of tiles whose depth changed since the last look can
  // have come to lie above their ceilings: the others were looked at then
  // (and poured where they were), and are as they were.
  std::vector<uint32_t> candidates;
  for (int t : pressed_stale_.list) {
    candidates.insert(candidates.end(), under_ceilings_.begin() + under_start_[size_t(t)],
                      under_ceilings_.begin() + under_start_[size_t(t) + 1]);
  }
  pressed_stale_.clear();
  if (candidates.empty()) return 0;
  return pour_pressed_snow(cells_.data(), depth_.data(),
                           DepositGrid{width_, height_, layers_, texel_}, settings_.tolerance,
                           candidates);
}

double CpuStabilizer::snow_volume() const {
  const double sum = parallel_sum(depth_.size(), kSumChunk, [&](size_t begin, size_t end) {
    double part = 0.0;
    for (size_t k = begin; k < end; ++k) {
      if (cell_flags(cells_[k]) & kCellSurface) part += double(depth_[k]);
    }
    return part;
  });
  return sum * double(texel_) * double(texel_);
}

StabilizeResult stabilize_cpu(const SnowMaps& maps, std::vector<float>& depth,
                              const StabilizeSettings& settings, int max_iterations_override) {
  CpuStabilizer stabilizer(maps, settings);
  stabilizer.set_depth(depth);
  StabilizeResult result = stabilizer.iterate(
      max_iterations_override >= 0 ? max_iterations_override : settings.max_iterations);
  depth = stabilizer.depth();
  for (float& d : depth) d = std::max(d, 0.0f);
  return result;
}

}  // namespace snow
