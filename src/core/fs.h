#pragma once
// File-system helpers that never leave a half-written output behind.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace snow {

/// The extension of `path`, with its dot, in lower case ("model.GLB": ".glb").
std::string lower_extension(const std::filesystem::path& path);

/// Calls write(tmp_path) to produce the file at a temporary name in the
/// target's folder, then puts it at `path` in one step: swapped with the
/// file already there (renameat2 RENAME_EXCHANGE), which is then removed,
/// else renamed onto `path` (both atomic on POSIX). If write
/// throws, or the rename fails, the temporary file is removed and the target
/// is left untouched. Throws IOError naming `path` when the folder is not
/// writable. While write runs, SIGINT, SIGTERM and SIGHUP (when still at
/// their default action) remove the temporary file before the process dies;
/// a SIGKILL can leave the temporary ".<name>.tmp<pid>_<n>" behind, never a
/// partial file under `path`. The temporary name fits the folder's NAME_MAX
/// (".snowmodel.tmp<pid>_<n>" where the long form would not). Throws IOError
/// when `path` exists and is not a regular file (a device, a FIFO): the
/// rename would replace it.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path& tmp_path)>& write);

/// Calls write(tmp_path) to fill a new folder made at a temporary name
/// beside `path` (its parents are created), then puts it at `path` in one
/// step: swapped with the folder already there (renameat2 RENAME_EXCHANGE),
/// which is then removed with all it holds, else renamed onto `path` (a
/// missing or empty folder). A reader sees the old folder or the whole new
/// one, never a part. If write throws or the rename fails, the temporary
/// folder is removed and `path` is left untouched; SIGINT, SIGTERM and
/// SIGHUP remove it too (its files must lie directly in it). A SIGKILL can
/// leave the hidden temporary folder behind. Throws IOError naming `path`
/// when it cannot be made. Deciding whether the folder at `path` may be
/// replaced is the caller's (mesh/output_policy.h).
void write_folder_atomically(
    const std::filesystem::path& path,
    const std::function<void(const std::filesystem::path& tmp_path)>& write);

/// The longest file name the folder takes (pathconf _PC_NAME_MAX; NAME_MAX
/// where unknown), in bytes.
size_t name_max(const std::filesystem::path& folder);

/// Empty when `path` is a regular file or absent (symlinks followed); else
/// why it cannot be written as one: "not a regular file (a character
/// device)", "(a FIFO)", "(a folder)", ...
std::string not_a_regular_file(const std::filesystem::path& path);

/// Convenience: writes `bytes` atomically.
void write_bytes_atomically(const std::filesystem::path& path, const void* data, size_t size);
void write_text_atomically(const std::filesystem::path& path, const std::string& text);

/// Reads a whole file; throws IOError naming the path on failure.
std::vector<uint8_t> read_file_bytes(const std::filesystem::path& path);

}  // namespace snow
