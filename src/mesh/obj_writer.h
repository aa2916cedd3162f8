#pragma once
// Wavefront OBJ + MTL writer for triangle meshes.
#include <filesystem>
#include <vector>

#include "core/trimesh.h"

namespace snow {

/// Writes `meshes` to `path` as OBJ, one `o <name>` group per mesh
/// (whitespace in names becomes '_'; meshes without triangles are skipped)
/// with `v`, `vt` (when the mesh has uvs), `vn` (when it has normals) and
/// `f v/vt/vn` lines, all using `material`, which is written to
/// "<stem>.mtl" beside it (Ka, Kd, Ks, Ns, d, illum and the PBR extension
/// Pr/Pm). Numbers are written with 9 significant digits (floats round-trip).
/// Both files are written atomically; throws IOError naming the file.
void write_obj(const std::vector<TriMesh>& meshes, const MeshMaterial& material,
               const std::filesystem::path& path);

}  // namespace snow
