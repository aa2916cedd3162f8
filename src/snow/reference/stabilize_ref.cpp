// CPU reference of the stabilizer passes (DESIGN.md "Stabilizer"; angle of
// repose relaxation after Fearing 2000, section 5; steep routing as
// steepest-descent flow routing over a terrain). Every function here mirrors
// one fragment shader of shaders/stabilize_*.frag statement by statement, so
// that the GPU and this reference agree to float rounding.
#include "snow/reference/stabilize_ref.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "snow/column.h"

namespace snow::reference {
namespace {

int cell_flags(const glm::vec4& cell) { return int(cell.w); }

// The snow surface as far as it is free to move: ground + depth, kept
// kCeilingClearance under the ceiling (column.glsl free_top).
float free_top(const glm::vec4& cell, float s) {
  return std::max(cell.x, std::min(cell.x + s, cell.y - kCeilingClearance));
}

}  // namespace

Stabilizer::Stabilizer(const SnowMaps& maps, const StabilizeSettings& settings)
    : settings_(settings),
      width_(maps.grid.width),
      height_(maps.grid.height),
      layers_(maps.layers),
      texel_(maps.grid.texel),
      cells_(stabilize_cells(maps, settings)) {
  rise_ = kSurfaceContinuityTexels * texel_;
  distance_[0] = distance_[1] = distance_[2] = distance_[3] = texel_;
  distance_[4] = distance_[5] = distance_[6] = distance_[7] =
      float(double(texel_) * std::sqrt(2.0));
  const size_t n = cells_.size();
  depth_.assign(n, 0.0f);
  lost_.assign(n, 0.0f);
  amount_.assign(8 * n, 0.0f);
  code_.assign(8 * n, kCodeNone);
  pointer_.assign(n, 0u);
}

void Stabilizer::set_depth(const std::vector<float>& depth) {
  if (depth.size() != cells_.size()) {
    throw InputError("stabilize: depth has " + std::to_string(depth.size()) +
                     " entries, the maps have " + std::to_string(cells_.size()) + " layer texels");
  }
  for (size_t k = 0; k < cells_.size(); ++k) {
    const float d = depth[k];
    depth_[k] = (cell_flags(cells_[k]) & kCellSurface) && d > 0.0f ? d : 0.0f;
  }
  std::fill(lost_.begin(), lost_.end(), 0.0f);
  route_pending_ = true;
  schedule_.restart();
}

void Stabilizer::add_snow(const std::vector<float>& amount, float scale) {
  if (amount.size() != cells_.size()) {
    throw InputError("stabilize: snow amount has " + std::to_string(amount.size()) +
                     " entries, the maps have " + std::to_string(cells_.size()) + " layer texels");
  }
  // Mirrors shaders/stabilize_add.frag.
  for (size_t k = 0; k < cells_.size(); ++k) {
    const float add = amount[k] * scale;
    if ((cell_flags(cells_[k]) & kCellSurface) && add > 0.0f) depth_[k] = depth_[k] + add;
  }
  route_pending_ = true;
  schedule_.restart();
}

double Stabilizer::lost_volume() const {
  double sum = 0.0;
  for (float v : lost_) sum += double(v);
  return sum * double(texel_) * double(texel_);
}

// Mirrors shaders/column.glsl: snow::land_in_column on the cells, with the
// snow tops ground + depth, or with `kept` the routing's kept heights.
int Stabilizer::land(int i, int j, float h, float support, float rise, bool kept) const {
  if (i < 0 || j < 0 || i >= width_ || j >= height_) return kLandVoid;
  for (int l = 0; l < layers_; ++l) {
    const size_t k = index(l, i, j);
    const glm::vec4& cell = cells_[k];
    const int flags = cell_flags(cell);
    if ((flags & kCellSurface) == 0) {
      return l > 0 && (cell_flags(cells_[index(l - 1, i, j)]) & kCellDown) == 0 ? kLandBlocked
                                                                                : kLandVoid;
    }
    if (h >= cell.y) return kLandBlocked;
    const float top = kept ? stable_[k] : cell.x + depth_[k];
    if (top <= h) {
      if ((flags & kCellSolid) != 0 || cell.y - support < rise) return kLandBlocked;
      return l;
    }
    if (h >= cell.x) return kLandBlocked;
  }
  return kLandBlocked;
}

// Mirrors gap_at in shaders/stabilize_outflow.frag: the layer of column
// (i, j) whose gap (ground up to ceiling, not a solid's inside) contains
// height h, kLandBlocked or kLandVoid.
int Stabilizer::gap_at(int i, int j, float h) const {
  if (i < 0 || j < 0 || i >= width_ || j >= height_) return kLandVoid;
  for (int l = 0; l < layers_; ++l) {
    const glm::vec4& cell = cells_[index(l, i, j)];
    const int flags = cell_flags(cell);
    if ((flags & kCellSurface) == 0) {
      return l > 0 && (cell_flags(cells_[index(l - 1, i, j)]) & kCellDown) == 0 ? kLandBlocked
                                                                                : kLandVoid;
    }
    if (h >= cell.y) return kLandBlocked;
    if (h >= cell.x) return (flags & kCellSolid) != 0 ? kLandBlocked : l;
  }
  return kLandBlocked;
}

// Mirrors shaders/stabilize_outflow.frag.
void Stabilizer::outflow_pass(int stride) {
  for (int l = 0; l < layers_; ++l) {
    for (int j = 0; j < height_; ++j) {
      for (int i = 0; i < width_; ++i) {
        const size_t k = index(l, i, j);
        float* out = &amount_[8 * k];
        uint8_t* code = &code_[8 * k];
        for (int n = 0; n < 8; ++n) {
          out[n] = 0.0f;
          code[n] = kCodeNone;
        }
        const glm::vec4 cell = cells_[k];
        const float s = depth_[k];
        if ((cell_flags(cell) & kCellSurface) == 0 || !(s > 0.0f)) continue;
        const float h = cell.x + s;
        const float he = free_top(cell, s);  // snow above the ceiling is pressed out
        const float over = h - he;
        float w[8];
        float wsum = 0.0f, wmax = 0.0f;
        int voids = 0;
        float wmax1 = 0.0f;  // strided passes: the largest excess of a single step
        int voids1 = 0;      // and the single steps into the void
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
            if (stride == 1) break;
            if (m == 1 && land_l == kLandVoid) ++voids1;
            if (land_l < 0) break;
            const size_t km = index(land_l, ni, nj);
            const float top = cells_[km].x + depth_[km];
            if (m == 1) wmax1 = std::max(wmax1, he - top - distance_[n] * path_tan);
            if (path_h - top > rise_) {
              land_l = kLandBlocked;
              break;
            }
            path_h = top;
            path_g = cells_[km].x;
            step_tan = cells_[km].z;
          }
          if (stride > 1 && land_l == kLandVoid) land_l = kLandBlocked;
          if (land_l == kLandVoid) {
            code[n] = kCodeVoid;
            ++voids;
          } else if (land_l >= 0) {
            code[n] = uint8_t(land_l);
            const size_t kt = index(land_l, ni, nj);
            const float ht = cells_[kt].x + depth_[kt];
            const float e = he - ht - distance_[n] * path_tan;
            w[n] = std::max(e, 0.0f);
            wsum += w[n];
            wmax = std::max(wmax, w[n]);
          }
        }
        // A strided pass moves only snow that a single step moves (the
        // stride-1 rule below on the first steps): snow at rest for single
        // steps stays, which the GPU passes' active tiles rely on.
        const bool single_moves =
            voids1 > 0 ||
            (wmax1 > 0.0f && std::min(s, std::max(0.5f * wmax1, over)) >= settings_.min_move);
        if (stride > 1 && !single_moves) wmax = 0.0f;
        if (voids > 0) {
          // An edge of the world: everything falls off, shared by the void directions.
          const float share = s / float(voids);
          float left = s;
          int seen = 0;
          for (int n = 0; n < 8; ++n) {
            if (code[n] != kCodeVoid) continue;
            ++seen;
            out[n] = seen == voids ? left : share;
            left -= share;
          }
        } else if (wmax > 0.0f) {
          // Half the largest excess moves, split over the receivers by their
          // excess: a receiver rises by at most half its excess, so the pair
          // never overshoots and piles end at the repose slope.
          // Moves under min_move are not made (rounding noise).
          float total = std::min(s, std::max(0.5f * wmax, over));
          if (total < settings_.min_move) total = 0.0f;
          for (int n = 0; n < 8; ++n) out[n] = total * (w[n] / wsum);
        } else if (over > 0.0f && stride == 1) {
          // Snow deeper than its gap with nowhere downhill to go is squeezed
          // out sideways into the gaps of the neighbouring columns at that
          // height, as far as they have room (the void takes everything).
          float p[8];
          float psum = 0.0f;
          for (int n = 0; n < 8; ++n) {
            p[n] = 0.0f;
            code[n] = kCodeNone;
            const int ni = i + kDirI[n], nj = j + kDirJ[n];
            const int gap = gap_at(ni, nj, he);
            if (gap == kLandVoid) {
              code[n] = kCodeVoid;
              p[n] = over;
            } else if (gap >= 0) {
              code[n] = uint8_t(gap);
              const size_t kt = index(gap, ni, nj);
              const float room = (cells_[kt].y - kCeilingClearance) - (cells_[kt].x + depth_[kt]);
              p[n] = std::min(std::max(0.5f * (over + room), 0.0f), over);
            }
            psum += p[n];
          }
          if (psum > 0.0f) {
            const float scale = std::min(1.0f, over / psum);
            for (int n = 0; n < 8; ++n) out[n] = p[n] * scale;
          }
        }
        // A direction that moves nothing has no landing code.
        for (int n = 0; n < 8; ++n) {
          if (out[n] == 0.0f) code[n] = kCodeNone;
        }
      }
    }
  }
}

// Mirrors shaders/stabilize_gather.frag.
void Stabilizer::gather_pass(int stride) {
  std::vector<float> next(depth_.size());
  for (int l = 0; l < layers_; ++l) {
    for (int j = 0; j < height_; ++j) {
      for (int i = 0; i < width_; ++i) {
        const size_t k = index(l, i, j);
        float s = depth_[k];
        float lost = lost_[k];
        for (int n = 0; n < 8; ++n) {
          const float a = amount_[8 * k + n];
          s -= a;
          if (code_[8 * k + n] == kCodeVoid) lost += a;
        }
        for (int n = 0; n < 8; ++n) {
          const int mi = i - stride * kDirI[n], mj = j - stride * kDirJ[n];
          if (mi < 0 || mj < 0 || mi >= width_ || mj >= height_) continue;
          for (int lm = 0; lm < layers_; ++lm) {
            const size_t km = index(lm, mi, mj);
            if ((cell_flags(cells_[km]) & kCellSurface) == 0) break;  // layers are packed
            if (code_[8 * km + n] == uint8_t(l)) s += amount_[8 * km + n];
          }
        }
        next[k] = s;
        lost_[k] = lost;
      }
    }
  }
  depth_.swap(next);
}

// Mirrors the largest move of shaders/stabilize_gather.frag.
float Stabilizer::residual() const {
  float largest = 0.0f;
  for (size_t k = 0; k < cells_.size(); ++k) {
    float sum = 0.0f;
    for (int n = 0; n < 8; ++n) sum += amount_[8 * k + n];
    largest = std::max(largest, sum);
  }
  return largest;
}

int Stabilizer::route(double* routed_volume) {
  const size_t count = cells_.size();
  // Erosion passes (shaders/stabilize_erode.frag): the highest snow surface
  // each texel can keep, H = max(ground, min(H, min over neighbours of
  // H(landing) + distance * tan(repose))), from H = min(ground + depth,
  // ceiling), until nothing changes (shaders/stabilize_erode_check.frag).
  stable_.assign(count, 0.0f);
  for (size_t k = 0; k < count; ++k) {
    const glm::vec4 cell = cells_[k];
    stable_[k] = free_top(cell, depth_[k]);
  }
  std::vector<float> next_stable(count);
  int passes = 0;
  for (;;) {
    size_t changed = 0;
    for (int l = 0; l < layers_; ++l) {
      for (int j = 0; j < height_; ++j) {
        for (int i = 0; i < width_; ++i) {
          const size_t k = index(l, i, j);
          const glm::vec4 cell = cells_[k];
          float hs = stable_[k];
          if ((cell_flags(cell) & kCellSurface) != 0 && hs > cell.x) {
            const float he = free_top(cell, depth_[k]);
            for (int n = 0; n < 8; ++n) {
              const int ni = i + kDirI[n], nj = j + kDirJ[n];
              const int land_l = land(ni, nj, he, cell.x, rise_, true);
              if (land_l == kLandVoid) {
                hs = cell.x;
              } else if (land_l >= 0) {
                hs = std::min(hs, stable_[index(land_l, ni, nj)] + distance_[n] * cell.z);
              }
            }
            hs = std::max(hs, cell.x);
          }
          next_stable[k] = hs;
          if (hs != stable_[k]) ++changed;
        }
      }
    }
    stable_.swap(next_stable);
    ++passes;
    if (changed == 0) break;
  }
  // Receiver pass (shaders/stabilize_receiver.frag): a texel holding more
  // than it can keep sends the excess towards the neighbour that limits it
  // (the void when one neighbour is the void); H falls strictly along these
  // pointers, so they form a forest whose roots (terminals) point to themselves.
  for (int l = 0; l < layers_; ++l) {
    for (int j = 0; j < height_; ++j) {
      for (int i = 0; i < width_; ++i) {
        const size_t k = index(l, i, j);
        const glm::vec4 cell = cells_[k];
        uint32_t p = uint32_t(k);
        const float hs = stable_[k];
        if ((cell_flags(cell) & kCellSurface) != 0 && cell.x + depth_[k] > hs) {
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
        }
        pointer_[k] = p;
      }
    }
  }
  // Jump passes (shaders/stabilize_jump.frag) until every pointer reaches a
  // terminal (the GPU runs one more, which moves no pointer on and does not
  // count).
  auto unfinished = [&]() {
    size_t open = 0;
    for (size_t k = 0; k < count; ++k) {
      const uint32_t p = pointer_[k];
      if (p == kPointerVoid || p == uint32_t(k)) continue;
      if (pointer_[p] != p) ++open;  // kPointerVoid != p here
    }
    return open;
  };
  int jumps = 0;
  std::vector<uint32_t> next(count);
  while (unfinished() > 0) {
    for (size_t k = 0; k < count; ++k) {
      const uint32_t p = pointer_[k];
      next[k] = p == kPointerVoid ? p : pointer_[p];
    }
    pointer_.swap(next);
    ++jumps;
  }
  // Scatter (shaders/stabilize_scatter.*: one point per routed texel, added
  // in texel order into its terminal) and apply (stabilize_apply.frag).
  auto excess = [&](size_t k) { return (cells_[k].x + depth_[k]) - stable_[k]; };
  std::vector<float> arrive(count, 0.0f);
  for (size_t k = 0; k < count; ++k) {
    const uint32_t p = pointer_[k];
    if (p != uint32_t(k) && p != kPointerVoid) arrive[p] += excess(k);
  }
  double moved = 0.0;
  for (size_t k = 0; k < count; ++k) {
    const uint32_t p = pointer_[k];
    float s = depth_[k];
    if (p != uint32_t(k)) {
      const float e = excess(k);
      moved += double(e);
      if (p == kPointerVoid) lost_[k] = lost_[k] + e;
      s = s - e;
    }
    depth_[k] = s + arrive[k];
  }
  if (routed_volume) *routed_volume += moved * double(texel_) * double(texel_);
  route_pending_ = false;
  return passes + jumps;
}

StabilizeResult Stabilizer::iterate(int passes) {
  StabilizeResult result;
  const double lost_before = lost_volume();
  if (route_pending_) {
    if (settings_.route_steep) result.route_passes = route(&result.routed_volume);
    route_pending_ = false;
  }
  int last_check = 0;
  for (int pass = 1; pass <= passes; ++pass) {
    const int stride = schedule_.next();
    outflow_pass(stride);
    gather_pass(stride);
    ++result.iterations;
    if ((stride == 1 && pass - last_check >= settings_.check_every) || pass == passes) {
      last_check = pass;
      result.residual = residual();
      schedule_.checked(stride, result.residual);
      if (result.residual < settings_.tolerance) {
        result.converged = true;
        break;
      }
    }
  }
  result.lost_volume = lost_volume() - lost_before;
  result.volume = snow_volume_of(depth_);
  return result;
}

double Stabilizer::snow_volume_of(const std::vector<float>& depth) const {
  double sum = 0.0;
  for (size_t k = 0; k < depth.size(); ++k) {
    if (cell_flags(cells_[k]) & kCellSurface) sum += double(depth[k]);
  }
  return sum * double(texel_) * double(texel_);
}

StabilizeResult stabilize(const SnowMaps& maps, std::vector<float>& depth,
                          const StabilizeSettings& settings, int max_iterations_override) {
  Stabilizer stabilizer(maps, settings);
  stabilizer.set_depth(depth);
  StabilizeResult result = stabilizer.iterate(
      max_iterations_override >= 0 ? max_iterations_override : settings.max_iterations);
  depth = stabilizer.depth();
  for (float& d : depth) d = std::max(d, 0.0f);
  return result;
}

}  // namespace snow::reference
