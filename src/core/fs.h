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
/// partial file under `path`.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path& tmp_path)>& write);

/// Convenience: writes `bytes` atomically.
void write_bytes_atomically(const std::filesystem::path& path, const void* data, size_t size);
void write_text_atomically(const std::filesystem::path& path, const std::string& text);

/// Reads a whole file; throws IOError naming the path on failure.
std::vector<uint8_t> read_file_bytes(const std::filesystem::path& path);

}  // namespace snow
