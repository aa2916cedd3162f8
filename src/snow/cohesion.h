#pragma once
// How much fresh snow holds where it fell: cohesive snow, not dry sand
// (Fearing 2000, section 5: cohesion lets snow stand steeper than its angle of
// repose and bridge gaps). Two limits per support texel, both vertical depths
// in metres:
//  - the holding depth on a slope: snow deeper than this slides off a
//    support of that slope, whatever its surface looks like (slab release
//    on the snow-support interface), and thinner snow clings. It falls by a
//    factor e per `hold_fall_deg` degrees of steeper slope, the form of the
//    maximum snow-holding depth that SnowSlide (Bernhardt & Schulz 2010)
//    fits to field data, with the level set so that 0.3 m of fresh snow on
//    roofs follows EN 1991-1-3's roof shape coefficient mu1 (0.8 up to 30
//    degrees, linear to 0 at 60) relative to a flat roof;
//  - the standing height: snow up to this deep stands at a free edge (a
//    table top, a wall cap, a car roof keeps its depth to the edge: a
//    pillow) and is never moved by the angle-of-repose relaxation. Deeper
//    snow above it, and loose snow that slid and piled up, relaxes at the
//    angle of repose. The critical height of a vertical cut in a cohesive
//    soil (Rankine: 4c / (rho g) for a friction angle near 0) with the
//    cohesion and density of fresh snow gives the order of metres; the
//    presets stay below it.
// GL-free: both stabilizers take the per-texel limits from here.
#include <string>
#include <vector>

namespace snow {

struct Cohesion {
  float stand_height = 0.5f;     // m: snow up to this deep stands at free edges (>= 0;
                                 // 0: loose snow, every edge relaxes to the repose angle)
  float hold_depth = 0.22f;      // m: the deepest snow holding on a support of hold_angle_deg
                                 // (> 0)
  float hold_angle_deg = 40.0f;  // degrees, the slope hold_depth is given for (0..90)
  float hold_fall_deg = 10.0f;   // degrees: the holding depth falls by a factor e per this
                                 // much steeper slope (> 0)
};

/// The kinds of snow `--snow` names, with their cohesion:
///  - powder: cold, dry, little cohesion: stands 0.15 m, sheds from
///    steeper roofs sooner;
///  - fresh (the default): calibrated to EN 1991-1-3 as above;
///  - wet: sticky, stands 1 m and clings to steeper supports.
enum class SnowKind { Powder, Fresh, Wet };
Cohesion cohesion_of(SnowKind kind);
/// "powder", "fresh" or "wet"; InputError naming the value otherwise.
SnowKind snow_kind_from_name(const std::string& name);
const char* snow_kind_name(SnowKind kind);

/// Grip of a support surface: its holding depth is multiplied by this.
/// Slippery surfaces (glass, metal, PV panels) shed sooner; rough ones (rock,
/// shingles, gravel roofs) hold more.
constexpr float kGripSlippery = 0.5f;
constexpr float kGripNormal = 1.0f;
constexpr float kGripRough = 2.0f;

/// Throws InputError naming the first field out of range.
void check_cohesion(const Cohesion& cohesion);

/// The holding depth (m, vertical) on a support whose slope is `slope_deg`
/// degrees (0 = level, 90 = vertical) and whose grip is `grip` (> 0):
/// grip * hold_depth * exp((hold_angle_deg - slope_deg) / hold_fall_deg),
/// capped at kMaxHoldDepth.
float holding_depth(const Cohesion& cohesion, float slope_deg, float grip);
/// Holding depths are capped here (m): deeper than any snow the tool lays.
constexpr float kMaxHoldDepth = 1.0e6f;

/// The grip of each scene object, by object index (SnowMaps::object);
/// objects past its end, and texels of no object, have kGripNormal.
using ObjectGrip = std::vector<float>;

}  // namespace snow
