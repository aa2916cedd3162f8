// Wind (issue 51): the exposure measure the transport builds on, against the
// geometry of a cube in a field.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "core/error.h"
#include "scene/builder.h"
#include "snow/exposure.h"
#include "snow/peel.h"
#include "snow/reference/peel_ref.h"

namespace snow {
namespace {

// A 2 m cube on a 40 m field, 0.1 m texels, wind along +x: Winstral's Sx is
// about the angle the cube's top makes seen from the lee (atan(2 / 2) = 45
// degrees 2 m behind it), zero in the open field upwind, and below zero at
// the cube top's windward edge, which looks down on the field.
TEST(Wind, UpwindSlopeSheltersTheLeeAndExposesTheWindwardEdge) {
  SceneBuilder b;
  b.add_plane("Field", 0.0f, glm::vec2(-20.0f), glm::vec2(20.0f));
  b.add_box("Cube", glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 2.0f, 1.0f));
  const Scene scene = b.build();
  PeelSettings peel;
  peel.texel = 0.1f;
  peel.margin = 0.0f;
  const SnowMaps maps = reference::peel_layers(scene, make_grid(scene.bounds, peel), peel.layers);
  const std::vector<float> depth(maps.ground.size(), 0.0f);
  const std::vector<float> sx = upwind_slope(maps, depth, glm::vec2(5.0f, 0.0f), 100.0f);
  const auto at = [&](float x, float z) {
    const int i = int((x - maps.grid.origin.x) / maps.grid.texel);
    const int j = int((z - maps.grid.origin.y) / maps.grid.texel);
    return sx[size_t(j) * size_t(maps.grid.width) + size_t(i)];
  };
  std::printf("Sx: lee 2 m %.1f, lee 8 m %.1f, open field %.2f, windward edge %.2f degrees\n",
              at(3.0f, 0.0f), at(9.0f, 0.0f), at(-8.0f, 0.0f), at(-0.95f, 0.0f));
  EXPECT_NEAR(at(3.0f, 0.0f), 45.0f, 5.0f);
  EXPECT_NEAR(at(9.0f, 0.0f), std::atan(2.0f / 8.0f) * 180.0f / float(M_PI), 3.0f);
  EXPECT_NEAR(at(-8.0f, 0.0f), 0.0f, 0.01f);
  EXPECT_LT(at(-0.95f, 0.0f), 0.0f);
  EXPECT_THROW(upwind_slope(maps, depth, glm::vec2(0.0f), 100.0f), InputError);
}

}  // namespace
}  // namespace snow
