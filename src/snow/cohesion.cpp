// The cohesion of fresh snow (contract: snow/cohesion.h).
#include "snow/cohesion.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace snow {

Cohesion cohesion_of(SnowKind kind) {
  Cohesion c;  // fresh
  switch (kind) {
    case SnowKind::Powder:
      c.stand_height = 0.15f;
      c.hold_depth = 0.12f;
      c.hold_fall_deg = 8.0f;
      break;
    case SnowKind::Fresh:
      break;
    case SnowKind::Wet:
      c.stand_height = 1.0f;
      c.hold_depth = 0.35f;
      c.hold_fall_deg = 12.0f;
      break;
  }
  return c;
}

SnowKind snow_kind_from_name(const std::string& name) {
  if (name == "powder") return SnowKind::Powder;
  if (name == "fresh") return SnowKind::Fresh;
  if (name == "wet") return SnowKind::Wet;
  throw InputError("--snow must be powder, fresh or wet, got '" + name + "'");
}

const char* snow_kind_name(SnowKind kind) {
  switch (kind) {
    case SnowKind::Powder:
      return "powder";
    case SnowKind::Fresh:
      return "fresh";
    case SnowKind::Wet:
      return "wet";
  }
  return "fresh";
}

void check_cohesion(const Cohesion& c) {
  auto bad = [](const std::string& what) { throw InputError("snow cohesion: " + what); };
  if (!(c.stand_height >= 0.0f) || !std::isfinite(c.stand_height))
    bad("stand_height must be a finite number >= 0 metres, got " + std::to_string(c.stand_height));
  if (!(c.hold_depth > 0.0f) || !std::isfinite(c.hold_depth))
    bad("hold_depth must be a finite number > 0 metres, got " + std::to_string(c.hold_depth));
  if (!(c.hold_angle_deg >= 0.0f && c.hold_angle_deg <= 90.0f))
    bad("hold_angle_deg must be in 0..90 degrees, got " + std::to_string(c.hold_angle_deg));
  if (!(c.hold_fall_deg > 0.0f) || !std::isfinite(c.hold_fall_deg))
    bad("hold_fall_deg must be a finite number > 0 degrees, got " +
        std::to_string(c.hold_fall_deg));
}

float holding_depth(const Cohesion& c, float slope_deg, float grip) {
  const double h =
      double(grip) * double(c.hold_depth) *
      std::exp((double(c.hold_angle_deg) - double(slope_deg)) / double(c.hold_fall_deg));
  return float(std::min(h, double(kMaxHoldDepth)));
}

}  // namespace snow
