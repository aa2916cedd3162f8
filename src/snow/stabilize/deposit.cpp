#include "snow/deposit.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <numeric>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "core/zeroed.h"
#include "snow/column.h"
#include "snow/stabilize.h"
#include "snow/stabilize/pour_units.h"
#include "snow/stabilize_cpu.h"

namespace snow {
namespace {

/// A pile covers this many texels at most; what it would spread beyond
/// stays on the texels it covers (the relaxation takes it on from there).
constexpr size_t kMaxPileTexels = size_t(1) << 20;
/// All the piles of one call cover at most this many times the maps' layer
/// texels (counting each growth); the terminals after that keep their snow
/// as before, for the relaxation to spread. Covering a texel (a heap's
/// push and pop) costs far more than a pass over it: this keeps the piles
/// within about what the passes they save cost, where snow lies thousands
/// of texels deep (tools/RESULTS.md, the depth in texels).
constexpr size_t kPouredPerLayerTexel = 2;

/// A min-heap of T in a 4-ary tree (half a binary heap's depth; a pop
/// compares four children a level, in one cache line), its storage kept
/// between piles. Its top is always the least element, so the piles take
/// texels in the same order as with std::priority_queue.
template <class T>
class MinHeap {
 public:
  bool empty() const { return a_.empty(); }
  const T& top() const { return a_.front(); }
  void clear() { a_.clear(); }
  void push(T v) {
    size_t i = a_.size();
    a_.push_back(v);
    while (i > 0) {
      const size_t parent = (i - 1) / 4;
      if (!(v < a_[parent])) break;
      a_[i] = a_[parent];
      i = parent;
    }
    a_[i] = v;
  }
  void pop() {
    const T v = a_.back();
    a_.pop_back();
    const size_t n = a_.size();
    if (n == 0) return;
    size_t i = 0;
    for (;;) {
      const size_t first = 4 * i + 1;
      if (first >= n) break;
      const size_t end = std::min(first + 4, n);
      // The least child, chosen without branching on the comparisons: they
      // are unpredictable, and mispredicting them was most of a pop's time.
      size_t least = first;
      T least_value = a_[first];
      for (size_t c = first + 1; c < end; ++c) {
        const bool less = a_[c] < least_value;
        least = less ? c : least;
        least_value = less ? a_[c] : least_value;
      }
      if (!(least_value < v)) break;
      a_[i] = least_value;
      i = least;
    }
    a_[i] = v;
  }

 private:
  std::vector<T> a_;
};

/// Maps of at least kBandedRows rows pour their terminals by bands of rows,
/// kPourBands of them (deposit_piles): the even bands first, then the odd
/// ones, the bands of each phase on all cores. Two bands of a phase lie a
/// band apart, an eighth of the map, more than the piles of the measured
/// scenes span (narrower bands met; tools/RESULTS.md). Smaller maps pour in
/// texel order, as a pile there can span most of the rows.
constexpr uint32_t kBandedRows = 512;
constexpr uint32_t kPourBands = 8;

/// Which band of a phase of deposit_piles holds each column: a band reads
/// and writes the depth only of the columns it holds, so bands poured on
/// different threads never touch the same texel. A column that no band of
/// the phase holds yet goes to the first band that needs it; one that
/// another band holds aborts the phase.
class PhaseClaims {
 public:
  explicit PhaseClaims(size_t columns) : owner_(columns) {}
  /// Starts a phase of `bands` bands; returns the id of its first band (the
  /// others follow it).
  uint32_t start(size_t bands) {
    first_ = next_;
    next_ += uint32_t(bands);
    abort_.store(false, std::memory_order_relaxed);
    return first_;
  }
  /// Whether band `id` holds column c (taking it if free).
  bool claim(size_t c, uint32_t id) {
    uint32_t* slot = owner_.data() + c;
    uint32_t held = __atomic_load_n(slot, __ATOMIC_RELAXED);
    while (held != id) {
      if (held >= first_) {  // another band of this phase
        abort_.store(true, std::memory_order_relaxed);
        return false;
      }
      if (__atomic_compare_exchange_n(slot, &held, id, false, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
        return true;
      }
    }
    return true;
  }
  bool aborted() const { return abort_.load(std::memory_order_relaxed); }

 private:
  // Per column: the id of the band that last held it, 0 for none (ids of
  // earlier phases are below first_). ZeroedArray, so only the columns
  // poured on are ever written; hence the GCC atomics on plain integers.
  ZeroedArray<uint32_t> owner_;
  uint32_t first_ = 1, next_ = 1;
  std::atomic<bool> abort_{false};
};

class Pourer {
 public:
  Pourer(const glm::vec4* cells, float* depth, const DepositGrid& grid)
      : cells_(cells),
        depth_(depth),
        g_(grid),
        per_layer_(size_t(grid.width) * size_t(grid.height)),
        rise_(kSurfaceContinuityTexels * grid.texel),
        seen_(per_layer_ * size_t(grid.layers)),
        dist_(per_layer_ * size_t(grid.layers)),
        void_pour_(per_layer_),
        void_under_(per_layer_) {
    for (int n = 0; n < 8; ++n)
      step_[n] = n < 4 ? grid.texel : float(double(grid.texel) * std::sqrt(2.0));
  }

  void pour(uint32_t p, float volume);
  /// Pours the snow of `count` terminals (arrive[t] each) as one pile: the
  /// upper envelope of a cone at each terminal, apex `apex[t]` (m) raised
  /// by a common height until the pile holds their volumes together. What
  /// does not fit goes back to the terminals, each its share; a terminal
  /// that sheds keeps its own snow, as in pour().
  void pour_group(const uint32_t* terminals, const float* apex, size_t count, const float* arrive);
  /// Texels covered by all growths so far.
  size_t covered() const { return covered_total_; }

  /// Pours from here on as band `id` of a parallel phase (PhaseClaims):
  /// every column whose depth it reads or writes is claimed for that band
  /// first, and each write's old value goes to `undo`. Where a column is
  /// another band's, the phase is aborted and this pour writes nothing.
  /// With claims null: pours on its own (the serial order).
  void pour_as(PhaseClaims* claims, uint32_t id, std::vector<std::pair<uint32_t, float>>* undo) {
    claims_ = claims;
    claim_id_ = id;
    undo_ = undo;
  }

 private:
  /// A terminal a growth starts from, and its path cost there (m): how far
  /// its apex lies under the pile's highest.
  struct Seed {
    uint32_t k;
    float offset;
    float volume;  // metres of depth it brings
  };
  /// Grows the pile of `volume` from seeds_ (distinct texels) into covered_
  /// (texel, path cost), spreading from a covered texel at the larger of its
  /// snow top and apex - its path cost; returns the height of the pile's
  /// apex (that of a seed of offset 0).
  double grow(double volume, double apex);
  /// Pours the pile of `volume` from seeds_ and lays it over covered_ (each
  /// texel up to the apex - its path cost, capped); `anchor`, a seed of
  /// offset 0, takes what the others do not, so the volume is exact. Sums in
  /// Sum: a single pile in float, as it always has; a group in double, as its
  /// volume sums many terminals'.
  template <class Sum>
  void pour_seeds(uint32_t anchor, Sum volume);
  /// Whether growing again at the cone of apex `apex` would repeat the last
  /// growth, which spread at the snow tops: at every texel it covered, the
  /// cone's surface lies in the same gap of each neighbour column as the
  /// snow top. Then the second growth finds the same neighbours, so it takes
  /// the same texels in the same order at the same path costs and ends at
  /// the same apex. So it is skipped (for most piles of the measured
  /// scenes).
  bool grows_alike(double apex) const;

  // Column (i, j) with the snow tops top(k).
  auto column(int i, int j) const {
    const auto top_of = [this](size_t k) { return top(k); };
    return CellColumn<decltype(top_of)>{cells_, per_layer_,
                                        size_t(j) * size_t(g_.width) + size_t(i), top_of};
  }
  size_t index(int l, int i, int j) const {
    return size_t(l) * per_layer_ + size_t(j) * size_t(g_.width) + size_t(i);
  }
  bool on_map(int i, int j) const { return i >= 0 && j >= 0 && i < g_.width && j < g_.height; }
  // The snow top of layer texel k; in a parallel phase, 0 where its column
  // is another band's (the phase is then aborted).
  float top(size_t k) const {
    if (claims_ && !claims_->claim(column_of(k), claim_id_)) return 0.0f;
    return cells_[k].x + depth_[k];
  }
  bool aborted() const { return claims_ && claims_->aborted(); }
  // k % per_layer_, without a division (maps have few layers).
  size_t column_of(size_t k) const {
    while (k >= per_layer_) k -= per_layer_;
    return k;
  }
  // depth_[k] += add (rounded as before), its old value kept for an undo.
  void add_depth(size_t k, float add) {
    if (undo_) undo_->emplace_back(uint32_t(k), depth_[k]);
    depth_[k] = depth_[k] + add;
  }
  // The height a growth spreads from at covered texel k (path cost dist): the
  // cone's surface at apex `apex`, capped, never under the snow top (the
  // snow top itself in a first growth, apex -kOpenSky).
  float spread_height(size_t k, float dist, double apex) const {
    return float(std::max(double(top(k)), std::min(apex - double(dist), cap(k))));
  }
  // The highest snow top texel k can hold (kCeilingClearance under its
  // ceiling; infinite under the open sky).
  double cap(size_t k) const {
    return cells_[k].y < kCellOpenSky ? double(cells_[k].y) - double(kCeilingClearance)
                                      : std::numeric_limits<double>::infinity();
  }
  // Snow on layer texel k of column (i, j) would slide off into the void:
  // land_in_column gives kLandVoid in a neighbour column.
  bool sheds(size_t k, int i, int j) {
    const float h = top(k);
    for (int n = 0; n < 8; ++n) {
      const int ni = i + kDirI[n], nj = j + kDirJ[n];
      if (!on_map(ni, nj) || h < void_under(ni, nj)) return true;
    }
    return false;
  }
  bool sheds(size_t k) {
    const size_t c = column_of(k);
    return sheds(k, int(c % size_t(g_.width)), int(c / size_t(g_.width)));
  }
  // The heights h at which land_in_column gives kLandVoid in column (i, j)
  // are those under this one: it walks past every layer (h under its ground,
  // its snow top and its ceiling) to an end that is no wall (an empty
  // column, or a lowest surface facing down, with fewer than L layers).
  // The support and rise only decide between a landing and a wall. Kept
  // per column for one pour, in which no depth changes.
  float void_under(int i, int j) {
    const size_t c = size_t(j) * size_t(g_.width) + size_t(i);
    if (void_pour_[c] == pours_) return void_under_[c];
    const auto col = column(i, j);
    int count = 0;
    float under = std::numeric_limits<float>::infinity();
    for (; count < g_.layers && col.has(count); ++count) {
      under = std::min({under, col.ground(count), col.top(count), col.ceiling(count)});
    }
    if (count == g_.layers || (count > 0 && !col.faces_down(count - 1))) {
      under = -std::numeric_limits<float>::infinity();
    }
    void_pour_[c] = pours_;
    void_under_[c] = under;
    return under;
  }
  // The layer of column (i, j) whose gap contains h, or -1 (none, or the
  // inside of a solid): where a pile rising at h spreads to.
  int gap_at(int i, int j, float h) const {
    if (!on_map(i, j)) return -1;
    const auto col = column(i, j);
    for (int l = 0; l < g_.layers && col.has(l); ++l) {
      if (h >= col.ceiling(l)) return -1;
      if (h >= col.ground(l)) return col.solid(l) ? -1 : l;
    }
    return -1;
  }

  const glm::vec4* cells_;
  float* depth_;
  DepositGrid g_;
  size_t per_layer_;
  float rise_;
  float step_[8] = {};
  // Per layer texel: 2 * g for growth g (counted from 1) that last reached
  // it, 2 * g + 1 once that growth took it from the frontier; and its path
  // cost there (m).
  ZeroedArray<uint32_t> seen_;
  ZeroedArray<float> dist_;
  uint32_t growths_ = 0;
  uint32_t pours_ = 0;               // pours so far (counted from 1)
  ZeroedArray<uint32_t> void_pour_;  // per column: the pour void_under_ was found in
  ZeroedArray<float> void_under_;    // per column: void_under() in that pour
  size_t covered_total_ = 0;
  std::vector<std::pair<uint32_t, float>> covered_;  // texel, path cost
  std::vector<Seed> seeds_;                          // of the pile being poured
  // grow()'s frontier (entries: key bits << 32 | texel) and saturations
  // (apex height, texel), kept between piles.
  MinHeap<uint64_t> frontier_;
  MinHeap<std::pair<double, uint32_t>> saturations_;
  PhaseClaims* claims_ = nullptr;
  uint32_t claim_id_ = 0;
  std::vector<std::pair<uint32_t, float>>* undo_ = nullptr;
};

void Pourer::pour(uint32_t p, float volume) {
  ++pours_;
  if (sheds(p)) {  // as before: on the terminal
    if (!aborted()) add_depth(p, volume);
    return;
  }
  seeds_.assign(1, Seed{p, 0.0f, volume});
  pour_seeds(p, volume);
}

void Pourer::pour_group(const uint32_t* terminals, const float* apex, size_t count,
                        const float* arrive) {
  ++pours_;
  seeds_.clear();
  double volume = 0.0;
  float highest = -std::numeric_limits<float>::infinity();
  uint32_t anchor = 0;
  for (size_t t = 0; t < count; ++t) {
    const uint32_t p = terminals[t];
    if (sheds(p)) {
      if (!aborted()) add_depth(p, arrive[p]);
      continue;
    }
    volume += double(arrive[p]);
    seeds_.push_back(Seed{p, apex[t], arrive[p]});
    if (apex[t] > highest) {
      highest = apex[t];
      anchor = p;
    }
  }
  if (seeds_.empty() || aborted()) return;
  for (Seed& seed : seeds_) seed.offset = highest - seed.offset;
  pour_seeds(anchor, volume);
}

template <class Sum>
void Pourer::pour_seeds(uint32_t anchor, Sum volume) {
  // The pile spreads over the gaps its surface lies in, which depends on its
  // height: grown once at the snow tops as they are, then again at the
  // heights the first growth found.
  const double first = grow(double(volume), -kOpenSky);
  const double cone = grows_alike(first) ? first : grow(double(volume), first);
  if (aborted()) return;
  Sum placed = 0;
  for (const auto& [k, dist] : covered_) {
    if (k == anchor) continue;
    const float add = float(std::min(cone - double(dist), cap(k))) - top(k);
    if (add > 0.0f && placed + Sum(add) <= volume) {
      add_depth(k, add);
      placed += Sum(add);
    }
  }
  Sum left = volume - placed;
  if (seeds_.size() > 1 && std::isinf(cone)) {
    // No room in reach for all of it (every covered texel filled to its
    // ceiling): the anchor fills to its own, and what is left goes back to
    // the seeds, each its share of what it brought.
    const Sum own = std::min(left, Sum(std::max(cap(anchor) - double(top(anchor)), 0.0)));
    const double back = double(left - own) / double(volume);
    for (const Seed& seed : seeds_) {
      const float add = float(double(seed.volume) * back);
      if (seed.k == anchor || !(add > 0.0f) || Sum(add) > left - own) continue;
      add_depth(seed.k, add);
      left -= Sum(add);
    }
  }
  add_depth(anchor, float(left));
}

bool Pourer::grows_alike(double apex) const {
  for (const auto& [k, dist] : covered_) {
    // The heights grow() spreads from: the snow top in the first growth,
    // the cone's surface (capped, never under the top) in the second.
    const float at_top = top(k);
    const float at_cone = spread_height(k, dist, apex);
    if (at_cone == at_top) continue;
    const int i = int((k % per_layer_) % size_t(g_.width));
    const int j = int((k % per_layer_) / size_t(g_.width));
    for (int n = 0; n < 8; ++n) {
      const int ni = i + kDirI[n], nj = j + kDirJ[n];
      if (gap_at(ni, nj, at_top) != gap_at(ni, nj, at_cone)) return false;
    }
  }
  return true;
}

double Pourer::grow(double volume, double apex) {
  ++growths_;
  const uint32_t reached = 2 * growths_, done = 2 * growths_ + 1;
  // Frontier by the height at which the rising cone covers a texel: its
  // top plus its path cost; ties in texel order. An entry is that height's
  // bits, ordered as unsigned integers, over the texel: one integer compare
  // orders both. The path cost is dist_ when the texel is taken: later entries
  // of a texel come with a lower cost, so a lower height, and are taken
  // first (the others are then stale).
  MinHeap<uint64_t>& frontier = frontier_;
  frontier.clear();
  auto entry = [](float key, uint32_t k) {
    uint32_t bits;
    const float positive_zero = key + 0.0f;  // -0 as +0: equal keys, equal bits
    std::memcpy(&bits, &positive_zero, sizeof bits);
    bits = (bits & 0x80000000u) != 0 ? ~bits : bits | 0x80000000u;
    return uint64_t(bits) << 32 | k;
  };
  auto entry_key = [](uint64_t e) {
    uint32_t bits = uint32_t(e >> 32);
    bits = (bits & 0x80000000u) != 0 ? bits & 0x7fffffffu : ~bits;
    float key;
    std::memcpy(&key, &bits, sizeof key);
    return key;
  };
  for (const Seed& seed : seeds_) {
    frontier.push(entry(top(seed.k) + seed.offset, seed.k));
    seen_[seed.k] = reached;
    dist_[seed.k] = seed.offset;
  }
  covered_.clear();
  // A covered texel takes snow from the apex height at which the cone
  // reaches it (its key: top + path cost) up to the one at which the cone
  // reaches its ceiling (cap + path cost): the volume under an apex A is
  // active * A - keys + full, over the texels still filling (active, the
  // sum of their keys) and the full ones (full: what they hold).
  using Saturation = std::pair<double, uint32_t>;  // apex height, texel
  MinHeap<Saturation>& saturations = saturations_;
  saturations.clear();
  size_t active = 0;
  double keys = 0.0, full = 0.0;
  const double inf = std::numeric_limits<double>::infinity();
  double cone = inf;  // height of the cone's apex (m); infinite: every texel full
  for (;;) {
    const double next_key = frontier.empty() || covered_.size() >= kMaxPileTexels
                                ? inf
                                : double(entry_key(frontier.top()));
    const double next_full = saturations.empty() ? inf : saturations.top().first;
    const double next = std::min(next_key, next_full);
    // The cone at the height of the next event holds enough: it ends below.
    if (active > 0 && (next == inf || double(active) * next - keys + full >= double(volume))) {
      cone = (double(volume) - full + keys) / double(active);
      break;
    }
    if (next == inf) break;
    if (next_full <= next_key) {
      const uint32_t k = saturations.top().second;
      saturations.pop();
      --active;
      keys -= double(top(k)) + double(dist_[k]);
      full += cap(k) - double(top(k));
      continue;
    }
    const uint32_t k = uint32_t(frontier.top());
    frontier.pop();
    if (seen_[k] == done) continue;  // stale entry
    if (aborted()) break;
    seen_[k] = done;
    const float dist = dist_[k];
    const int i = int((k % per_layer_) % size_t(g_.width));
    const int j = int((k % per_layer_) / size_t(g_.width));
    if (sheds(k, i, j)) continue;  // (never a seed: pour() and pour_group() looked)
    covered_.emplace_back(k, dist);
    ++covered_total_;
    const double room = cap(k) - double(top(k));
    if (room > 0.0) {
      ++active;
      keys += double(top(k)) + double(dist);
      if (room < inf) saturations.push({cap(k) + double(dist), k});
    }
    const glm::vec4 cell = cells_[k];
    const float h = spread_height(k, dist, apex);
    for (int n = 0; n < 8; ++n) {
      const int ni = i + kDirI[n], nj = j + kDirJ[n];
      const int lb = gap_at(ni, nj, h);
      if (lb < 0) continue;
      const uint32_t b = uint32_t(index(lb, ni, nj));
      const float d = dist + step_[n] * cell.z;
      if (seen_[b] == done || (seen_[b] == reached && dist_[b] <= d)) continue;
      seen_[b] = reached;
      dist_[b] = d;
      frontier.push(entry(top(b) + d, b));
    }
  }
  return cone;
}

/// value(i) for each i in [0, count) where keep(i) holds, in order: chunks
/// of indices on all cores.
template <class Keep, class Value>
std::vector<uint32_t> select_in_order(size_t count, Keep keep, Value value) {
  constexpr size_t kChunk = size_t(1) << 14;
  std::vector<std::vector<uint32_t>> found((count + kChunk - 1) / kChunk);
  parallel_for_ranges(count, kChunk, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      if (keep(i)) found[begin / kChunk].push_back(value(i));
    }
  });
  std::vector<uint32_t> out;
  for (const std::vector<uint32_t>& f : found) out.insert(out.end(), f.begin(), f.end());
  return out;
}

/// The layer texels with a surface under a ceiling, in texel order: the only
/// ones pour_pressed_snow pours from.
std::vector<uint32_t> texels_under_ceilings(const glm::vec4* cells, const DepositGrid& grid) {
  const size_t count = size_t(grid.width) * size_t(grid.height) * size_t(grid.layers);
  return select_in_order(
      count,
      [&](size_t k) { return (int(cells[k].w) & kCellSurface) != 0 && cells[k].y < kCellOpenSky; },
      [](size_t k) { return uint32_t(k); });
}

}  // namespace

size_t deposit_piles(const glm::vec4* cells, float* depth, const float* arrive,
                     std::vector<uint32_t> terminals, const DepositGrid& grid, unsigned threads,
                     DepositStats* stats, PileGrouping grouping) {
  if (stats) *stats = DepositStats{};
  if (terminals.empty()) return 0;
  const size_t per_layer = size_t(grid.width) * size_t(grid.height);
  const size_t count = per_layer * size_t(grid.layers);
  const uint32_t height = uint32_t(grid.height);
  const uint32_t band_rows =
      height >= kBandedRows ? (height + kPourBands - 1) / kPourBands : std::max(height, 1u);
  const auto band_of = [&](uint32_t k) {
    return uint32_t((k % per_layer) / size_t(grid.width)) / band_rows;
  };
  // The order: the even bands' terminals, then the odd ones'; band by band,
  // and in texel order in a band (one band: texel order).
  {
    std::vector<uint64_t> keys(terminals.size());
    for (size_t t = 0; t < terminals.size(); ++t) {
      const uint64_t band = band_of(terminals[t]);
      keys[t] = (band & 1u) << 63 | band << 32 | terminals[t];
    }
    std::sort(keys.begin(), keys.end());
    for (size_t t = 0; t < keys.size(); ++t) terminals[t] = uint32_t(keys[t]);
  }
  const PourUnits units = plan_pour_units(cells, depth, arrive, terminals, grid, grouping);
  const auto first_of = [&](size_t u) { return units.terminals[units.begin[u]]; };
  const auto pour_unit = [&](Pourer& pourer, size_t u) {
    const size_t b = units.begin[u], n = units.begin[u + 1] - b;
    if (n == 1) {
      pourer.pour(units.terminals[b], arrive[units.terminals[b]]);
    } else {
      pourer.pour_group(&units.terminals[b], &units.apex[b], n, arrive);
    }
  };
  const size_t budget = kPouredPerLayerTexel * count;
  size_t covered = 0;  // texels covered by all growths so far
  Pourer serial(cells, depth, grid);
  const auto pour_serially = [&](size_t u0, size_t u1) {
    for (size_t u = u0; u < u1; ++u) {
      if (covered < budget) {
        const size_t before = serial.covered();
        pour_unit(serial, u);
        covered += serial.covered() - before;
      } else {
        for (size_t t = units.begin[u]; t < units.begin[u + 1]; ++t) {
          const uint32_t p = units.terminals[t];
          depth[p] = depth[p] + arrive[p];
        }
      }
    }
  };
  // A phase's bands on all cores, each band's piles in order on one thread.
  // Where two bands would touch the same column, or the piles would exceed
  // the budget, all their writes are undone and the phase is poured
  // serially: either way the result is that of the order above, on any
  // number of threads. (The claims cost a little per pile, which the
  // parallel pouring repays on large maps even on 2 cores.)
  const unsigned workers = threads > 0 ? threads : default_threads();
  std::unique_ptr<PhaseClaims> claims;
  std::vector<std::unique_ptr<Pourer>> pourers;
  const auto pour_in_parallel = [&](const std::vector<std::pair<size_t, size_t>>& bands) {
    const size_t n = std::min<size_t>(workers, bands.size());
    std::vector<std::vector<std::pair<uint32_t, float>>> undo(bands.size());
    std::vector<size_t> band_covered(bands.size(), 0);
    bool poured_all = false;
    try {
      if (!claims) claims = std::make_unique<PhaseClaims>(per_layer);
      while (pourers.size() < n) pourers.push_back(std::make_unique<Pourer>(cells, depth, grid));
      const uint32_t first_id = claims->start(bands.size());
      std::atomic<size_t> next{0};
      parallel_for(
          n,
          [&](size_t w) {
            Pourer& pourer = *pourers[w];
            for (size_t b = next++; b < bands.size() && !claims->aborted(); b = next++) {
              pourer.pour_as(claims.get(), first_id + uint32_t(b), &undo[b]);
              const size_t before = pourer.covered();
              for (size_t u = bands[b].first; u < bands[b].second && !claims->aborted(); ++u) {
                pour_unit(pourer, u);
              }
              band_covered[b] = pourer.covered() - before;
            }
            pourer.pour_as(nullptr, 0, nullptr);
          },
          unsigned(n));
      poured_all = !claims->aborted();
    } catch (const std::bad_alloc&) {
      // No memory for the pourers' marks or the undo logs: serially. (Each
      // write is logged before it is made, so the logs hold all of them.)
      pourers.clear();
    }
    const size_t poured = std::accumulate(band_covered.begin(), band_covered.end(), size_t(0));
    if (poured_all && covered + poured < budget) {
      covered += poured;
      return true;
    }
    for (const auto& writes : undo) {
      for (auto w = writes.rbegin(); w != writes.rend(); ++w) depth[w->first] = w->second;
    }
    return false;
  };
  bool parallel = workers > 1;
  for (size_t u0 = 0, u1 = 0; u0 < units.units(); u0 = u1) {
    // The phase [u0, u1): bands of one parity (a unit's band: its first
    // terminal's).
    std::vector<std::pair<size_t, size_t>> bands;
    const uint32_t parity = band_of(first_of(u0)) & 1u;
    while (u1 < units.units() && (band_of(first_of(u1)) & 1u) == parity) {
      size_t end = u1 + 1;
      while (end < units.units() && band_of(first_of(end)) == band_of(first_of(u1))) ++end;
      bands.emplace_back(u1, end);
      u1 = end;
    }
    if (parallel && bands.size() > 1) {
      if (pour_in_parallel(bands)) {
        if (stats) stats->piles_in_parallel += units.begin[u1] - units.begin[u0];
        continue;
      }
      parallel = false;  // the next phase's piles are likely to meet as well
    }
    pour_serially(u0, u1);
  }
  if (stats) {
    stats->covered = covered;
    for (size_t u = 0; u < units.units(); ++u)
      stats->groups += units.begin[u + 1] - units.begin[u] > 1;
  }
  return terminals.size();
}

size_t pour_pressed_snow(const glm::vec4* cells, float* depth, const DepositGrid& grid,
                         float min_over, const std::vector<uint32_t>& under) {
  // The texels pressed above their ceilings, in the order of `under` (most
  // calls find none; deposit_piles sorts them into its order).
  std::vector<uint32_t> terminals = select_in_order(
      under.size(),
      [&](size_t u) {
        const glm::vec4& c = cells[under[u]];
        return (c.x + depth[under[u]]) - (c.y - kCeilingClearance) >= min_over;
      },
      [&](size_t u) { return under[u]; });
  if (terminals.empty()) return 0;
  const size_t count = size_t(grid.width) * size_t(grid.height) * size_t(grid.layers);
  ZeroedArray<float> arrive(count);
  std::vector<float> before(terminals.size());
  for (size_t t = 0; t < terminals.size(); ++t) {
    const uint32_t k = terminals[t];
    const float kept = std::max(0.0f, (cells[k].y - kCeilingClearance) - cells[k].x);
    before[t] = depth[k];
    arrive[k] = depth[k] - kept;
    depth[k] = kept;
  }
  const std::vector<uint32_t> pressed = terminals;
  deposit_piles(cells, depth, arrive.data(), std::move(terminals), grid, 0, nullptr,
                PileGrouping::Pressed);
  // A pile with no room anywhere leaves its snow where it was: that texel
  // stays as it was, and does not count.
  size_t moved = 0;
  for (size_t t = 0; t < pressed.size(); ++t) moved += depth[pressed[t]] != before[t];
  return moved;
}

size_t pour_pressed_snow(const glm::vec4* cells, float* depth, const DepositGrid& grid,
                         float min_over) {
  return pour_pressed_snow(cells, depth, grid, min_over, texels_under_ceilings(cells, grid));
}

size_t deposit_piles(const glm::vec4* cells, float* depth, const float* arrive,
                     const DepositGrid& grid) {
  const size_t count = size_t(grid.width) * size_t(grid.height) * size_t(grid.layers);
  std::vector<uint32_t> terminals;
  for (size_t k = 0; k < count; ++k) {
    if (arrive[k] > 0.0f) terminals.push_back(uint32_t(k));
  }
  return deposit_piles(cells, depth, arrive, std::move(terminals), grid);
}

}  // namespace snow
