#pragma once
// The combined writer (write_combined_gltf, mesh/export.h): the input scene
// plus snow as one .glb, or one .gltf with one "<stem>.bin", from the JSON
// the loader parsed (scene/source_gltf.h; the input's JSON is never read or
// parsed again). The input's JSON is kept as written; its buffers are
// merged into one output buffer, copied from their files by the kernel
// (copy_file_range, never into memory) as far as their byteLength, or
// decoded from data URIs; its images in files or data URIs are embedded as
// buffer views; the snow is merged in after them.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/trimesh.h"
#include "scene/source_gltf.h"

namespace snow {

/// MIME type of encoded image bytes, from their signature; empty if unknown.
std::string sniff_mime_type(const std::vector<unsigned char>& bytes);

/// Bytes of a file that the combined output copies, and the file's size and
/// modification time when the plan was made.
struct FileBytes {
  std::filesystem::path file;
  uint64_t offset = 0, length = 0;
  uint64_t file_size = 0;
  std::filesystem::file_time_type modified{};
};

/// Bytes the output buffer takes from the input: a file's range, or bytes
/// decoded from a data URI.
struct InputBytes {
  std::optional<FileBytes> file;  // else `bytes`
  std::vector<uint8_t> bytes;
  uint64_t length() const { return file ? file->length : bytes.size(); }
};

/// The combined output planned from the input (plan_combined), written by
/// write_combined.
struct CombinedInput {
  std::filesystem::path path;  // the input, for messages
  /// The input's JSON, its bufferViews already pointing into the one output
  /// buffer (buffer 0; its uri and byteLength are set by the write).
  nlohmann::json gltf;
  /// The input's buffers in the output buffer: buffer i's first byteLength
  /// bytes at `offset` (a multiple of 8; buffer 0 at 0).
  struct Piece {
    uint64_t offset = 0;
    InputBytes bytes;
  };
  std::vector<Piece> buffers;
  uint64_t buffers_end = 0;  // where the last buffer ends in the output buffer (bytes)
  /// Images in files or data URIs, to embed as buffer views.
  struct EmbeddedImage {
    size_t index;
    InputBytes bytes;
    std::string mime;
  };
  std::vector<EmbeddedImage> images;
  std::vector<std::string> kept_by_uri;  // warnings: images left at their uri
};

/// The plan for writing `source` plus snow. Applies the input policy
/// (scene/input_policy.h) to every buffer and image uri, used by the scene
/// or not; nothing is read but the first bytes of each image file (for its
/// format) and data URIs. Throws InputError, one line naming the input and
/// the buffer, for a buffer that is not an object, has no whole byteLength,
/// no uri (but a .glb's buffer 0, which must fit in its BIN chunk), a uri
/// that resolves outside the scene's folder or to anything but a regular
/// file, a file shorter than byteLength, or a malformed data URI; and for a
/// bufferView whose buffer is not one of them, or an image uri outside the
/// folder. An image file that cannot be read or has no known format stays
/// at its uri, with a warning at the write.
CombinedInput plan_combined(const SourceGltf& source);

/// Writes the plan's input plus `snow` (append_meshes' nodes, meshes and
/// material under a "Snow" root in the default scene) to `out`: a .glb, or
/// a .gltf (by its extension) with its buffer in "<stem>.bin" beside it,
/// each file atomically. The plan's JSON is changed. Throws IOError when a
/// file cannot be read or `out` written, or when a file the plan copies
/// from changed (size or modification time) since the plan was made (the
/// input .glb since the loader read it): its bytes would no longer match
/// the JSON read then.
void write_combined(CombinedInput& plan, const std::vector<TriMesh>& snow,
                    const std::filesystem::path& out);

}  // namespace snow
