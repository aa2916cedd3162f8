// Tracks in the live preview (live/live_sim.h): --track sources and the
// brush pressed into the snow lying now.
#include <algorithm>
#include <cmath>

#include "live/live_weather.h"

namespace snow::live {

TrackResult LiveSim::make_tracks(const std::vector<TrackSource>& sources,
                                 const TrackSettings& settings) {
  return press(depth(), sources, settings);
}

std::optional<TrackResult> LiveSim::brush(glm::vec3 origin, glm::vec3 direction, float radius,
                                          TrackMode mode, const TrackSettings& settings) {
  const std::vector<float> lying = depth();
  const std::optional<glm::vec3> at = hit(lying, origin, direction);
  if (!at) return std::nullopt;
  TrackSource disc;
  disc.name = "brush";
  disc.mode = mode;
  disc.segments = {*at, *at};
  disc.width = 2.0f * radius;
  return press(lying, {disc}, settings);
}

TrackResult LiveSim::press(const std::vector<float>& lying, const std::vector<TrackSource>& sources,
                           const TrackSettings& settings) {
  SnowPack settled;
  SnowPack* pack = &settled;
  if (weather_) {
    account_moves(weather_->pack, maps_, lying);  // sync_snowpack, on the depth read
    pack = &weather_->pack;
  } else {
    settled = settled_pack(maps_, lying);
  }
  const TrackResult result = snow::make_tracks(maps_, *pack, sources, settings);
  replace_depth(pack->depth);
  return result;
}

std::optional<glm::vec3> LiveSim::pick(glm::vec3 origin, glm::vec3 direction) const {
  return hit(depth(), origin, direction);
}

std::optional<glm::vec3> LiveSim::hit(const std::vector<float>& lying, glm::vec3 origin,
                                      glm::vec3 direction) const {
  const MapGrid& g = maps_.grid;
  if (g.texels() == 0 || !(glm::length(direction) > 0.0f)) return std::nullopt;
  direction = glm::normalize(direction);
  // The span of the ray over the maps' rectangle (slab test in x and z).
  float t0 = 0.0f, t1 = 1e30f;
  const glm::vec2 lo = g.origin, hi = g.origin + g.texel * glm::vec2(g.width, g.height);
  for (int axis = 0; axis < 2; ++axis) {
    const float o = axis == 0 ? origin.x : origin.z, d = axis == 0 ? direction.x : direction.z;
    const float a = axis == 0 ? lo.x : lo.y, b = axis == 0 ? hi.x : hi.y;
    if (std::abs(d) < 1e-12f) {
      if (o < a || o > b) return std::nullopt;
      continue;
    }
    const float ta = (a - o) / d, tb = (b - o) / d;
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  if (!(t0 <= t1)) return std::nullopt;
  const float step = 0.5f * g.texel;
  for (float t = t0; t <= t1; t += step) {
    const glm::vec3 p = origin + t * direction;
    const int i = std::clamp(int((p.x - g.origin.x) / g.texel), 0, g.width - 1);
    const int j = std::clamp(int((p.z - g.origin.y) / g.texel), 0, g.height - 1);
    const size_t k = maps_.index(0, i, j);
    if (std::isnan(maps_.ground[k])) continue;
    if (p.y <= maps_.ground[k] + lying[k]) return p;
  }
  return std::nullopt;
}

}  // namespace snow::live
