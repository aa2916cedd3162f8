// Part of the glTF loader (see scene/gltf/internal.h):
// KHR_draco_mesh_compression, decoded with Google's Draco library when the
// build has it (SNOW_HAVE_DRACO, set on this file only by
// src/scene/CMakeLists.txt). The decoded mesh is validated like accessors:
// counts against the limits, every value finite, every face index in range.
#include <cmath>
#include <cstring>

#ifdef SNOW_HAVE_DRACO
#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#endif

#include "scene/gltf/internal.h"

namespace snow {
namespace gltf {

void GltfLoader::decode_draco(const json& extension, const std::string& what,
                              const std::string& uv_name, PrimitiveGeometry& geometry) {
#ifdef SNOW_HAVE_DRACO
  const std::string dwhat = what + " KHR_draco_mesh_compression";
  const int64_t view_index =
      opt_index(extension, "bufferView", top_array("bufferViews").size(), dwhat, "bufferViews");
  if (view_index < 0) fail(dwhat + " has no 'bufferView'");
  const json* attributes = member(extension, "attributes");
  if (!attributes || !attributes->is_object()) fail(dwhat + " has no 'attributes' object");
  const ViewRange range = view(uint64_t(view_index), dwhat);
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(range.data), size_t(range.length));
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok())
    fail(dwhat + ": Draco decoding failed: " + one_line(decoded.status().error_msg_string()));
  const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
  const uint64_t points = mesh->num_points();
  const uint64_t faces = mesh->num_faces();
  if (faces > settings_.limits.max_triangles || points > max_elements())
    fail(dwhat + ": " + std::to_string(faces) + " faces exceed LoadLimits::max_triangles");
  auto read = [&](const char* name, int components, std::vector<float>& out) -> bool {
    const json* id = member(*attributes, name);
    if (!id) return false;
    const draco::PointAttribute* attribute = mesh->GetAttributeByUniqueId(
        uint32_t(std::min<uint64_t>(as_uint(*id, dwhat + " " + name), UINT32_MAX)));
    if (!attribute) fail(dwhat + ": " + name + " refers to a missing Draco attribute");
    if (attribute->num_components() < components)
      fail(dwhat + ": " + name + " has " + std::to_string(int(attribute->num_components())) +
           " components");
    out.resize(size_t(points) * size_t(components));
    for (uint64_t i = 0; i < points; ++i) {
      const draco::AttributeValueIndex value =
          attribute->mapped_index(draco::PointIndex(uint32_t(i)));
      if (value.value() >= attribute->size() ||
          !attribute->ConvertValue<float>(value, int8_t(components),
                                          out.data() + i * size_t(components)))
        fail(dwhat + ": " + name + " value of point " + std::to_string(i) + " is unreadable");
    }
    for (float v : out)
      if (!std::isfinite(v)) fail(dwhat + ": " + name + " has a non-finite value");
    return true;
  };
  std::vector<float> values;
  if (!read("POSITION", 3, values)) fail(dwhat + " has no POSITION attribute");
  geometry.positions.resize(size_t(points));
  if (!values.empty())
    std::memcpy(geometry.positions.data(), values.data(), values.size() * sizeof(float));
  if (settings_.shading && read("NORMAL", 3, values)) {
    geometry.normals.resize(size_t(points));
    if (!values.empty())
      std::memcpy(geometry.normals.data(), values.data(), values.size() * sizeof(float));
  }
  if (settings_.shading && read(uv_name.c_str(), 2, values)) {
    geometry.uvs.resize(size_t(points));
    if (!values.empty())
      std::memcpy(geometry.uvs.data(), values.data(), values.size() * sizeof(float));
  }
  geometry.triangles.resize(size_t(faces) * 3);
  for (uint64_t f = 0; f < faces; ++f) {
    const draco::Mesh::Face& face = mesh->face(draco::FaceIndex(uint32_t(f)));
    for (int k = 0; k < 3; ++k) {
      const uint32_t index = face[k].value();
      if (index >= points)
        fail(dwhat + ": face " + std::to_string(f) + " has an out-of-range point");
      geometry.triangles[size_t(f) * 3 + size_t(k)] = index;
    }
  }
#else
  (void)extension;
  (void)uv_name;
  (void)geometry;
  fail(what +
       " is compressed with KHR_draco_mesh_compression, but this build has no Draco decoder");
#endif
}

}  // namespace gltf

bool gltf_draco_supported() {
#ifdef SNOW_HAVE_DRACO
  return true;
#else
  return false;
#endif
}

}  // namespace snow
