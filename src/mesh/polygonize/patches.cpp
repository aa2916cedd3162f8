// Patch finding: snowy layer texels joined across layers by the stabilizer's
// landing rule (snow::landing_layer, column.h; height spans after Onoue and
// Nishita), so a floor running under a table is one patch.
//
// Patches grow breadth first from seeds in index order, and take at most
// one layer per column. Most texels of a terrain, a floor or a roof lie on
// the top surface of a column, under the open sky, with no snow on the
// surfaces below it (a slab's underside, the floor under a roof): "single"
// texels. Between two of them the landing rule reduces to "tops within
// max_step" (snow that does not land on a column's top lands lower, where
// there is no snow to join), which is symmetric and never meets the
// one-layer rule. So those are first joined into clusters on all cores
// (union-find over strips of rows), and a patch that reaches a cluster takes
// all of it; only the texels of other columns, and the cluster texels beside
// them, are walked one by one. The patches hold the texels the walk of every
// texel would give them (an order of their texels aside), but where two
// layers of one column could both join a patch, the one reached first may
// differ from that walk's.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "core/zeroed.h"
#include "mesh/polygonize/steps.h"
#include "snow/column.h"

namespace snow::poly {
namespace {

constexpr int kDi[4] = {1, -1, 0, 0};
constexpr int kDj[4] = {0, 0, 1, -1};

/// One find_patches call: the maps, the column classes and clusters, and
/// the walk's state.
class PatchFinder {
 public:
  PatchFinder(const SnowMaps& maps, const LayerArray<float>& depth, float min_thickness,
              float max_step)
      : maps_(maps),
        depth_(depth),
        min_thickness_(min_thickness),
        max_step_(max_step),
        n_(depth.size()),
        per_layer_(maps.grid.texels()),
        w_(maps.grid.width),
        h_(maps.grid.height),
        strips_(std::min<size_t>(size_t(h_), 4 * size_t(default_threads()))) {}

  std::vector<PatchTexels> run() {
    classify_columns();
    cluster_single_texels();
    collect_cluster_edges();
    std::vector<PatchTexels> patches = walk_patches();
    add_cluster_texels(patches);
    return patches;
  }

 private:
  bool snowy(size_t k) const { return depth_[k] > min_thickness_; }
  float top(size_t k) const { return maps_.ground[k] + depth_[k]; }
  /// The first row of strip s of rows (s == strips_: the end).
  int strip_row(size_t s) const { return int(s * size_t(h_) / strips_); }
  bool is_clustered(size_t k) const { return k < per_layer_ && clustered_[k]; }

  void classify_columns();
  void cluster_single_texels();
  void collect_cluster_edges();
  std::vector<PatchTexels> walk_patches();
  void claim(size_t k);
  bool unclaimed(size_t k) const;
  void walk(size_t a);
  void add_cluster_texels(std::vector<PatchTexels>& patches) const;

  const SnowMaps& maps_;
  const LayerArray<float>& depth_;
  const float min_thickness_, max_step_;
  const size_t n_, per_layer_;  // layer texels, texels per layer
  const int w_, h_;
  const size_t strips_;  // strips of rows clustered on all cores

  // By column (layer-0 index); cluster_ only where clustered_.
  // (These arrays over every column are written on all cores; cluster_ only
  // where a texel is clustered, the only entries read.)
  LayerArray<uint8_t> single_;     // its top texel is a single texel
  LayerArray<uint8_t> clustered_;  // ... and snowy
  LayerArray<uint32_t> cluster_;   // each clustered texel's root (its cluster's lowest index)
  // The cluster texels beside a column that is not single, by cluster: the
  // only ones a walk must visit. (root, texel), sorted.
  std::vector<std::pair<uint32_t, uint32_t>> edge_;

  // The walk. Patch p is stamped p + 1: these start as zero pages, which only
  // the texels a walk visits fault in.
  ZeroedArray<uint8_t> claimed_;        // texels outside clusters
  ZeroedArray<int32_t> cluster_patch_;  // by root
  ZeroedArray<int32_t> column_stamp_;
  static constexpr size_t kClusterItem = size_t(1) << 63;  // a queue item that is a cluster's root
  std::vector<size_t> queue_;
  int32_t id_ = 0;                // the stamp of the patch being walked
  PatchTexels* patch_ = nullptr;  // the patch being walked
};

/// Single snowy texels (layer 0; their index is their column's).
void PatchFinder::classify_columns() {
  const auto snow_below = [&](size_t c) {
    for (size_t k = c + per_layer_; k < n_ && !std::isnan(maps_.ground[k]); k += per_layer_) {
      if (snowy(k)) return true;
    }
    return false;
  };
  single_.resize(per_layer_);
  clustered_.resize(per_layer_);
  parallel_for(size_t(h_), [&](size_t j) {
    for (size_t c = j * size_t(w_); c < (j + 1) * size_t(w_); ++c) {
      single_[c] = !std::isnan(maps_.ground[c]) && std::isinf(maps_.ceiling[c]) &&
                   maps_.ceiling[c] > 0.0f && !snow_below(c);
      clustered_[c] = single_[c] && snowy(c);
    }
  });
}

/// Union-find, each cluster's root its lowest index: strips of rows on all
/// cores, then the rows where strips meet.
void PatchFinder::cluster_single_texels() {
  auto joined = [&](size_t a, size_t b) {
    return clustered_[a] && clustered_[b] && std::abs(top(b) - top(a)) <= max_step_;
  };
  LayerArray<uint32_t> root(per_layer_);
  auto find = [&](uint32_t a) {
    while (root[a] != a) a = root[a] = root[root[a]];
    return a;
  };
  auto unite = [&](uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) root[std::max(a, b)] = std::min(a, b);
  };
  const uint32_t w = uint32_t(w_);
  parallel_for(strips_, [&](size_t s) {
    for (int j = strip_row(s); j < strip_row(s + 1); ++j) {
      for (int i = 0; i < w_; ++i) {
        const uint32_t c = uint32_t(j) * w + uint32_t(i);
        if (!clustered_[c]) continue;
        root[c] = c;
        if (i > 0 && joined(c, c - 1)) unite(c, c - 1);
        if (j > strip_row(s) && joined(c, c - w)) unite(c, c - w);
      }
    }
  });
  for (size_t s = 1; s < strips_; ++s) {
    const uint32_t row = uint32_t(strip_row(s)) * w;
    for (uint32_t c = row; c < row + w; ++c) {
      if (joined(c, c - w)) unite(c, c - w);
    }
  }
  cluster_.resize(per_layer_);
  parallel_for(size_t(h_), [&](size_t j) {
    for (size_t c = j * size_t(w_); c < (j + 1) * size_t(w_); ++c) {
      if (!clustered_[c]) continue;
      uint32_t r = uint32_t(c);
      while (root[r] != r) r = root[r];
      cluster_[c] = r;
    }
  });
}

void PatchFinder::collect_cluster_edges() {
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> rows(static_cast<size_t>(h_));
  parallel_for(size_t(h_), [&](size_t j) {
    for (int i = 0; i < w_; ++i) {
      const size_t c = j * size_t(w_) + size_t(i);
      if (!clustered_[c]) continue;
      for (int d = 0; d < 4; ++d) {
        const int ni = i + kDi[d], nj = int(j) + kDj[d];
        if (ni < 0 || nj < 0 || ni >= w_ || nj >= h_) continue;
        if (!single_[size_t(nj) * size_t(w_) + size_t(ni)]) {
          rows[j].emplace_back(cluster_[c], uint32_t(c));
          break;
        }
      }
    }
  });
  size_t count = 0;
  for (const auto& row : rows) count += row.size();
  edge_.reserve(count);
  for (const auto& row : rows) edge_.insert(edge_.end(), row.begin(), row.end());
  std::sort(edge_.begin(), edge_.end());
}

/// The patches grown from every unclaimed snowy seed, in index order; a
/// cluster the walk reaches is claimed whole, but its texels are added to
/// the patch by add_cluster_texels.
std::vector<PatchTexels> PatchFinder::walk_patches() {
  claimed_ = ZeroedArray<uint8_t>(n_);
  cluster_patch_ = ZeroedArray<int32_t>(per_layer_);
  column_stamp_ = ZeroedArray<int32_t>(per_layer_);
  std::vector<PatchTexels> patches;
  for (size_t seed = 0; seed < n_; ++seed) {
    if (!snowy(seed)) continue;
    const bool in_cluster = seed < per_layer_ && clustered_[seed];
    if (in_cluster ? cluster_patch_[cluster_[seed]] != 0 : claimed_[seed] != 0) continue;
    id_ = int32_t(patches.size()) + 1;
    patches.emplace_back();
    patch_ = &patches.back();
    queue_.clear();
    claim(seed);
    for (size_t next = 0; next < queue_.size(); ++next) {
      const size_t item = queue_[next];
      if (!(item & kClusterItem)) {
        walk(item);
        continue;
      }
      const uint32_t r = uint32_t(item & ~kClusterItem);
      for (auto e = std::lower_bound(edge_.begin(), edge_.end(), std::make_pair(r, uint32_t(0)));
           e != edge_.end() && e->first == r; ++e) {
        walk(e->second);
      }
    }
  }
  patch_ = nullptr;
  return patches;
}

void PatchFinder::claim(size_t k) {
  if (is_clustered(k)) {
    cluster_patch_[cluster_[k]] = id_;
    queue_.push_back(kClusterItem | cluster_[k]);
    return;
  }
  claimed_[k] = 1;
  column_stamp_[k % per_layer_] = id_;
  patch_->texels.push_back(k);
  queue_.push_back(k);
}

bool PatchFinder::unclaimed(size_t k) const {
  return is_clustered(k) ? cluster_patch_[cluster_[k]] == 0 : claimed_[k] == 0;
}

/// The walk from texel a: claims the neighbours it joins by the landing rule.
void PatchFinder::walk(size_t a) {
  const TexelCoord ca = coord_of(maps_, a);
  const bool a_clustered = is_clustered(a);
  const float ha = top(a);
  for (int d = 0; d < 4; ++d) {
    const int ni = ca.i + kDi[d];
    const int nj = ca.j + kDj[d];
    if (ni < 0 || nj < 0 || ni >= w_ || nj >= h_) continue;
    const size_t col = size_t(nj) * size_t(w_) + size_t(ni);
    if (a_clustered && single_[col]) continue;  // its cluster, or not joined
    if (column_stamp_[col] == id_) continue;    // one layer per column and patch
    auto consider = [&](size_t b) {
      if (unclaimed(b) && snowy(b) && column_stamp_[col] != id_) claim(b);
    };
    // Snow leaving a lands on b (b lies at most max_step lower) ...
    const int lb = landing_layer(maps_, depth_.data(), ni, nj, ha);
    if (lb >= 0) {
      const size_t b = maps_.index(lb, ni, nj);
      if (ha - top(b) <= max_step_) consider(b);
    }
    // ... or snow leaving b lands on a (b lies at most max_step higher).
    for (int l = 0; l < maps_.layers; ++l) {
      const size_t b = maps_.index(l, ni, nj);
      if (std::isnan(maps_.ground[b])) break;
      const float hb = top(b);
      if (hb < ha || hb - ha > max_step_ || !snowy(b)) continue;
      if (landing_layer(maps_, depth_.data(), ca.i, ca.j, hb) == ca.l) consider(b);
    }
  }
}

/// The clusters' texels join their patches in index order, each patch's
/// list grown once, on all cores: each strip of rows counts its texels per
/// patch, then writes them from its offsets. With very many patches, whose
/// counts per strip would take much memory, on one core.
void PatchFinder::add_cluster_texels(std::vector<PatchTexels>& patches) const {
  const auto patch_of = [&](size_t c) { return size_t(cluster_patch_[cluster_[c]] - 1); };
  const auto strip_texels = [&](size_t s, auto&& fn) {
    const size_t end = size_t(strip_row(s + 1)) * size_t(w_);
    for (size_t c = size_t(strip_row(s)) * size_t(w_); c < end; ++c) {
      if (clustered_[c]) fn(c);
    }
  };
  const bool apart = strips_ * patches.size() <= (size_t(1) << 20);
  std::vector<std::vector<size_t>> lists(apart ? strips_ : 1,
                                         std::vector<size_t>(patches.size(), 0));
  const auto each_strip = [&](auto&& fn) {  // fn(strip, its list of counts or offsets)
    if (apart) {
      parallel_for(strips_, [&](size_t s) { fn(s, lists[s]); });
    } else {
      for (size_t s = 0; s < strips_; ++s) fn(s, lists[0]);
    }
  };
  each_strip([&](size_t s, std::vector<size_t>& counts) {
    strip_texels(s, [&](size_t c) { ++counts[patch_of(c)]; });
  });
  for (size_t p = 0; p < patches.size(); ++p) {
    size_t end = patches[p].texels.size();
    for (std::vector<size_t>& list : lists) {
      const size_t count = list[p];
      list[p] = end;
      end += count;
    }
    patches[p].texels.resize(end);
  }
  each_strip([&](size_t s, std::vector<size_t>& at) {
    strip_texels(s, [&](size_t c) {
      const size_t p = patch_of(c);
      patches[p].texels[at[p]++] = c;
    });
  });
}

}  // namespace

std::vector<PatchTexels> find_patches(const SnowMaps& maps, const LayerArray<float>& depth,
                                      float min_thickness, float max_step) {
  return PatchFinder(maps, depth, min_thickness, max_step).run();
}

}  // namespace snow::poly
