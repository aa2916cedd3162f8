// Wind transport of fallen snow (contract and model: snow/drift.h).
#include "snow/drift.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"
#include "plan/rules.h"
#include "snow/exposure.h"

namespace snow {
namespace {

// Lanes a settled drift spreads across at most, each way.
constexpr int kMaxSpread = 64;

// Lateral mixing passes per slab at most; beyond, the spread is less than
// mixing_length asks (maps far finer than a metre).
constexpr int kMaxMixPasses = 32;

// What the march reads per column, from the horizons of the surface.
struct Shelter {
  std::vector<float> rate;     // 1/m: share of the carried snow that settles per metre
  std::vector<float> speedup;  // capacity factor (>= 1)
  std::vector<float> room;     // m: how deep snow may settle there, up to the horizon line
};

// The share of the flux that an obstacle `h` metres high catches in its
// shelter: one as high as the drifting layer half, lower ones little (the
// ripples of the snow's own surface next to nothing).
float capture(float h, float layer) { return h * h / (h * h + layer * layer); }

// The rate (1/m) at which the flux settles at `x` metres into a shelter
// `zone` metres long whose triangle there has the weight `w` (1 at the
// obstacle, 0 at the zone's end), so that the share `c` of the flux that
// entered settles as that triangle. `towards`: the flux moves towards the
// obstacle (a windward face; x is the distance still to go), else away from
// it (a lee). The triangle's area is zone / 2.
float settling_rate(float zone, float x, float w, float c, bool towards) {
  x = std::clamp(x, 0.0f, zone);
  const float half = 0.5f * zone;
  // The triangle's part the flux has passed: from the zone's far end to x
  // in front, from the obstacle to x behind.
  const float passed = towards ? half - (x - x * x / (2.0f * zone)) : x - x * x / (2.0f * zone);
  const float rest = half - c * passed;
  return rest > 0.0f ? c * w / rest : 1e30f;
}

// `top` with what is narrower across the wind than 2 `radius` metres taken
// out: per column, the lowest surface within `radius` across the wind (NaN
// where the column has none). A post or a railing does not shelter: the
// flow closes behind it.
std::vector<float> without_narrow(const MapGrid& grid, const std::vector<float>& top,
                                  const glm::vec2& wind, float radius) {
  const Slabs slabs(grid, wind);
  const int lanes = slabs.lanes;
  const int reach = int(std::min(std::ceil(radius / slabs.width), float(lanes)));
  std::vector<float> out(top.size());
  std::vector<float> value(static_cast<size_t>(lanes));
  std::vector<int> window(static_cast<size_t>(lanes));  // a deque of lanes, values rising
  for (int sl = 0; sl < slabs.count; ++sl) {
    for (int t = 0; t < lanes; ++t) {
      const float z = top[slabs.column(sl, t)];
      value[size_t(t)] = std::isnan(z) ? std::numeric_limits<float>::infinity() : z;
    }
    // The lowest value over [c - reach, c + reach] for each centre c, as
    // the window's right end t runs across the slab.
    int head = 0, tail = 0;
    for (int t = 0; t < lanes + reach; ++t) {
      if (t < lanes) {
        while (tail > head && value[size_t(window[size_t(tail - 1)])] >= value[size_t(t)]) --tail;
        window[size_t(tail++)] = t;
      }
      while (window[size_t(head)] < t - 2 * reach) ++head;
      const int centre = t - reach;
      if (centre < 0) continue;
      const size_t c = slabs.column(sl, centre);
      out[c] = std::isnan(top[c]) ? top[c] : value[size_t(window[size_t(head)])];
    }
  }
  return out;
}

// The settling rate and the speed-up of every column (snow/drift.h).
Shelter shelter_of(const MapGrid& grid, const std::vector<float>& top, const DriftSettings& s) {
  const glm::vec2 wind = glm::normalize(s.direction), across(-wind.y, wind.x);
  const float slope = s.shelter_slope, c = s.windward_capture;
  // The shelters, of obstacles wider than twice the drifting layer, seen
  // from each column's own surface.
  const std::vector<float> wide = without_narrow(grid, top, wind, s.layer_height);
  Horizon lee = horizon_along(grid, wide, -wind, slope);
  Horizon front = horizon_along(grid, wide, wind, slope);
  for (Horizon* h : {&lee, &front}) {
    for (size_t k = 0; k < top.size(); ++k) {
      const float below = wide[k] - top[k];  // <= 0
      h->rise[k] += below;
      h->height[k] += below;
    }
  }
  const Horizon side_a = horizon_along(grid, top, across, slope);
  const Horizon side_b = horizon_along(grid, top, -across, slope);
  Shelter out;
  out.rate.assign(top.size(), 0.0f);
  out.speedup.assign(top.size(), 1.0f);
  out.room.assign(top.size(), 0.0f);
  for (size_t k = 0; k < top.size(); ++k) {
    float rate = 0.0f;
    // Behind a step of height h the flux settles as a triangle from the
    // step to h / slope; in front of a windward face, as one rising towards
    // it. A share of the flux settles: capture(h) of it behind, that times
    // windward_capture in front.
    if (lee.rise[k] > 0.0f && lee.height[k] > 0.0f) {
      const float h = lee.height[k], x = (h - lee.rise[k]) / slope;
      rate += settling_rate(h / slope, x, lee.rise[k] / h, capture(h, s.layer_height), false);
    }
    if (front.rise[k] > 0.0f && front.height[k] > 0.0f) {
      const float h = front.height[k], d = (h - front.rise[k]) / slope;
      rate += settling_rate(h / slope, d, front.rise[k] / h, c * capture(h, s.layer_height), true);
    }
    out.rate[k] = rate;
    // A shelter fills up to its horizon line, and then shelters no more.
    out.room[k] = std::max({0.0f, lee.rise[k], front.rise[k]});
    // Beside an obstacle (across the wind, within its shelter's reach) the
    // flow speeds up: fully at its side, not at all h / slope away.
    float side = 0.0f;
    for (const Horizon* h : {&side_a, &side_b}) {
      if (h->rise[k] > 0.0f && h->height[k] > 0.0f)
        side = std::max(side, std::min(1.0f, h->rise[k] / h->height[k]));
    }
    out.speedup[k] = 1.0f + s.speedup_gain * side;
  }
  // The flow speeds up and slows down over speedup_length along the wind:
  // the factor follows the obstacles' sides with that lag, so the capacity
  // (and the scour) has no step where an obstacle starts or ends.
  const Slabs slabs(grid, wind);
  const float keep = std::exp(-slabs.step / s.speedup_length);
  std::vector<float> prev(size_t(slabs.lanes), 1.0f), next(prev.size());
  for (int sl = 0; sl < slabs.count; ++sl) {
    for (int t = 0; t < slabs.lanes; ++t) {
      float before = 0.0f;
      for (const auto& [lane, w] : slabs.sources(t)) {
        before += w * (lane >= 0 && lane < slabs.lanes ? prev[size_t(lane)] : 1.0f);
      }
      const size_t c = slabs.column(sl, t);
      next[size_t(t)] = out.speedup[c] = before * keep + out.speedup[c] * (1.0f - keep);
    }
    prev.swap(next);
  }
  return out;
}

// Spreads the carried snow across the lanes of one slab (`z`: their
// surfaces, NaN where none): neighbouring lanes that both have a surface
// exchange `a` (<= 1/4) of their difference per pass.
void mix(std::vector<double>& flux, const std::vector<float>& z, int passes, double a) {
  const size_t n = flux.size();
  std::vector<double> moved(n);
  for (int p = 0; p < passes; ++p) {
    for (size_t t = 0; t + 1 < n; ++t) {
      moved[t] = std::isnan(z[t]) || std::isnan(z[t + 1]) ? 0.0 : a * (flux[t] - flux[t + 1]);
    }
    for (size_t t = 0; t + 1 < n; ++t) {
      flux[t] -= moved[t];
      flux[t + 1] += moved[t];
    }
  }
}

// The flux meeting a step up of `rise` metres (per lane; <= 0 or NaN: none)
// climbs it with the share layer^2 / (rise^2 + layer^2); the rest goes round
// the obstacle where a lane whose own step is at most `layer` lies within
// `rise` metres across the wind (half to each side that has one), and
// climbs too where none does. `z`: the lanes' surfaces (NaN: none); `width`:
// metres per lane.
void deflect(std::vector<double>& in, const std::vector<float>& z, const std::vector<float>& rise,
             float layer, float width) {
  const int lanes = int(in.size());
  std::vector<double> round(in.size(), 0.0);
  const auto free = [&](int t) {
    return t >= 0 && t < lanes && !std::isnan(z[size_t(t)]) && !(rise[size_t(t)] > layer);
  };
  for (int t = 0; t < lanes; ++t) {
    const float r = rise[size_t(t)];
    if (!(r > layer) || !(in[size_t(t)] > 0.0)) continue;
    const int reach = int(std::min(std::ceil(r / width), float(lanes)));
    int left = -1, right = -1;
    for (int d = 1; d <= reach && (left < 0 || right < 0); ++d) {
      if (left < 0 && free(t - d)) left = t - d;
      if (right < 0 && free(t + d)) right = t + d;
    }
    if (left < 0 && right < 0) continue;
    const double away = in[size_t(t)] * double(r * r) / double(r * r + layer * layer);
    in[size_t(t)] -= away;
    if (left >= 0 && right >= 0) {
      round[size_t(left)] += 0.5 * away;
      round[size_t(right)] += 0.5 * away;
    } else {
      round[size_t(left >= 0 ? left : right)] += away;
    }
  }
  for (size_t t = 0; t < in.size(); ++t) in[t] += round[t];
}

// Spreads what settled in one slab (`settled`, m^3 per lane) across the
// lanes, so that a drift's flanks are no steeper than `flank` (tan): each
// lane's share is laid as a tent around it, R lanes to each side with R^2 >=
// its height / (flank * width), over the lanes of its run (a lane's ground
// within `width` of its neighbour's; walls and columns without a surface
// end a run). Returns the depth (m) each lane gets; the sum is kept.
std::vector<double> spread_across(const std::vector<double>& settled,
                                  const std::vector<float>& ground, float width, float flank,
                                  double area) {
  const int lanes = int(settled.size());
  // The runs: lane t joins lane t - 1 where both lie on one level.
  const auto joined = [&](int t) {
    return t > 0 && !std::isnan(ground[size_t(t)]) && !std::isnan(ground[size_t(t - 1)]) &&
           std::abs(ground[size_t(t)] - ground[size_t(t - 1)]) <= width;
  };
  std::vector<int> last(settled.size());  // the last lane of each lane's run
  for (int t = lanes - 1; t >= 0; --t) {
    last[size_t(t)] = t + 1 < lanes && joined(t + 1) ? last[size_t(t + 1)] : t;
  }
  std::vector<double> out(settled.size(), 0.0);
  int first = 0;
  for (int t = 0; t < lanes; ++t) {
    if (!joined(t)) first = t;
    if (!(settled[size_t(t)] > 0.0)) continue;
    const double height = settled[size_t(t)] / area;
    const int reach = int(std::min(double(kMaxSpread),
                                   std::ceil(std::sqrt(height / (double(width) * double(flank))))));
    const int a = std::max(first, t - reach + 1), b = std::min(last[size_t(t)], t + reach - 1);
    double weights = 0.0;
    for (int u = a; u <= b; ++u) weights += double(reach - std::abs(u - t));
    for (int u = a; u <= b; ++u) {
      out[size_t(u)] += height * double(reach - std::abs(u - t)) / weights;
    }
  }
  return out;
}

// One part of the storm: capacity `q` (m^2 per metre of width) on open
// level ground.
void drift_part(const SnowMaps& maps, std::vector<float>& depth, const std::vector<float>& floor,
                double q, const DriftSettings& s, DriftResult& result) {
  const MapGrid& g = maps.grid;
  std::vector<float> top = top_surface(maps, depth);
  const Shelter shelter = shelter_of(g, top, s);
  const Slabs slabs(g, s.direction);
  const size_t lanes = size_t(slabs.lanes);
  const double area = double(g.texel) * double(g.texel);
  const double open = q * double(slabs.width);  // m^3 carried per lane on open level ground
  const double keep = std::exp(-double(slabs.step) / double(s.saturation_length));
  // Lateral mixing: the variance per slab in lanes^2, as passes of a <= 1/4.
  const double spread =
      double(s.mixing_length) * double(slabs.step) / (double(slabs.width) * double(slabs.width));
  // (Compared as doubles: on texels of a few nanometres the spread
  // overflows an int.)
  const double wanted = std::ceil(spread / 0.5);
  const int passes = wanted > 0.0 ? int(std::min(double(kMaxMixPasses), wanted)) : 0;
  const double a = passes > 0 ? std::min(0.25, spread / (2.0 * passes)) : 0.0;
  std::vector<double> in(lanes), out(lanes, 0.0);
  std::vector<float> z(lanes), z_prev(lanes, kNoSurface), rise(lanes), ground(lanes);
  std::vector<double> settled(lanes);
  for (int sl = 0; sl < slabs.count; ++sl) {
    for (size_t t = 0; t < lanes; ++t) z[t] = top[slabs.column(sl, int(t))];
    // What arrives from the slab before (or from beyond the maps), and the
    // step up it meets.
    for (int t = 0; t < int(lanes); ++t) {
      in[size_t(t)] = 0.0;
      rise[size_t(t)] = 0.0f;
      if (std::isnan(z[size_t(t)])) continue;
      float from = 0.0f, weight = 0.0f;
      for (const auto& [src, w] : slabs.sources(t)) {
        if (!(w > 0.0f)) continue;
        if (sl > 0 && src >= 0 && src < int(lanes) && !std::isnan(z_prev[size_t(src)])) {
          in[size_t(t)] += double(w) * out[size_t(src)];
          from += w * z_prev[size_t(src)];
          weight += w;
        } else {
          in[size_t(t)] += double(w) * open;
          result.entered += double(w) * open;
        }
      }
      if (weight > 0.0f) rise[size_t(t)] = z[size_t(t)] - from / weight;
    }
    // What the slab before sends where no surface is, or off the maps.
    if (sl > 0) {
      for (int t = 0; t < int(lanes); ++t) {
        if (std::isnan(z_prev[size_t(t)])) continue;
        for (const auto& [dst, w] : slabs.targets(t)) {
          if (w > 0.0f && (dst < 0 || dst >= int(lanes) || std::isnan(z[size_t(dst)])))
            result.left += double(w) * out[size_t(t)];
        }
      }
    }
    deflect(in, z, rise, s.layer_height, slabs.width);
    mix(in, z, passes, a);
    for (size_t t = 0; t < lanes; ++t) {
      out[t] = 0.0;
      settled[t] = 0.0;
      ground[t] = kNoSurface;
      if (std::isnan(z[t])) continue;
      const size_t c = slabs.column(sl, int(t));
      const size_t k = c;  // layer 0 comes first in the maps' layout
      const float old = std::max(depth[k], 0.0f);
      float now = old;
      const double carried = in[t];
      const float rate = shelter.rate[c];
      // Drifts grow to max_depth at most (EN 1991-1-3's cap on mu_w).
      const double space = std::max(0.0, double(s.max_depth) - double(old)) * area;
      if (rate > 0.0f) {
        const double settle = std::min({carried * -std::expm1(-double(rate) * double(slabs.step)),
                                        double(shelter.room[c]) * area, space});
        now = old + float(settle / area);
      } else {
        const double capacity = open * double(shelter.speedup[c]);
        const double target = capacity + (carried - capacity) * keep;
        if (target > carried) {  // erodes, down to the scour limit
          const double room = std::max(0.0, double(old) - double(floor[c])) * area;
          const double take = std::min(target - carried, room);
          now = std::max(floor[c], old - float(take / area));
          result.moved += double(old - now) * area;
        } else {
          now = old + float(std::min(carried - target, space) / area);
        }
      }
      // The flux takes what the float depth really gave or got; what
      // settled is laid across the lanes below.
      out[t] = carried - (double(now) - double(old)) * area;
      ground[t] = maps.ground[k];
      if (now > old) {
        settled[t] = (double(now) - double(old)) * area;
      } else {
        depth[k] = now;
      }
    }
    const std::vector<double> laid =
        spread_across(settled, ground, slabs.width, s.flank_slope, area);
    for (size_t t = 0; t < lanes; ++t) {
      if (laid[t] > 0.0) depth[slabs.column(sl, int(t))] += float(laid[t]);
    }
    z_prev.swap(z);
  }
  for (size_t t = 0; t < lanes; ++t) {
    if (!std::isnan(z_prev[t])) result.left += out[t];
  }
}

}  // namespace

DriftSettings drift_for_wind(const glm::vec2& wind, SnowKind kind, float fall_depth) {
  DriftSettings s;
  s.max_depth = float(plan::kDriftMaxCoefficient) * std::max(fall_depth, 0.0f);
  const double speed = glm::length(glm::dvec2(wind));
  const double threshold = kind == SnowKind::Powder ? plan::kDriftThresholdPowder
                           : kind == SnowKind::Wet  ? plan::kDriftThresholdWet
                                                    : plan::kDriftThresholdFresh;
  s.transport = float(plan::drift_transport(speed, threshold));
  if (s.transport > 0.0f) s.direction = wind / float(speed);
  return s;
}

void check_drift_settings(const DriftSettings& s) {
  const auto fail = [](const std::string& what) { throw InputError("wind transport: " + what); };
  const float len = std::abs(s.direction.x) + std::abs(s.direction.y);
  if (!std::isfinite(len)) fail("the direction must be finite");
  if (!(s.transport >= 0.0f && s.transport <= 1e6f)) fail("transport must be in 0..1e6 m");
  if (s.transport > 0.0f && !(len > 0.0f)) fail("the wind needs a direction");
  if (!(s.saturation_length > 0.0f && s.saturation_length <= 1e6f))
    fail("the saturation length must be in (0, 1e6] m");
  if (!(s.mixing_length >= 0.0f && s.mixing_length <= 1e3f))
    fail("the mixing length must be in 0..1000 m");
  if (!(s.shelter_slope >= 0.05f && s.shelter_slope <= 5.0f))
    fail("the shelter slope must be in 0.05..5");
  if (!(s.windward_capture >= 0.0f && s.windward_capture <= 1.0f))
    fail("the windward capture must be in 0..1");
  if (!(s.flank_slope > 0.0f && s.flank_slope <= 100.0f))
    fail("the flank slope must be in (0, 100]");
  if (!(s.max_depth > 0.0f)) fail("the drifts' depth limit must be > 0 m");
  if (!(s.max_scour >= 0.0f && s.max_scour <= 1.0f)) fail("the scour share must be in 0..1");
  if (!(s.layer_height > 0.0f && s.layer_height <= 1e3f))
    fail("the drifting layer's height must be in (0, 1000] m");
  if (!(s.speedup_gain >= 0.0f && s.speedup_gain <= 10.0f))
    fail("the speed-up gain must be in 0..10");
  if (!(s.speedup_length > 0.0f && s.speedup_length <= 1e6f))
    fail("the speed-up length must be in (0, 1e6] m");
  if (s.substeps < 1 || s.substeps > 64) fail("substeps must be in 1..64");
}

DriftResult drift_snow(const SnowMaps& maps, std::vector<float>& depth, float fall_depth,
                       const DriftSettings& settings) {
  check_drift_settings(settings);
  if (depth.size() != maps.ground.size())
    throw InputError("wind transport: depth does not match the maps");
  DriftResult result;
  if (!(settings.transport > 0.0f) || !(fall_depth > 0.0f) || maps.layers < 1) return result;
  const double q = double(fall_depth) * double(settings.transport) / double(settings.substeps);
  // The wind takes at most max_scour of the snow lying, and of the depth
  // that fell: a snowfall in many parts is scoured as one.
  std::vector<float> floor(maps.grid.texels());
  for (size_t c = 0; c < floor.size(); ++c) {
    const float d = std::max(depth[c], 0.0f);
    floor[c] = std::max(0.0f, d - settings.max_scour * std::min(d, fall_depth));
  }
  for (int part = 0; part < settings.substeps; ++part) {
    drift_part(maps, depth, floor, q, settings, result);
  }
  return result;
}

}  // namespace snow
