#include "core/fs.h"

#include <fcntl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>

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

// Temporary files and folders being written, so that SIGINT/SIGTERM/SIGHUP
// can remove them before the process dies (SIGKILL cannot be caught: a killed
// run may leave a ".<name>.tmp<pid>_<n>" file or folder, never a partial one
// under the target name). The handler only reads these slots and calls
// unlink(2), open(2), getdents64(2), unlinkat(2) and rmdir(2) (async-signal-safe
// system calls); a folder's entries are plain files, removed one level deep.
constexpr int kTempSlots = 16;
constexpr size_t kTempPathMax = 4096;
char g_temp_paths[kTempSlots][kTempPathMax];
std::atomic<bool> g_temp_used[kTempSlots];
std::atomic<bool> g_temp_claimed[kTempSlots];
std::atomic<bool> g_temp_folder[kTempSlots];

/// Empties the folder `path` of its files (one level) and removes it, with
/// system calls alone (for the signal handler).
void remove_flat_folder(const char* path) {
  const int fd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    alignas(8) char buffer[4096];
    for (;;) {
      const long n = syscall(SYS_getdents64, fd, buffer, sizeof buffer);
      if (n <= 0) break;
      for (long at = 0; at < n;) {
        // struct linux_dirent64: d_ino (8), d_off (8), d_reclen (2), d_type (1), d_name.
        unsigned short length = 0;
        std::memcpy(&length, buffer + at + 16, sizeof length);
        const char* name = buffer + at + 19;
        if (std::strcmp(name, ".") != 0 && std::strcmp(name, "..") != 0) unlinkat(fd, name, 0);
        if (length == 0) break;
        at += length;
      }
    }
    close(fd);
  }
  rmdir(path);
}

extern "C" void remove_temporaries_and_reraise(int signal_number) {
  for (int i = 0; i < kTempSlots; ++i) {
    if (!g_temp_used[i].load()) continue;
    if (g_temp_folder[i].load()) {
      remove_flat_folder(g_temp_paths[i]);
    } else {
      unlink(g_temp_paths[i]);
    }
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

/// Registers `tmp` (a file, or a folder of files) for removal on a signal
/// while alive.
class TempRegistration {
 public:
  explicit TempRegistration(const fs::path& tmp, bool folder = false) {
    install_signal_cleanup();
    const std::string& text = tmp.native();
    if (text.size() >= kTempPathMax) return;
    for (int i = 0; i < kTempSlots; ++i) {
      bool expected = false;
      if (g_temp_claimed[i].compare_exchange_strong(expected, true)) {
        std::memcpy(g_temp_paths[i], text.c_str(), text.size() + 1);
        g_temp_folder[i].store(folder);
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

/// A name beside `path` for writing it: ".<name>.tmp<pid>_<n>", or
/// ".snowmodel.tmp<pid>_<n>" where that would be longer than the folder
/// allows a name to be (NAME_MAX), so that every name the system takes as
/// an output can be written. Unique within the process (n counts).
fs::path temporary_name(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  const std::string suffix = ".tmp" + std::to_string(getpid()) + "_" + std::to_string(counter++);
  const std::string long_name = "." + path.filename().string() + suffix;
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  if (long_name.size() <= name_max(folder)) return path.parent_path() / long_name;
  return path.parent_path() / (".snowmodel" + suffix);
}

/// What `type` is, for an error message ("a character device").
const char* file_type_name(fs::file_type type) {
  switch (type) {
    case fs::file_type::directory:
      return "a folder";
    case fs::file_type::character:
      return "a character device";
    case fs::file_type::block:
      return "a block device";
    case fs::file_type::fifo:
      return "a FIFO";
    case fs::file_type::socket:
      return "a socket";
    default:
      return "not a regular file";
  }
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
  // The rename would replace a device node or FIFO by a regular file.
  if (const std::string why = not_a_regular_file(path); !why.empty()) {
    throw IOError("cannot write " + path.string() + ": " + why);
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

size_t name_max(const fs::path& folder) {
  const long limit = pathconf(folder.empty() ? "." : folder.c_str(), _PC_NAME_MAX);
  return limit > 0 ? size_t(limit) : size_t(NAME_MAX);
}

std::string not_a_regular_file(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status) || fs::is_regular_file(status)) return {};
  const std::string what = file_type_name(status.type());
  return what == "not a regular file" ? what : "not a regular file (" + what + ")";
}

void write_folder_atomically(const fs::path& path_as_given,
                             const std::function<void(const fs::path&)>& write) {
  // "maps/" names the folder "maps".
  const fs::path path = path_as_given.has_filename() ? path_as_given : path_as_given.parent_path();
  const fs::path folder = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (!fs::is_directory(folder)) {
    throw IOError("cannot create the folder " + path.string() +
                  (ec ? ": " + ec.message() : std::string()));
  }
  if (fs::exists(path, ec) && !fs::is_directory(path, ec)) {
    throw IOError("cannot create the folder " + path.string() + ": " +
                  file_type_name(fs::status(path, ec).type()) + " is there");
  }
  const fs::path tmp = temporary_name(folder / path.filename());
  const TempRegistration registration(tmp, true);
  if (!fs::create_directory(tmp, ec)) {
    throw IOError("cannot create the folder " + path.string() + ": " + ec.message());
  }
  try {
    write(tmp);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  // Swap with the folder there, then remove the old one (now at tmp).
  if (renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, path.c_str(), RENAME_EXCHANGE) == 0) {
    fs::remove_all(tmp, ec);
    return;
  }
  // No swap (no folder there, or a file system without it): a rename onto a
  // missing or empty folder; onto a full one, the old folder is renamed
  // away first (for that moment `path` is absent) and removed after.
  if (std::rename(tmp.c_str(), path.c_str()) == 0) return;
  int error = errno;
  if (error == ENOTEMPTY || error == EEXIST) {
    const fs::path old = temporary_name(folder / path.filename());
    const TempRegistration old_registration(old, true);
    if (std::rename(path.c_str(), old.c_str()) == 0) {
      if (std::rename(tmp.c_str(), path.c_str()) == 0) {
        fs::remove_all(old, ec);
        return;
      }
      error = errno;
      std::rename(old.c_str(), path.c_str());  // put the old folder back
    } else {
      error = errno;
    }
  }
  fs::remove_all(tmp, ec);
  throw IOError("cannot write the folder " + path.string() + ": " + std::strerror(error));
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
