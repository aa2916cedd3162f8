#pragma once
// A Draco-compressed quad for tests (KHR_draco_mesh_compression), when the
// Draco encoder's headers are there (SNOW_TEST_DRACO_ENCODER; link
// snow_draco).
#if __has_include(<draco/compression/encode.h>)
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#define SNOW_TEST_DRACO_ENCODER 1
#endif

#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "gltf_scene.h"  // tests/support/gltf_scene.h

namespace snow::test {

#ifdef SNOW_TEST_DRACO_ENCODER
/// Two triangles of a unit quad facing +Y, encoded with Draco; the
/// POSITION attribute's unique id in `unique_id`.
inline std::vector<char> draco_quad(int* unique_id) {
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(2);
  const int pos_att =
      builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const float q[4][3] = {{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}};
  builder.SetAttributeValuesForFace(pos_att, draco::FaceIndex(0), q[0], q[1], q[2]);
  builder.SetAttributeValuesForFace(pos_att, draco::FaceIndex(1), q[0], q[2], q[3]);
  std::unique_ptr<draco::Mesh> draco_mesh = builder.Finalize();
  if (!draco_mesh) return {};
  *unique_id =
      int(draco_mesh->attribute(draco_mesh->GetNamedAttributeId(draco::GeometryAttribute::POSITION))
              ->unique_id());
  draco::Encoder encoder;
  encoder.SetSpeedOptions(5, 5);
  draco::EncoderBuffer encoded;
  if (!encoder.EncodeMeshToBuffer(*draco_mesh, &encoded).ok()) return {};
  return {encoded.data(), encoded.data() + encoded.size()};
}

/// A glTF whose one primitive is draco_quad, 1 m up; with `indexed`, the
/// primitive has an indices accessor without a bufferView, as the
/// extension's files usually do (Draco provides the indices).
inline Gltf draco_quad_gltf(bool indexed) {
  int unique_id = 0;
  const std::vector<char> encoded = draco_quad(&unique_id);
  EXPECT_FALSE(encoded.empty());
  Gltf g;
  const int view = g.view(encoded.data(), encoded.size());
  const int pos = g.accessor(-1, kFloat, 4, "VEC3");
  json primitive = {{"attributes", {{"POSITION", pos}}},
                    {"extensions",
                     {{"KHR_draco_mesh_compression",
                       {{"bufferView", view}, {"attributes", {{"POSITION", unique_id}}}}}}}};
  if (indexed) primitive["indices"] = g.accessor(-1, kUShort, 6, "SCALAR");
  const int mesh = g.mesh(json::array({primitive}));
  g.scene({g.node({{"mesh", mesh}, {"translation", {0, 1, 0}}})});
  g.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  g.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  return g;
}
#endif

}  // namespace snow::test
