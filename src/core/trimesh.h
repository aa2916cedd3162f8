#pragma once
// Plain indexed triangle mesh handed between the scene builder, polygonize,
// the exporters, the preview renderer and the asset generator. World space,
// metres, +Y up, counter-clockwise front faces. It depends on glm only, so
// every library can use it.
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace snow {

struct MeshMaterial {
  std::string name = "material";
  glm::vec4 base_color{1.0f};  // linear RGBA
  float roughness = 0.8f;
  float metallic = 0.0f;
};

struct TriMesh {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;  // empty or one per position
  std::vector<glm::vec2> uvs;      // empty or one per position
  std::vector<uint32_t> indices;   // 3 per triangle
  int material = 0;                // index into the exporter's material list
};

}  // namespace snow
