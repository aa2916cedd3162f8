// Fall directions of the coverage stage (snow/coverage.h): the mean
// direction from wind and fall speed, and K directions over the cone of
// flake flutter around it (Fearing, "Computer Modelling of Fallen Snow",
// SIGGRAPH 2000, section 4.1). Direction sampling: stratified in
// cos(angle) with a golden-ratio azimuth sequence (a jittered spherical
// Fibonacci pattern), uniform in solid angle over the cone.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "core/error.h"
#include "snow/coverage.h"
#include "snow/coverage/internal.h"

namespace snow {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kGoldenFraction = 0.6180339887498949;  // frac of the golden ratio
constexpr uint64_t kJitterStream = 0xD1B54A32D192ED03ull;

/// splitmix64 (Steele, Lea and Flood 2014): tiny, fast, same stream everywhere.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1), 53 bits.
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  uint64_t state_;
};

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace

namespace cov {

void validate_settings(const CoverageSettings& s) {
  if (s.directions < 1 || s.directions > 4096) {
    throw InputError("directions must be in 1..4096, got " + std::to_string(s.directions));
  }
  if (!(s.flutter_deg >= 0.0f && s.flutter_deg <= 60.0f)) {
    throw InputError("flutter must be in 0..60 degrees, got " + number(s.flutter_deg));
  }
  if (s.batch < 0 || s.batch > kMaxBatch) {
    throw InputError("shadow-map batch must be in 1..32 (0: automatic), got " +
                     std::to_string(s.batch));
  }
  if (!std::isfinite(s.bias)) throw InputError("shadow bias must be finite");
  if (s.method != "auto" && s.method != "shadow-maps" && s.method != "rays" &&
      s.method != "cpu-rays" && s.method != "cpu-shadow-maps") {
    throw InputError(
        "coverage method must be auto, shadow-maps, rays, cpu-rays or cpu-shadow-maps, got '" +
        s.method + "'");
  }
  mean_fall_direction(s);  // checks the wind and the fall speed
}

}  // namespace cov

glm::vec3 mean_fall_direction(const CoverageSettings& s) {
  if (!(s.fall_speed > 0.0f) || !std::isfinite(s.fall_speed)) {
    throw InputError("flake fall speed must be a finite number > 0 m/s, got " +
                     number(s.fall_speed));
  }
  if (!std::isfinite(s.wind.x) || !std::isfinite(s.wind.y)) {
    throw InputError("wind must be finite");
  }
  const double wind = glm::length(glm::dvec2(s.wind));
  if (wind > double(kMaxWind)) {
    throw InputError("wind of " + number(wind) + " m/s is over the " + number(kMaxWind) +
                     " m/s snowmodel takes (--wind)");
  }
  const double cap = std::max(0.0, double(kMaxFallAngleDeg) - double(s.flutter_deg)) * kPi / 180.0;
  const double tilt = std::min(std::atan2(wind, double(s.fall_speed)), cap);
  const glm::dvec2 along = wind > 0.0 ? glm::dvec2(s.wind) / wind : glm::dvec2(0.0);
  return glm::vec3(glm::dvec3(along.x * std::sin(tilt), -std::cos(tilt), along.y * std::sin(tilt)));
}

std::vector<glm::vec3> fall_directions(const CoverageSettings& s) {
  cov::validate_settings(s);
  const glm::dvec3 m(mean_fall_direction(s));
  // Orthonormal frame (m, e1, e2).
  const glm::dvec3 ref = std::abs(m.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 0, 1);
  const glm::dvec3 e1 = glm::normalize(glm::cross(m, ref));
  const glm::dvec3 e2 = glm::cross(m, e1);
  const double cos_max = std::cos(double(s.flutter_deg) * kPi / 180.0);
  SplitMix64 rng(s.seed);
  const double rotation = rng.uniform();
  const int k_count = s.directions;
  std::vector<glm::vec3> out;
  out.reserve(size_t(k_count));
  for (int k = 0; k < k_count; ++k) {
    const double u1 = (k + rng.uniform()) / k_count;  // stratum k, jittered
    const double cos_t = 1.0 - u1 * (1.0 - cos_max);
    const double sin_t = std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t));
    double turn = k * kGoldenFraction + rotation + (rng.uniform() - 0.5) / k_count;
    turn -= std::floor(turn);
    const double phi = 2.0 * kPi * turn;
    const glm::dvec3 d = cos_t * m + sin_t * (std::cos(phi) * e1 + std::sin(phi) * e2);
    out.push_back(glm::vec3(glm::normalize(d)));
  }
  return out;
}

std::vector<glm::vec2> shadow_origin_jitter(const CoverageSettings& s) {
  SplitMix64 rng(s.seed ^ kJitterStream);
  std::vector<glm::vec2> out(size_t(std::max(0, s.directions)));
  for (glm::vec2& j : out) {
    const double x = rng.uniform();
    const double y = rng.uniform();
    j = glm::vec2(float(x), float(y));
    // float rounding of values just below 1 must not reach 1.
    j = glm::min(j, glm::vec2(std::nextafter(1.0f, 0.0f)));
  }
  return out;
}

int shadow_batch(const CoverageSettings& settings, double shadow_texels) {
  return plan::choose_shadow_batch(settings.batch, settings.directions, shadow_texels,
                                   cov::kMaxBatch);
}

Bvh::Build coverage_bvh_build(size_t triangles, size_t receivers) {
  return plan::coverage_bvh_morton(triangles, receivers) ? Bvh::Build::Morton : Bvh::Build::Sah;
}

}  // namespace snow
