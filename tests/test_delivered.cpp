// Scenes as artists deliver them (sky domes and boxes, units, axes): what the
// tool recognises in them before it snows them.
#include <gtest/gtest.h>

#include <vector>

#include "plan/rules.h"
#include "scene/enclosure.h"
#include "support/enclosures.h"

namespace snow {
namespace {

using test::Sky;

std::vector<int> enclosures(Sky sky) {
  return find_sky_enclosures(test::yard_under(sky).build(), plan::kSkyEnclosureCover);
}

TEST(Delivered, SkyDomesBoxesAndInvertedSpheresAreFound) {
  EXPECT_EQ(enclosures(Sky::None), std::vector<int>{});
  EXPECT_EQ(enclosures(Sky::Dome), std::vector<int>{0});
  EXPECT_EQ(enclosures(Sky::Box), std::vector<int>{0});
  EXPECT_EQ(enclosures(Sky::InvertedSphere), std::vector<int>{0});
  EXPECT_EQ(enclosures(Sky::DomeAndBox), (std::vector<int>{0, 1}));  // the box, then the dome
}

// Not enclosures: a ground under everything, a roof over part of the scene,
// a tall tower beside it.
TEST(Delivered, GroundsRoofsAndTowersAreNotEnclosures) {
  SceneBuilder b;
  b.add_box("Slab", glm::vec3(-20.0f, -1.0f, -20.0f), glm::vec3(20.0f, 0.0f, 20.0f));
  b.add_box("Block", glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 1.0f, 1.0f));
  b.add_box("Canopy", glm::vec3(-20.0f, 5.0f, -20.0f), glm::vec3(20.0f, 5.2f, 0.0f));
  b.add_box("Tower", glm::vec3(10.0f, 0.0f, 10.0f), glm::vec3(12.0f, 50.0f, 12.0f));
  EXPECT_EQ(find_sky_enclosures(b.build(), plan::kSkyEnclosureCover), std::vector<int>{});
}

}  // namespace
}  // namespace snow
