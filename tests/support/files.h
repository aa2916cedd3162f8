#pragma once
// Files for the tests that run the tool or its writers: whole-file reads and
// writes, and the hidden temporaries an atomic write would leave behind.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace snow::test {

/// The bytes of `path` ("" when it cannot be read).
inline std::string read_all(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Writes `bytes` to `path`, replacing it.
inline void write_all(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

/// Every file or folder under `dir` whose name starts with '.' and holds
/// ".tmp" (".<name>.tmp<pid>_<n>", ".snowmodel.tmp..."): what an atomic write
/// left behind.
inline std::vector<std::string> temporaries(const std::filesystem::path& dir) {
  std::vector<std::string> found;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 1 && name[0] == '.' && name.find(".tmp") != std::string::npos)
      found.push_back(entry.path().string());
  }
  return found;
}

}  // namespace snow::test
