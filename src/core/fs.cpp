#include "core/fs.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "core/error.h"

namespace snow {
namespace fs = std::filesystem;

namespace {
fs::path temporary_name(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  return path.parent_path() /
         ("." + path.filename().string() + ".tmp" + std::to_string(getpid()) + "_" +
          std::to_string(counter++));
}
}  // namespace

void write_file_atomically(const fs::path& path, const std::function<void(const fs::path&)>& write) {
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw IOError("cannot write " + path.string() + ": folder " + folder.string() + " does not exist");
  }
  if (fs::is_directory(path, ec)) {
    throw IOError("cannot write " + path.string() + ": it is a folder");
  }
  const fs::path tmp = temporary_name(path.parent_path().empty() ? fs::path(".") / path : path);
  try {
    write(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    fs::remove(tmp, ec);
    throw IOError("cannot write " + path.string() + ": " + reason);
  }
}

void write_bytes_atomically(const fs::path& path, const void* data, size_t size) {
  write_file_atomically(path, [&](const fs::path& tmp) {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw IOError("cannot write " + path.string() + ": " + std::strerror(errno));
    const size_t written = size ? std::fwrite(data, 1, size, f) : 0;
    const bool ok = written == size && std::fflush(f) == 0;
    const std::string reason = std::strerror(errno);
    std::fclose(f);
    if (!ok) throw IOError("cannot write " + path.string() + ": " + reason);
  });
}

void write_text_atomically(const fs::path& path, const std::string& text) {
  write_bytes_atomically(path, text.data(), text.size());
}

std::vector<uint8_t> read_file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IOError("cannot read " + path.string() + ": " + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw IOError("cannot read " + path.string());
  in.seekg(0);
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size)) {
    throw IOError("cannot read " + path.string() + ": short read");
  }
  return bytes;
}

}  // namespace snow
