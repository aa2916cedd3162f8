// The snowpack's bookkeeping (snow/snowpack.h).
#include "snow/snowpack.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace snow {
namespace {

/// Water equivalent below this (m) is no snow: rounding residues.
constexpr float kNoSnowSwe = 1e-9f;

double texel_area(const SnowMaps& maps) {
  return double(maps.grid.texel) * double(maps.grid.texel);
}

void check_size(const SnowMaps& maps, size_t n, const char* what) {
  if (n != maps.ground.size()) {
    throw InputError(std::string("snowpack: ") + what + " has " + std::to_string(n) +
                     " values, the maps have " + std::to_string(maps.ground.size()));
  }
}

}  // namespace

SnowPack SnowPack::empty(const SnowMaps& maps) {
  SnowPack pack;
  pack.depth.assign(maps.ground.size(), 0.0f);
  pack.swe.assign(maps.ground.size(), 0.0f);
  pack.albedo.assign(maps.ground.size(), kFreshAlbedo);
  return pack;
}

double SnowPack::lying(const SnowMaps& maps) const {
  double sum = 0.0;
  for (float s : swe) sum += double(s);
  return sum * texel_area(maps);
}

std::vector<float> SnowPack::load() const {
  std::vector<float> out(swe.size());
  // kg/m^2 of water = swe * kWaterDensity; times g in N, over 1000 in kN.
  for (size_t k = 0; k < swe.size(); ++k) out[k] = swe[k] * kWaterDensity * kGravity / 1000.0f;
  return out;
}

std::vector<float> SnowPack::density() const {
  std::vector<float> out(swe.size(), 0.0f);
  for (size_t k = 0; k < swe.size(); ++k) {
    if (depth[k] > 0.0f) out[k] = swe[k] * kWaterDensity / depth[k];
  }
  return out;
}

void add_fresh_snow(SnowPack& pack, const SnowMaps& maps, const std::vector<float>& coverage,
                    float swe_m, float density) {
  check_size(maps, coverage.size(), "coverage");
  if (!(swe_m > 0.0f)) return;
  const float depth_m = swe_m * kWaterDensity / density;
  double added = 0.0;
  for (size_t k = 0; k < coverage.size(); ++k) {
    const float c = coverage[k];
    if (!(c > 0.0f) || std::isnan(maps.ground[k])) continue;
    const float s = c * swe_m;
    pack.albedo[k] = pack.swe[k] > 0.0f ? aged_albedo(pack.albedo[k], 0.0, false, s) : kFreshAlbedo;
    pack.swe[k] += s;
    pack.depth[k] += c * depth_m;
    added += double(s);
  }
  pack.fallen += added * texel_area(maps);
}

double account_moves(SnowPack& pack, const SnowMaps& maps, const std::vector<float>& after) {
  check_size(maps, after.size(), "depth");
  // What left: depth and water, and the albedo it carries (water-weighted).
  double left_depth = 0.0, left_swe = 0.0, left_albedo = 0.0, pack_depth = 0.0, pack_swe = 0.0;
  for (size_t k = 0; k < after.size(); ++k) {
    const float d0 = pack.depth[k], d1 = std::max(after[k], 0.0f);
    pack_depth += double(d0);
    pack_swe += double(pack.swe[k]);
    if (d1 < d0) {
      const double s = double(pack.swe[k]) * double(d0 - d1) / double(d0);
      left_depth += double(d0 - d1);
      left_swe += s;
      left_albedo += s * double(pack.albedo[k]);
    }
  }
  // Water per metre of moved snow: that of what left, or where nothing left
  // (the wind only carried snow in), the pack's mean.
  const double per_depth = left_depth > 0.0   ? left_swe / left_depth
                           : pack_depth > 0.0 ? pack_swe / pack_depth
                                              : double(fresh_snow_density(0.0f)) / kWaterDensity;
  const float moved_albedo = left_swe > 0.0 ? float(left_albedo / left_swe) : kFreshAlbedo;
  double arrived_swe = 0.0;
  for (size_t k = 0; k < after.size(); ++k) {
    const float d0 = pack.depth[k], d1 = std::max(after[k], 0.0f);
    if (d1 < d0) {
      pack.swe[k] = d1 > 0.0f ? float(double(pack.swe[k]) * double(d1) / double(d0)) : 0.0f;
    } else if (d1 > d0) {
      const double s = double(d1 - d0) * per_depth;
      const double total = double(pack.swe[k]) + s;
      pack.albedo[k] =
          float((double(pack.albedo[k]) * double(pack.swe[k]) + double(moved_albedo) * s) / total);
      pack.swe[k] = float(total);
      arrived_swe += s;
    }
    pack.depth[k] = d1;
  }
  const double lost = (left_swe - arrived_swe) * texel_area(maps);
  pack.lost += lost;
  return lost;
}

void melt_and_settle(SnowPack& pack, const SnowMaps& maps, const WeatherStep& step, float rain_m,
                     const StepSun& sun) {
  if (sun.sunlit) check_size(maps, sun.sunlit->size(), "sunlit share");
  double melted = 0.0;
  for (size_t k = 0; k < pack.swe.size(); ++k) {
    const float swe = pack.swe[k];
    if (!(swe > 0.0f) || !(pack.depth[k] > 0.0f)) continue;
    const glm::vec3 n = maps.normal[k];
    const float length = glm::length(n);
    const float cos_incidence = length > 0.0f ? glm::dot(n, sun.direction) / length : 0.0f;
    const float lit = sun.sunlit ? (*sun.sunlit)[k] : 1.0f;
    const float radiation = shortwave(sun.elevation_deg, cos_incidence, lit, step.cloud);
    const float melt =
        melt_swe(step.temp_c, (1.0f - pack.albedo[k]) * radiation, step.hours, rain_m);
    const bool melting = melt > 0.0f;
    const float left = std::max(swe - melt, 0.0f);
    melted += double(swe - left);
    if (left < kNoSnowSwe) {
      melted += double(left);
      pack.swe[k] = pack.depth[k] = 0.0f;
      pack.albedo[k] = kFreshAlbedo;
      continue;
    }
    const float density = swe * kWaterDensity / pack.depth[k];
    // Snow compacts; it never loosens again (a cold spell after a thaw).
    const float settled = std::max(density, settled_density(density, step.hours, melting));
    pack.swe[k] = left;
    pack.depth[k] = left * kWaterDensity / settled;
    pack.albedo[k] = aged_albedo(pack.albedo[k], step.hours, melting, 0.0f);
  }
  pack.melted += melted * texel_area(maps);
}

}  // namespace snow
