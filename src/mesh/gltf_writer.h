#pragma once
// glTF 2.0 writing with tinygltf: appends TriMeshes to a tinygltf::Model and
// saves .glb/.gltf atomically. Output is deterministic (same input, same
// bytes).
#include <filesystem>
#include <string>
#include <vector>

#include "core/trimesh.h"

namespace tinygltf {
class Model;
}

namespace snow {

/// Appends `meshes` as one node each (named after the mesh, one mesh with one
/// TRIANGLES primitive) under a new root node `root_name`, which is added to
/// the model's default scene (a scene is created and made default if there is
/// none). Adds one PBR material per MeshMaterial (baseColorFactor,
/// roughnessFactor, metallicFactor; double-sided false); TriMesh::material
/// indexes `materials` (out of range: InputError naming the mesh). Writes
/// POSITION (with min/max), NORMAL when the mesh has normals (one per
/// position, else InputError), TEXCOORD_0 when it has uvs, and indices as
/// uint16 when every index fits, else uint32. All data goes to buffer 0
/// (created if the model has none; appended, 4-byte aligned, otherwise) in
/// one buffer view per accessor. Meshes without triangles are skipped with a
/// warning naming them. Sets asset.version "2.0" and asset.generator when
/// empty. Throws InputError for indices out of range.
void append_meshes(tinygltf::Model& model, const std::vector<TriMesh>& meshes,
                   const std::vector<MeshMaterial>& materials, const std::string& root_name);

/// At most the bytes append_meshes adds to buffer 0 for `meshes` (their
/// attributes and indices, with padding): room to reserve beforehand.
size_t mesh_buffer_bytes(const std::vector<TriMesh>& meshes);

/// Writes `model` as binary .glb or as .gltf JSON, chosen by the extension of
/// `path` (case-insensitive; anything else: InputError). For .gltf every
/// buffer without a data URI is written beside it as "<stem>.bin" (buffer 0)
/// or "<stem><i>.bin" (buffer i > 0), and referenced by that relative URI.
/// Every file is written atomically (snow::write_file_atomically); failures
/// throw IOError naming the path. Pass a model that is no longer needed with
/// std::move: its buffers are then written without a copy.
void save_gltf(tinygltf::Model model, const std::filesystem::path& path);

/// The JSON text of `model` as the GLB that save_gltf writes would hold it
/// (compact, without the chunk's padding): buffer 0 without a uri, its bytes
/// in the BIN chunk (empty them first to leave them out). `path` names the
/// output in errors.
std::string glb_json(const tinygltf::Model& model, const std::filesystem::path& path);

namespace detail {
/// Where the 0 of `"buffers":[{"byteLength":0` is in compact glTF JSON, at
/// the top level (not in a string, not in a nested object); npos if not
/// there, or not followed by ',' or '}'. save_gltf's GLB writer sets buffer
/// 0's length there (exposed for tests).
size_t empty_buffer0_length_at(const std::string& json);
}  // namespace detail

}  // namespace snow
