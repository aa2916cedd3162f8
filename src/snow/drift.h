#pragma once
// Wind transport of fallen snow: erosion where the wind is free, transport
// downwind, deposition in the shelter of obstacles. Mass-conserving over the
// maps' top surface (layer 0), between the snowfall's addition and the
// stabilizer (snow/accumulate.h).
//
// The model is a saturation-length flux model (as dune and drifting-snow
// models write it, e.g. Sauermann et al. 2001; Fearing 2000 and Cordonnier
// et al. 2018 for snow on scenes), marched slab by slab along the wind
// (snow/exposure.h's Slabs): the snow the wind carries per lane relaxes
// towards the wind's capacity over saturation_length, eroding where it
// carries less and settling where it carries more. A column loses at most
// max_scour of its snow and of fall_depth (wind-packed snow resists), and no
// drift grows deeper than max_depth. The capacity on open level ground is
// the storm's (transport, the planner's from the wind speed above the snow's
// threshold); open ground in equilibrium neither gains nor loses. Beside
// obstacles the flow speeds up (capacity x up to 1 + speedup_gain, following
// them along the wind over speedup_length). In their shelter (the horizons
// at shelter_slope, over obstacles wider across the wind than twice
// layer_height: the flow closes behind posts and rails) the carried snow
// settles whatever the capacity, as
// EN 1991-1-3 draws the drift at a step (section 5.3.6: a triangle of
// length 2h): behind an obstacle of height h the share
// h^2 / (h^2 + layer_height^2) of what arrives, as a triangle falling from
// it to h / shelter_slope downwind; before a windward face windward_capture
// times that share, as a triangle rising towards it; a shelter fills up to
// its horizon line at most. Flux that meets a step up of height r climbs it
// with the share layer_height^2 / (r^2 + layer_height^2); the rest goes
// round the obstacle to the nearest lane beside it within r, or over where
// none is. What settles spreads across the wind so that a drift's flanks
// are no steeper than flank_slope. The flux spreads across the wind too
// (turbulent mixing, mixing_length). The storm runs in `substeps` parts, each on the surface
// the earlier parts left, so drifts fill their shelter.
//
// The world goes on past the maps: flux enters over the upwind border (and
// past columns without a surface) at the capacity, and what crosses the
// downwind border or falls where no surface is leaves; DriftResult counts
// both, so what lies plus what left equals what fell plus what entered.
#include <vector>

#include <glm/glm.hpp>

#include "plan/rules.h"
#include "snow/cohesion.h"
#include "snow/maps.h"

namespace snow {

// The defaults are the planner's (plan/rules.h, "Wind transport").
struct DriftSettings {
  glm::vec2 direction{1.0f, 0.0f};  // where the wind blows to (x, z), any nonzero length
  float transport = 0.0f;           // metres: the storm's capacity on open level ground over the
                           // whole snowfall, as the length of fallen snow it carries (volume
                           // per metre of width over the fallen depth); 0: no transport
                           // (0..1e6)
  float saturation_length = float(plan::kDriftSaturationLength);  // m: the flux relaxes to
                                                                  // the capacity over this
                                                                  // (> 0)
  float mixing_length = float(plan::kDriftMixingLength);          // m: the carried snow's variance
                                                                  // across the wind grows by this
                                                                  // many m^2 per metre (>= 0)
  float shelter_slope = float(plan::kDriftShelterSlope);          // tan: an obstacle of height h
                                                                  // shelters h / this up- and
                                                                  // downwind (0.05..5)
  float windward_capture = float(plan::kDriftWindwardCapture);    // share (0..1) of the flux
                                                                  // reaching a windward face
                                                                  // that settles before it
  float layer_height = float(plan::kDriftLayerHeight);            // m: an obstacle h high catches
                                                        // h^2 / (h^2 + this^2) of the flux
                                                        // in its shelter (> 0)
  float speedup_gain = float(plan::kDriftSpeedupGain);      // capacity gain (0..10) beside
                                                            // obstacles
  float speedup_length = float(plan::kDriftSpeedupLength);  // m (> 0): the gain follows the
                                                            // obstacles along the wind over
                                                            // this distance
  float flank_slope = float(plan::kDriftFlankSlope);        // tan (0..100]: what settles spreads
                                                            // across the wind so that the drift's
                                                            // flanks are no steeper than this
  float max_depth = 1e30f;  // m: no drift grows deeper than this (the planner's:
                            // plan::kDriftMaxCoefficient times the fallen depth)
  float max_scour = float(plan::kDriftMaxScour);  // share (0..1): a column loses at most
                                                  // this much of its snow and of the depth
                                                  // that fell
  int substeps = plan::kDriftSubsteps;            // parts of the storm (1..64)
};

struct DriftResult {
  double entered = 0.0;  // m^3 carried in over the maps' border or past columns without surface
  double left = 0.0;     // m^3 carried off the maps or into columns without surface
  double moved = 0.0;    // m^3 eroded (and carried) in all
};

/// Moves the snow of layer 0 in `depth` (maps' layout, metres; the other
/// layers are left as they are) as a storm of `settings` blowing over snow
/// fallen `fall_depth` metres deep on open ground. Same inputs, same bytes.
/// Does nothing where transport or fall_depth is 0. Throws InputError for
/// settings out of range or a size mismatch.
DriftResult drift_snow(const SnowMaps& maps, std::vector<float>& depth, float fall_depth,
                       const DriftSettings& settings);

/// The planner's storm for a wind of `wind` (x, z, m/s) over `fall_depth`
/// metres of snow of `kind` (plan/rules.h, "Wind transport"): no transport
/// at or below the kind's threshold speed.
DriftSettings drift_for_wind(const glm::vec2& wind, SnowKind kind, float fall_depth);

/// Throws InputError naming the first setting out of range.
void check_drift_settings(const DriftSettings& settings);

}  // namespace snow
