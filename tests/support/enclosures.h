#pragma once
// Scenes as DCC tools export them with a sky: a small yard (a 10 m ground and
// a 2 x 2 m block) inside a sky dome, a sky box or an inverted sphere. Shared
// by test_delivered.cpp and test_cli.cpp.
#include <cmath>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "scene/builder.h"

namespace snow::test {

enum class Sky { None, Dome, Box, InvertedSphere, DomeAndBox };

/// A UV sphere (or its upper half) of `radius` around `centre`, wound to face
/// inwards (as sky domes are) or outwards; 24 x 12 quads.
inline int add_sphere(SceneBuilder& b, const std::string& name, const glm::vec3& centre,
                      float radius, bool inward, bool upper_half) {
  const int slices = 24, stacks = 12;
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  const float top = 0.0f, bottom = upper_half ? 0.5f * float(M_PI) : float(M_PI);
  for (int j = 0; j <= stacks; ++j) {
    const float polar = top + (bottom - top) * float(j) / float(stacks);
    for (int i = 0; i <= slices; ++i) {
      const float azimuth = 2.0f * float(M_PI) * float(i) / float(slices);
      positions.push_back(centre + radius * glm::vec3(std::sin(polar) * std::cos(azimuth),
                                                      std::cos(polar),
                                                      std::sin(polar) * std::sin(azimuth)));
    }
  }
  for (int j = 0; j < stacks; ++j) {
    for (int i = 0; i < slices; ++i) {
      const uint32_t a = uint32_t(j * (slices + 1) + i), c = a + uint32_t(slices + 1);
      const uint32_t quad[6] = {a, c, a + 1, a + 1, c, c + 1};  // outward
      for (int k = 0; k < 6; k += 3) {
        indices.push_back(quad[k]);
        indices.push_back(quad[k + (inward ? 2 : 1)]);
        indices.push_back(quad[k + (inward ? 1 : 2)]);
      }
    }
  }
  return b.add_mesh(name, positions, indices);
}

/// The yard ("Ground" 10 m, "Block" 2 x 2 x 1 m) under `sky`: "SkyDome" (an
/// inward hemisphere of 60 m), "SkyBox" (a closed 80 m box from y = -5), or
/// "SkySphere" (an inward sphere of 60 m).
inline SceneBuilder yard_under(Sky sky) {
  SceneBuilder b;
  if (sky == Sky::Box || sky == Sky::DomeAndBox) {
    b.add_box("SkyBox", glm::vec3(-40.0f, -5.0f, -40.0f), glm::vec3(40.0f, 40.0f, 40.0f));
  }
  if (sky == Sky::Dome || sky == Sky::DomeAndBox) {
    add_sphere(b, "SkyDome", glm::vec3(0.0f), 30.0f, true, true);
  }
  if (sky == Sky::InvertedSphere) add_sphere(b, "SkySphere", glm::vec3(0.0f), 60.0f, true, false);
  b.add_plane("Ground", 0.0f, glm::vec2(-5.0f), glm::vec2(5.0f));
  b.add_box("Block", glm::vec3(-1.0f, 0.0f, -1.0f), glm::vec3(1.0f, 1.0f, 1.0f));
  return b;
}

}  // namespace snow::test
