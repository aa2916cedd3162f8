#pragma once
// The scene's frame: glTF is metres with +Y up, but scenes arrive in
// centimetres, millimetres or +Z up (exporters' defaults). The run works in
// metres, +Y up; the options --unit-scale and --up say how to get there,
// and the snow goes back to the file's frame on export, so it still lies
// exactly on the scene.
#include <string>

#include <glm/glm.hpp>

#include "core/trimesh.h"
#include "scene/scene.h"

namespace snow {

struct FileFrame {
  float unit_scale = 1.0f;  // metres per file unit (0.01: centimetres), > 0
  bool z_up = false;        // the file's +Z is up (its +Y points away from the viewer)

  bool is_identity() const { return unit_scale == 1.0f && !z_up; }
};

/// "y" or "z" for --up; InputError naming the value otherwise.
bool z_up_from_name(const std::string& name);

/// `scene` in metres, +Y up: positions scaled by unit_scale and, with z_up,
/// turned so that the file's +Z is +Y ((x, y, z) -> (x, z, -y), a right-
/// handed turn of -90 degrees about +X); normals turned alike; bounds
/// recomputed; the points of `lines` mapped as positions, and each of the
/// motions' `moves` M conjugated to F * M * F^-1 (F: the map of positions),
/// so that it moves the mapped points. The identity frame changes nothing.
void to_metres_y_up(Scene& scene, const FileFrame& frame);

/// The inverse of to_metres_y_up on a mesh (positions, normals), for the
/// snow that goes back into the file's frame; UVs (metres) stay.
void to_file_frame(TriMesh& mesh, const FileFrame& frame);

/// What the scene's geometry says about its frame, read in metres +Y up.
struct FrameFigures {
  float median_object_size = 0.0f;  // units: median over objects of their bounds' longest side
  double area_facing_y = 0.0;       // units^2: triangles facing within 25 degrees of +-Y
  double area_facing_z = 0.0;       // units^2: triangles facing within 25 degrees of +-Z
};
FrameFigures frame_figures(const Scene& scene);

}  // namespace snow
