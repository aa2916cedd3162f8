#include "core/fs.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "core/error.h"

namespace snow {
namespace fs = std::filesystem;

namespace {

// Temporary files being written, so that SIGINT/SIGTERM/SIGHUP can remove them
// before the process dies (SIGKILL cannot be caught: a killed run may leave
// a ".<name>.tmp<pid>_<n>" file, never a partial file under the target name).
// The handler only reads these slots and calls unlink(2) (async-signal-safe).
constexpr int kTempSlots = 16;
constexpr size_t kTempPathMax = 4096;
char g_temp_paths[kTempSlots][kTempPathMax];
std::atomic<bool> g_temp_used[kTempSlots];
std::atomic<bool> g_temp_claimed[kTempSlots];

extern "C" void remove_temporaries_and_reraise(int signal_number) {
  for (int i = 0; i < kTempSlots; ++i) {
    if (g_temp_used[i].load()) unlink(g_temp_paths[i]);
  }
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

/// Installs the cleanup handler for the signals still at their default
/// action (a program's own handlers are left alone). Once per process.
void install_signal_cleanup() {
  static const bool installed = [] {
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction old {};
      if (sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_DFL) {
        struct sigaction action {};
        action.sa_handler = remove_temporaries_and_reraise;
        sigemptyset(&action.sa_mask);
        sigaction(sig, &action, nullptr);
      }
    }
    return true;
  }();
  (void)installed;
}

/// Registers `tmp` for removal on a signal while alive.
class TempRegistration {
 public:
  explicit TempRegistration(const fs::path& tmp) {
    install_signal_cleanup();
    const std::string& text = tmp.native();
    if (text.size() >= kTempPathMax) return;
    for (int i = 0; i < kTempSlots; ++i) {
      bool expected = false;
      if (g_temp_claimed[i].compare_exchange_strong(expected, true)) {
        std::memcpy(g_temp_paths[i], text.c_str(), text.size() + 1);
        g_temp_used[i].store(true);
        slot_ = i;
        return;
      }
    }
  }
  ~TempRegistration() {
    if (slot_ < 0) return;
    g_temp_used[slot_].store(false);
    g_temp_claimed[slot_].store(false);
  }
  TempRegistration(const TempRegistration&) = delete;
  TempRegistration& operator=(const TempRegistration&) = delete;

 private:
  int slot_ = -1;
};

/// Puts the finished temporary file `tmp` at `path`, in one step for any
/// reader: `path` holds the old file or the new one, never a part. Where `path`
/// exists, the two are swapped (renameat2 RENAME_EXCHANGE) and the old file,
/// now at `tmp`, removed: a rename over an existing file on ext4 first writes
/// the new file's data out (its auto_da_alloc), a wait the swap does not have.
/// The data then reach the disk as those of any new file do. Elsewhere (no such
/// file, a file system without the swap): rename(2). Returns 0 or an errno
/// value.
int replace_file(const fs::path& tmp, const fs::path& path) {
  if (renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, path.c_str(), RENAME_EXCHANGE) == 0) {
    unlink(tmp.c_str());
    return 0;
  }
  return std::rename(tmp.c_str(), path.c_str()) == 0 ? 0 : errno;
}

fs::path temporary_name(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  return path.parent_path() / ("." + path.filename().string() + ".tmp" + std::to_string(getpid()) +
                               "_" + std::to_string(counter++));
}
}  // namespace

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

void write_file_atomically(const fs::path& path,
                           const std::function<void(const fs::path&)>& write) {
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    throw IOError("cannot write " + path.string() + ": folder " + folder.string() +
                  " does not exist");
  }
  if (fs::is_directory(path, ec)) {
    throw IOError("cannot write " + path.string() + ": it is a folder");
  }
  const fs::path tmp = temporary_name(path.parent_path().empty() ? fs::path(".") / path : path);
  const TempRegistration registration(tmp);
  try {
    write(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  if (const int error = replace_file(tmp, path)) {
    const std::string reason = std::strerror(error);
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
