#pragma once
// Binary PLY writer for triangle meshes.
#include <filesystem>
#include <vector>

#include "core/trimesh.h"

namespace snow {

/// Writes all `meshes` as one binary little-endian PLY mesh: element vertex
/// with float x, y, z, nx, ny, nz, s, t (normals (0, 1, 0) and UVs (0, 0)
/// where a mesh has none) and element face with `list uchar uint
/// vertex_indices`. A `comment mesh <name> faces <first> <count>` line per
/// mesh records where each one lies. Written atomically; throws IOError
/// naming the file.
void write_ply(const std::vector<TriMesh>& meshes, const std::filesystem::path& path);

}  // namespace snow
