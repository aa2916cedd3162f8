#pragma once
// The input of the combined writer as tinygltf is given it (export.cpp,
// read_with_tinygltf): what tinygltf would refuse or change in a valid
// file is mended before its parse and after it, or refused naming the file.
#include <cstdint>
#include <filesystem>
#include <vector>

namespace tinygltf {
class Model;
}

namespace snow {

struct TinygltfInput {
  /// The file's bytes, its JSON rewritten where tinygltf needs it (a GLB's
  /// chunks rebuilt around it).
  std::vector<unsigned char> bytes;
  /// Primitives (mesh, primitive, accessor) whose indices accessor, with no
  /// bufferView as KHR_draco_mesh_compression allows, was taken out of the
  /// JSON: tinygltf refuses it ("accessor[N] invalid bufferView").
  struct DracoIndices {
    int mesh = 0;
    int primitive = 0;
    int accessor = 0;
  };
  std::vector<DracoIndices> draco_indices;
};

/// Prepares `bytes`, the file `path` as read (.glb when `binary`, else
/// .gltf), for tinygltf. Throws InputError naming the file and the
/// JSON path for a whole number outside -2^31..2^31-1 where tinygltf keeps
/// an int (a texCoord, an index, a number in extras or extensions: it would
/// write it wrapped, 2^31 as -2^31); byteLength, byteOffset and count are
/// exempt (tinygltf keeps them as size_t). A file it cannot take apart is
/// handed on as it is, for tinygltf's own error.
TinygltfInput prepare_for_tinygltf(std::vector<unsigned char> bytes,
                                   const std::filesystem::path& path, bool binary);

/// Puts back into `model` (as tinygltf read input.bytes) what
/// prepare_for_tinygltf took out.
void restore_after_tinygltf(const TinygltfInput& input, tinygltf::Model& model);

}  // namespace snow
