#pragma once
// The snowpack over time (snow/weather.h has the physics): per layer texel
// its depth, its snow water equivalent and its albedo, and the mass balance
// of the whole maps. The stabilizer and the wind move depth; account_moves
// turns what they moved into water equivalent: snow leaves a texel at that
// texel's density, and what arrives anywhere (or leaves the maps) has the
// density of all that left, so the water equivalent is conserved exactly:
// lying + melted + lost = fallen, whatever the densities.
// GL-free.
#include <vector>

#include <glm/glm.hpp>

#include "snow/maps.h"
#include "snow/weather.h"

namespace snow {

struct SnowPack {
  std::vector<float> depth;   // m per layer texel (maps' layout), >= 0
  std::vector<float> swe;     // m of water per layer texel, >= 0; 0 where depth is 0
  std::vector<float> albedo;  // per layer texel, kOldAlbedo..kFreshAlbedo where snow lies
  // Mass balance over the maps, m^3 of water (texel area x metres of water).
  double fallen = 0.0;  // fell as snow (and the wind carried in)
  double melted = 0.0;  // left as meltwater
  double lost = 0.0;    // left the maps (off an edge, into the void, the wind's)

  /// An empty pack for `maps`.
  static SnowPack empty(const SnowMaps& maps);
  /// m^3 of water lying on the maps.
  double lying(const SnowMaps& maps) const;
  /// Snow load on each layer texel, kN/m^2 (water equivalent x g).
  std::vector<float> load() const;
  /// Density of each layer texel, kg/m^3 (0 where no snow lies).
  std::vector<float> density() const;
};

/// Standard gravity, m/s^2 (snow loads).
constexpr float kGravity = 9.80665f;

/// Fresh snow: swe_m metres of water at `density` kg/m^3 times coverage[k]
/// on each layer texel; albedo refreshed (aged_albedo). Texels without a
/// surface take none.
void add_fresh_snow(SnowPack& pack, const SnowMaps& maps, const std::vector<float>& coverage,
                    float swe_m, float density);

/// The depth after the stabilizer and the wind moved snow (`after`, same
/// layout): each texel's water equivalent follows its new depth as above.
/// Returns the m^3 of water that left the maps (negative when the wind
/// carried more in than left), also added to pack.lost.
double account_moves(SnowPack& pack, const SnowMaps& maps, const std::vector<float>& after);

/// The sun and the weather of one step for melt_and_settle.
struct StepSun {
  glm::vec3 direction{0.0f, 1.0f, 0.0f};       // unit, towards the sun (world, +Y up)
  float elevation_deg = -90.0f;                // below the horizon: no sunshine
  const std::vector<float>* sunlit = nullptr;  // per layer texel 0..1 (null: all lit)
};

/// One step of `step.hours`: melt (from the air temperature, the shortwave
/// each texel absorbs by its slope, aspect, shadow and albedo, and the rain
/// `rain_m` metres), settling and albedo ageing. Meltwater leaves the pack.
void melt_and_settle(SnowPack& pack, const SnowMaps& maps, const WeatherStep& step, float rain_m,
                     const StepSun& sun);

}  // namespace snow
