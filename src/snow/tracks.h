#pragma once
// Tracks in the snow: tyre tracks, footprints and cleared paths, pressed
// into the snowpack after it fell (or at an hour of a weather run).
//
// A source is a contact shape (triangles, whose underside presses, or
// centre lines of a width) that goes through a list of poses (its
// animation, or its rest pose alone). At each pose the contact rests on the
// snow it presses: it is lowered or raised as a whole until its lowest part
// reaches the pressed snow's floor (a press: the compacted snow under it; a
// clear: the ground), so a tread or a sole prints its shape and a
// contact modelled on the bare ground rides on the snow. A column takes the
// lowest floor of all poses. The surface pressed is the highest layer whose
// ground lies no more than kContactReach above the contact's underside, the
// source's own surfaces (its object at rest) skipped.
//
// Pressing (rut depth after Richmond, Shoop and Blaisdell 1995, CRREL
// Report 95-1: a rut compacts the snow under it to a final density): snow
// of density rho under a contact of pressure P compacts to
//   rho_f = kMaxCompactedDensity - (kMaxCompactedDensity - rho) * exp(-P / kCompactionPressure)
// (the density under a rapid load levels off near 550 kg/m^3, Abele and Gow
// 1975). Of the snow the contact pushes below the old surface, the share
// `displaced_share` is pushed aside into berms and the rest compacts in the
// column, so a contact pressing to the floor leaves
//   d' = d * rho * (1 - s) / (rho_f - s * rho)
// of snow at density rho_f (pressed_depth). Where the contact's floor lies
// higher (a tread's groove, the edge of a wheel), the column keeps what is
// below the floor, denser by what it kept. Snow already at rho_f or denser
// does not compact again.
// Clearing (a shovel, a plough) takes every bit of snow above the floor.
// The snow pushed aside or cleared goes to the nearest texel outside the
// tracks on the same surface, and from there spreads away from the track
// over a band as wide as its volume needs to stand at the repose angle:
// berms beside a press peak at the track's edge (a triangle of slope
// tan(repose)), piles beside a cleared path are cones' sections with both
// sides at the repose angle, away from the edge. Water is conserved exactly:
// what a column keeps plus what it sends equals what it held (a track with
// nowhere to put its snow, walled in on all sides, leaves it as it was).
// GL-free.
#include <cstddef>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "scene/scene.h"
#include "snow/maps.h"
#include "snow/snowpack.h"

namespace snow {

/// Density reached under a rapid load that never ends, kg/m^3 (Abele and
/// Gow 1975: compacted snow levels off near 0.55 g/cm^3).
constexpr float kMaxCompactedDensity = 550.0f;
/// Pressure scale of the compaction, kPa: each kCompactionPressure of load
/// brings the density e times closer to kMaxCompactedDensity.
constexpr float kCompactionPressure = 100.0f;
/// A contact's underside may lie this far below the surface it presses, m
/// (a wheel modelled sunk into the ground still presses the ground's snow).
constexpr float kContactReach = 0.25f;
/// Density of the snow a run without weather lays, kg/m^3: fresh snow
/// settled for a few days (snow/weather.h's settling).
constexpr float kSettledSnowDensity = 150.0f;

enum class TrackMode {
  Press,  // compact the snow under the contact, push a share aside into berms
  Clear,  // take all the snow above the contact's floor into piles beside it
};

/// One thing that moves through the snow.
struct TrackSource {
  std::string name;  // for messages
  TrackMode mode = TrackMode::Press;
  std::vector<glm::vec3> triangles;  // world (m, +Y up), 3 per triangle, at rest
  std::vector<glm::vec3> segments;   // world, 2 per segment: centre lines of `width`, at rest
  float width = 0.0f;                // m, the lines' width (> 0 where segments are given)
  std::vector<glm::mat4> poses;      // rest -> world at each place it goes; empty: rest only
  int object = -1;                   // its triangles' scene object (SnowMaps::object), -1: none
};

struct TrackSettings {
  float pressure_kpa = 200.0f;   // contact pressure of pressing sources, kPa (> 0)
  float displaced_share = 0.2f;  // share of a rut's snow pushed aside into berms, 0..1
  float repose_deg = 38.0f;      // slope of berms and piles, degrees (1..89)
};

/// What a make_tracks call did, water equivalent in m^3. lying + compacted
/// + moved = fallen (to float rounding).
struct TrackResult {
  double fallen = 0.0;     // lying on the maps before
  double lying = 0.0;      // in the texels the tracks did not touch, as it lay
  double compacted = 0.0;  // kept by the pressed and cleared texels
  double moved = 0.0;      // pushed aside or cleared into berms and piles
  size_t pressed = 0;      // layer texels pressed
  size_t cleared = 0;      // layer texels cleared
  size_t poses = 0;        // contact poses pressed, all sources
};

/// Density (kg/m^3) that snow of `density` reaches under `pressure_kpa`
/// (the formula above); `density` itself where that is denser already.
float compacted_density(float density, float pressure_kpa);

/// Depth (m) that snow `depth` deep of `density` keeps under a contact of
/// `pressure_kpa` pressing to the floor, `displaced_share` of the rut pushed
/// aside (the formula above); `depth` where it does not compact.
float pressed_depth(float depth, float density, float pressure_kpa, float displaced_share);

/// The snow a run without weather laid, `depth` per layer texel (the maps'
/// layout), as a pack at kSettledSnowDensity; fallen is what lies.
SnowPack settled_pack(const SnowMaps& maps, const std::vector<float>& depth);

/// Poses along `moves` (rest -> world, in order) such that no point of
/// `bounds` (rest, world) moves more than `spacing` metres (> 0) between
/// consecutive poses: each interval is cut evenly, its matrices blended
/// linearly. At most `max_poses` poses; InputError naming `name` beyond.
std::vector<glm::mat4> track_poses(const std::vector<glm::mat4>& moves, const Bounds& bounds,
                                   float spacing, size_t max_poses, const std::string& name);

/// Presses and clears `sources` into `pack` (depth and swe change; albedo
/// stays) on `maps`. `compaction`, when given, receives per layer texel the
/// share of its depth the tracks took (1 - depth after / depth before; 1
/// where cleared; 0 where untouched). Throws InputError for a source
/// without a shape, segments without a width, or settings out of range.
TrackResult make_tracks(const SnowMaps& maps, SnowPack& pack,
                        const std::vector<TrackSource>& sources, const TrackSettings& settings,
                        std::vector<float>* compaction = nullptr);

}  // namespace snow
