#pragma once
// The input policy: what every command that reads a scene (the glTF loader,
// and the combined writer of mesh/export.h, which copies the input's files
// from the JSON the loader parsed) accepts from the file system and from
// the JSON. A scene is untrusted:
// - its JSON nests at most kMaxJsonDepth levels, checked on the raw text
//   before any parser sees it (recursive parsers and writers, tinygltf's
//   and json::dump, then stay well inside their stack);
// - every file it names lies inside the scene's folder after symlinks are
//   followed (resolve_relative_uri in scene/load_gltf.h, inside_folder);
// - every file read, the scene itself included, is a regular file: FIFOs,
//   devices, sockets and folders are refused before they are opened
//   (regular_file_problem, read_regular_file).
// The loader's resource limits (LoadLimits in scene/load_gltf.h) bound the
// bytes read: buffer files only as far as the buffers declare, and the
// buffers plus the decoded images summed against LoadLimits::memory_budget.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace snow {

/// Nesting of JSON arrays and objects a scene may have (levels). glTF's own
/// structure nests below 10; `extras` and extensions add a few more.
inline constexpr int kMaxJsonDepth = 512;

/// Throws InputError "<label>: JSON nested deeper than 512 levels" when the
/// arrays and objects of `text` nest deeper than kMaxJsonDepth (brackets in
/// strings do not count). Checks nothing else: broken JSON passes, for the
/// parser to report.
void check_json_depth(std::string_view text, const std::string& label);

/// The JSON text in the first `size` bytes of a scene file: a GLB's JSON
/// chunk (glTF 2.0 section 4.4; cut at the end of the bytes when it claims
/// more), else all of them.
std::string_view scene_json_text(const uint8_t* data, size_t size);

/// True when `file` lies inside `folder` once both are resolved (symlinks
/// followed, "." and ".." removed; `file` need not exist). False when either
/// cannot be resolved.
bool inside_folder(const std::filesystem::path& folder, const std::filesystem::path& file);

/// Empty when `file` (symlinks followed) is a regular file; else why not:
/// "does not exist", "is a folder", "is not a regular file (a FIFO, device
/// or socket)". Only looks (stat); opens nothing.
std::string regular_file_problem(const std::filesystem::path& file);

/// Reads the first `bytes` bytes of the regular file `file` into `out`
/// (`out` holds at least `bytes`). The file is refused, not opened, when it
/// is not a regular file, and opened without blocking and checked again on
/// the open descriptor, so a file swapped for a FIFO or a device meanwhile
/// is refused too, never waited on. False, with the reason in *why, when
/// it is not a regular file, cannot be read or holds fewer bytes.
bool read_regular_file(const std::filesystem::path& file, uint64_t bytes, uint8_t* out,
                       std::string* why);

}  // namespace snow
