#pragma once
// The input scene plus snow as one GLB, streamed from the input's files
// (write_combined_gltf's fast path, mesh/export.h): where the input keeps
// its data in one buffer (a .bin file or the GLB's own BIN chunk) and in
// image files, its JSON is read and kept as written, the snow merged in,
// and the buffer's and the images' bytes copied into the new BIN chunk by
// the kernel (copy_file_range), never into memory. tinygltf's path reads
// the buffer, copies it into its model and again to embed the images.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/trimesh.h"

namespace snow {

/// MIME type of encoded image bytes, from their signature; empty if unknown.
std::string sniff_mime_type(const std::vector<unsigned char>& bytes);

/// Bytes of a file that the streamed GLB copies, and the file's size and
/// modification time when the plan was made.
struct FileBytes {
  std::filesystem::path file;
  uint64_t offset = 0, length = 0;
  uint64_t file_size = 0;
  std::filesystem::file_time_type modified{};
};

struct StreamPlan {
  nlohmann::json gltf;              // the input's JSON
  std::optional<FileBytes> buffer;  // buffer 0's bytes
  struct EmbeddedImage {
    size_t index;
    FileBytes bytes;
    std::string mime;
  };
  std::vector<EmbeddedImage> images;     // images in files, to embed
  std::vector<std::string> kept_by_uri;  // warnings: images left at their uri
};

/// The plan for `input`, or nullopt where the input is not of that form
/// (several buffers, data URIs, a GLB or JSON that is not as expected):
/// tinygltf's path then writes it, and reports what is wrong with it.
/// Throws InputError where the input policy (scene/input_policy.h) refuses
/// the input: JSON nested too deep, a buffer or image uri that names a file
/// outside the input's folder. Files that are not regular files are not
/// planned (images stay at their uri; a buffer goes to tinygltf's path).
std::optional<StreamPlan> plan_streamed_glb(const std::filesystem::path& input);

/// Writes the plan's input plus `snow` (append_meshes' nodes, meshes and
/// material under a "Snow" root in the default scene) to the .glb `out`,
/// atomically. The plan's JSON is changed. Throws IOError when a file
/// cannot be read or `out` written, or when a file the plan copies from
/// changed (size or modification time) since the plan was made: its bytes
/// would no longer match the JSON read then.
void write_streamed_glb(StreamPlan& plan, const std::vector<TriMesh>& snow,
                        const std::filesystem::path& out);

}  // namespace snow
