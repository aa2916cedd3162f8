#pragma once
// Snow maps of a scene built in code for the tests of the CPU stages: the
// reference peel over the scene's bounds, no margin.
#include "snow/maps.h"
#include "snow/peel.h"
#include "snow/reference/peel_ref.h"

namespace snow::test {

/// The maps of `scene` at `texel` metres, the default layers.
inline SnowMaps maps_of(const Scene& scene, float texel) {
  PeelSettings peel;
  peel.texel = texel;
  peel.margin = 0.0f;
  return reference::peel_layers(scene, make_grid(scene.bounds, peel), peel.layers);
}

}  // namespace snow::test
