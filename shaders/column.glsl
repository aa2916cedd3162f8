// GLSL mirror of src/snow/column.h (the landing rule) on the stabilizer's
// cells, plus the constants the stabilize_* passes share with
// src/snow/stabilize.h and src/snow/stabilize_cpu.h.
// Needs bindings.h included first.

layout(binding = SNOW_STABILIZE_CELLS) uniform sampler2DArray u_cells;  // ground, ceiling, tan, flags
layout(binding = SNOW_STABILIZE_DEPTH) uniform sampler2DArray u_depth;  // r = depth (m), g = lost
// Routing: the highest snow surface each texel keeps (m), in r.
layout(binding = SNOW_STABILIZE_STABLE) uniform sampler2DArray u_stable;
// r = holding depth (m), g = what cohesion may hold of the snow (m): the
// held cap (CpuStabilizer::held_cap_).
layout(binding = SNOW_STABILIZE_HOLD) uniform sampler2DArray u_hold;

uniform ivec2 u_size;    // map width, height (texels)
uniform int u_layers;    // L
uniform int u_layer;     // the layer this draw writes
uniform vec2 u_distance; // metres to an edge neighbour, to a diagonal one
uniform float u_rise;    // metres, kSurfaceContinuityTexels * texel
uniform int u_stride;    // texels, stride of a relaxation pass
uniform float u_min_move;  // metres, StabilizeSettings::min_move
uniform float u_stand;     // metres, StabilizeSettings::cohesion.stand_height
// Routing: 1 in the first erosion pass, which takes the kept heights at their
// start value (kept_height) rather than from u_stable.
uniform int u_start;
// Routing: 1 when routing creeping snow (Routing::Creep): the kept heights
// start at the free tops, not capped at the holding depth.
uniform int u_repose_only;

const int kCellSurface = 1;
const int kCellSolid = 2;
const int kCellDown = 4;

const int kLandBlocked = -1;
const int kLandVoid = -2;

const float kCeilingClearance = 1e-4;  // metres, snow::kCeilingClearance

const uint kCodeNone = 254u;
const uint kCodeVoid = 255u;
// Set on the landing layer of snow squeezed into a gap that is already full
// (stabilize_outflow.frag): it lands as the layer's, but is no move that
// the convergence test sees (CpuStabilizer::outflow_texel's *hidden).
const uint kCodeFull = 64u;
const uint kPointerVoid = 0xffffffffu;

const ivec2 kDir[8] = ivec2[8](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1), ivec2(1, 1),
                               ivec2(-1, 1), ivec2(1, -1), ivec2(-1, -1));

float dir_distance(int n) { return n < 4 ? u_distance.x : u_distance.y; }

// a / b rounded as the CPU's IEEE division. GLSL may divide through an
// approximate reciprocal (NVIDIA's does: a unit in the last place off); the
// quotient of two floats in double precision, rounded to float, is the
// correctly rounded one.
float divide(float a, float b) { return float(double(a) / double(b)); }

bool in_map(ivec2 c) { return all(greaterThanEqual(c, ivec2(0))) && all(lessThan(c, u_size)); }

// The snow surface as far as it is free to move: ground + depth, kept
// kCeilingClearance under the ceiling.
float free_top(vec4 cell, float s) { return max(cell.x, min(cell.x + s, cell.y - kCeilingClearance)); }

// The snow of layer texel t (with cell `cell` and depth s) that cohesion
// holds in place: up to its held cap (what of the snow that fell there
// cohesion may hold), never above its free top. Mirrors held_snow of
// src/snow/stabilize/cpu.cpp.
float held(ivec3 t, vec4 cell, float s) {
  return min(min(s, free_top(cell, s) - cell.x), texelFetch(u_hold, t, 0).g);
}

// Routing: the kept height layer texel t starts from: its free top, no
// higher than its holding depth above its ground unless u_repose_only
// (CpuStabilizer::start_height).
float start_height(ivec3 t, vec4 cell) {
  float top = free_top(cell, texelFetch(u_depth, t, 0).r);
  return u_repose_only != 0 ? top : min(top, cell.x + texelFetch(u_hold, t, 0).r);
}

// Routing: the highest snow surface layer texel t (with cell `cell`) keeps,
// from u_stable, or its start value (start_height) with u_start.
float kept_height(ivec3 t, vec4 cell) {
  return u_start != 0 ? start_height(t, cell) : texelFetch(u_stable, t, 0).r;
}

// snow::land_in_column: the layer of column c on which snow at height h,
// resting on a support at height `support`, comes to rest, kLandBlocked or
// kLandVoid. On a landing, also that layer's cell and snow top. The snow tops
// are ground + depth, or with `kept` the heights the routing keeps
// (kept_height), as if the snow that will leave had left.
int landing(ivec2 c, float h, float support, bool kept, out vec4 land_cell, out float land_top) {
  land_cell = vec4(0.0);
  land_top = 0.0;
  if (!in_map(c)) return kLandVoid;
  for (int l = 0; l < u_layers; ++l) {
    vec4 cell = texelFetch(u_cells, ivec3(c, l), 0);
    int flags = int(cell.w);
    if ((flags & kCellSurface) == 0) {
      return l > 0 && (int(texelFetch(u_cells, ivec3(c, l - 1), 0).w) & kCellDown) == 0 ? kLandBlocked
                                                                                   : kLandVoid;
    }
    if (h >= cell.y) return kLandBlocked;
    float top =
        kept ? kept_height(ivec3(c, l), cell) : cell.x + texelFetch(u_depth, ivec3(c, l), 0).r;
    if (top <= h) {
      if ((flags & kCellSolid) != 0 || cell.y - support < u_rise) return kLandBlocked;
      land_cell = cell;
      land_top = top;
      return l;
    }
    if (h >= cell.x) return kLandBlocked;
  }
  return kLandBlocked;
}

int landing(ivec2 c, float h, float support, bool kept) {
  vec4 land_cell;
  float land_top;
  return landing(c, h, support, kept, land_cell, land_top);
}

uint texel_index(ivec2 c, int l) {
  return (uint(l) * uint(u_size.y) + uint(c.y)) * uint(u_size.x) + uint(c.x);
}

ivec3 texel_of_index(uint k) {
  uint w = uint(u_size.x), h = uint(u_size.y);
  return ivec3(int(k % w), int((k / w) % h), int(k / (w * h)));
}
