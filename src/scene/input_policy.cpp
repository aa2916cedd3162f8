// The input policy (scene/input_policy.h).
#include "scene/input_policy.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "core/error.h"

namespace snow {
namespace fs = std::filesystem;

void check_json_depth(std::string_view text, const std::string& label) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;  // the escaped character, a quote or a backslash among them
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth)
        throw InputError(label + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) +
                         " levels");
    } else if (c == ']' || c == '}') {
      depth = std::max(depth - 1, 0);
    }
  }
}

std::string_view scene_json_text(const uint8_t* data, size_t size) {
  const auto u32 = [data](size_t at) {
    return uint32_t(data[at]) | uint32_t(data[at + 1]) << 8 | uint32_t(data[at + 2]) << 16 |
           uint32_t(data[at + 3]) << 24;
  };
  const char* text = reinterpret_cast<const char*>(data);
  if (size < 20 || u32(0) != 0x46546C67u) return {text, size};  // not "glTF": JSON
  return {text + 20, std::min<size_t>(u32(12), size - 20)};
}

bool inside_folder(const fs::path& folder, const fs::path& file) {
  std::error_code ec;
  const fs::path root = fs::canonical(folder, ec);
  if (ec) return false;
  const fs::path absolute = fs::absolute(file, ec);
  if (ec) return false;
  const fs::path target = fs::weakly_canonical(absolute, ec);
  if (ec) return false;
  auto t = target.begin();
  for (auto r = root.begin(); r != root.end(); ++r, ++t) {
    if (t == target.end() || *t != *r) return false;
  }
  return true;
}

std::string regular_file_problem(const fs::path& file) {
  std::error_code ec;
  const fs::file_status status = fs::status(file, ec);
  if (ec || !fs::exists(status)) return "does not exist";
  if (fs::is_directory(status)) return "is a folder";
  if (!fs::is_regular_file(status)) return "is not a regular file (a FIFO, device or socket)";
  return {};
}

bool read_regular_file(const fs::path& file, uint64_t bytes, uint8_t* out, std::string* why) {
  const auto refuse = [why](std::string reason) {
    if (why) *why = std::move(reason);
    return false;
  };
  if (std::string problem = regular_file_problem(file); !problem.empty()) return refuse(problem);
  // O_NONBLOCK: a FIFO put here since the look above opens at once, with no
  // writer to wait for, and is refused below.
  const int fd = ::open(file.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return refuse(std::string("cannot be opened (") + std::strerror(errno) + ")");
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
    return refuse("is not a regular file (a FIFO, device or socket)");
  uint64_t done = 0;
  while (done < bytes) {
    const size_t chunk = size_t(std::min<uint64_t>(bytes - done, uint64_t(1) << 30));
    const ssize_t n = ::pread(fd, out + done, chunk, off_t(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return refuse(std::string("cannot be read (") + std::strerror(errno) + ")");
    if (n == 0)
      return refuse("holds " + std::to_string(done) + " bytes, fewer than the " +
                    std::to_string(bytes) + " needed");
    done += uint64_t(n);
  }
  return true;
}

}  // namespace snow
