#version 450 core
// Stabilizer outflow pass (contract: src/snow/stabilize.h): for each of the 8
// directions, where snow leaving this texel lands u_stride columns away
// (column.glsl, along a path of single steps for strided passes) and how
// much goes there. Mirrors CpuStabilizer::outflow_texel.
#include "bindings.h"
#include "column.glsl"

layout(location = 0) out vec4 o_out_a;  // metres to directions 0..3
layout(location = 1) out vec4 o_out_b;  // metres to directions 4..7
layout(location = 2) out uvec2 o_code;  // landing codes, 8 bits per direction

// The layer of column c whose gap (ground up to ceiling, not a solid's
// inside) contains height h, kLandBlocked or kLandVoid.
int gap_at(ivec2 c, float h) {
  if (!in_map(c)) return kLandVoid;
  for (int l = 0; l < u_layers; ++l) {
    vec4 cell = texelFetch(u_cells, ivec3(c, l), 0);
    int flags = int(cell.w);
    if ((flags & kCellSurface) == 0) {
      return l > 0 && (int(texelFetch(u_cells, ivec3(c, l - 1), 0).w) & kCellDown) == 0 ? kLandBlocked
                                                                                   : kLandVoid;
    }
    if (h >= cell.y) return kLandBlocked;
    if (h >= cell.x) return (flags & kCellSolid) != 0 ? kLandBlocked : l;
  }
  return kLandBlocked;
}

// The stride-1 rule of a strided pass (below): would a single step move
// snow from this texel? Most texels of a late strided pass stay, and this
// answers for them without walking the paths. Mirrors
// CpuStabilizer::single_step_moves.
bool single_step_moves(ivec2 c, vec4 cell, float movable, float he, float over) {
  float wmax1 = 0.0;
  for (int n = 0; n < 8; ++n) {
    vec4 mc;
    float top;
    int land_l = landing(c + kDir[n], he, cell.x, false, mc, top);
    if (land_l == kLandVoid) return true;
    if (land_l >= 0) {
      precise float e = he - top - dir_distance(n) * (0.0 + cell.z);  // not fused, as the CPU
      wmax1 = max(wmax1, e);
    }
  }
  return wmax1 > 0.0 && min(movable, max(0.5 * wmax1, over)) >= u_min_move;
}

// Sends `total` into the `voids` directions whose code is kCodeVoid, in
// equal shares, the last taking what rounding leaves. Mirrors the CPU's
// fall_off (snow/stabilize/cpu.cpp).
void fall_off(uint code[8], int voids, float total, inout float amount[8]) {
  float share = divide(total, float(voids));
  float left = total;
  int seen = 0;
  for (int n = 0; n < 8; ++n) {
    if (code[n] != kCodeVoid) continue;
    ++seen;
    amount[n] = seen == voids ? left : share;
    left -= share;
  }
}

void main() {
  ivec2 c = ivec2(gl_FragCoord.xy);
  float amount[8];
  uint code[8];
  for (int n = 0; n < 8; ++n) {
    amount[n] = 0.0;
    code[n] = kCodeNone;
  }
  vec4 cell = texelFetch(u_cells, ivec3(c, u_layer), 0);
  float s = texelFetch(u_depth, ivec3(c, u_layer), 0).r;
  float he = free_top(cell, s);  // snow above the ceiling is pressed out
  precise float over = (cell.x + s) - he;
  // What cohesion holds stays (snow/cohesion.h); only the rest moves.
  precise float movable = s - held(ivec3(c, u_layer), cell, s);
  // A strided pass moves only snow that a single step moves: snow at rest
  // for single steps stays (the active tiles rely on it).
  if ((int(cell.w) & kCellSurface) != 0 && s > 0.0 && movable > 0.0 &&
      (u_stride == 1 || single_step_moves(c, cell, movable, he, over))) {
    float w[8];
    float wsum = 0.0, wmax = 0.0;
    int voids = 0;
    for (int n = 0; n < 8; ++n) {
      w[n] = 0.0;
      // Strided passes: a path of single steps, each landing by the rule and
      // going down by at most u_rise; never into the void.
      ivec2 nc = c;
      int land_l = 0;
      float path_h = he, path_g = cell.x, path_tan = 0.0;
      float step_tan = cell.z;
      vec4 mc;    // the landing cell of the step
      float top;  // and its snow top
      for (int m = 1; m <= u_stride; ++m) {
        nc = c + m * kDir[n];
        land_l = landing(nc, path_h, path_g, false, mc, top);
        path_tan += step_tan;
        if (u_stride == 1 || land_l < 0) break;
        if (path_h - top > u_rise) {
          land_l = kLandBlocked;
          break;
        }
        path_h = top;
        path_g = mc.x;
        step_tan = mc.z;
      }
      if (u_stride > 1 && land_l == kLandVoid) land_l = kLandBlocked;
      if (land_l == kLandVoid) {
        code[n] = kCodeVoid;
        ++voids;
      } else if (land_l >= 0) {
        code[n] = uint(land_l);
        // A receiver under a ceiling takes at most its room (as the CPU).
        precise float room = (mc.y - kCeilingClearance) - top;
        precise float e = min(he - top - dir_distance(n) * path_tan, room);  // not fused, as the CPU
        w[n] = max(e, 0.0);
        wsum += w[n];
        wmax = max(wmax, w[n]);
      }
    }
    if (voids > 0) {
      // An edge of the world: everything that moves falls off, shared by the
      // void directions.
      fall_off(code, voids, movable, amount);
    } else if (wmax > 0.0) {
      float total = min(movable, max(0.5 * wmax, over));  // half the largest excess, split by excess
      if (total < u_min_move) total = 0.0;
      for (int n = 0; n < 8; ++n) amount[n] = total * divide(w[n], wsum);
    } else if (over > 0.0 && u_stride == 1) {
      // Snow deeper than its gap with nowhere downhill to go is squeezed out
      // sideways into the neighbouring columns' gaps at that height: all of
      // it into the void where there is one, else until this texel and the
      // gaps taking end level (CpuStabilizer::outflow_texel); into a full
      // gap it is not a move the convergence test sees (kCodeFull).
      precise float room[8];  // no fused or reassociated arithmetic, as the CPU
      bool is_gap[8], taking[8];
      int edges = 0;
      for (int n = 0; n < 8; ++n) {
        room[n] = 0.0;
        is_gap[n] = taking[n] = false;
        code[n] = kCodeNone;
        ivec2 nc = c + kDir[n];
        int gap = gap_at(nc, he);
        if (gap == kLandVoid) {
          code[n] = kCodeVoid;
          ++edges;
        } else if (gap >= 0) {
          code[n] = uint(gap);
          vec4 tc = texelFetch(u_cells, ivec3(nc, gap), 0);
          room[n] = min((tc.y - kCeilingClearance) - (tc.x + texelFetch(u_depth, ivec3(nc, gap), 0).r),
                        over);  // room past the over takes no more
          is_gap[n] = taking[n] = true;
          if (!(room[n] > 0.0)) code[n] |= kCodeFull;  // it stays at its ceiling
        }
      }
      if (edges > 0) {
        fall_off(code, edges, over, amount);
      } else {
        precise float level = 0.0;
        for (bool dropped = true; dropped;) {
          precise float rooms = 0.0;
          int count = 0;
          for (int n = 0; n < 8; ++n) {
            if (!taking[n]) continue;
            rooms += room[n];
            ++count;
          }
          level = divide(over - rooms, float(count + 1));
          dropped = false;
          for (int n = 0; n < 8; ++n) {
            if (taking[n] && !(level + room[n] > 0.0)) {
              taking[n] = false;
              dropped = true;
            }
          }
        }
        if (level > 0.0) {
          for (int n = 0; n < 8; ++n) amount[n] = taking[n] ? level + room[n] : 0.0;
        } else {  // the rooms hold it all: filled in proportion to their room
          precise float free = 0.0;
          for (int n = 0; n < 8; ++n) free += is_gap[n] ? max(room[n], 0.0) : 0.0;
          for (int n = 0; n < 8; ++n) {
            if (is_gap[n] && room[n] > 0.0) amount[n] = over * divide(room[n], free);
          }
        }
      }
    }
    // A direction that moves nothing has no landing: the gather adds only
    // what moves, and a texel at rest writes what a skipped one holds.
    for (int n = 0; n < 8; ++n) {
      if (amount[n] == 0.0) code[n] = kCodeNone;
    }
  }
  o_out_a = vec4(amount[0], amount[1], amount[2], amount[3]);
  o_out_b = vec4(amount[4], amount[5], amount[6], amount[7]);
  o_code = uvec2(code[0] | (code[1] << 8) | (code[2] << 16) | (code[3] << 24),
                 code[4] | (code[5] << 8) | (code[6] << 16) | (code[7] << 24));
}
