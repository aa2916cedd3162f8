#pragma once
// Runs a shell command for the end-to-end tests (the snowmodel executable)
// and collects its output.
#include <sys/wait.h>

#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

namespace snow::test {

struct CommandResult {
  int code = -1;       // exit status; 128 + signal number when killed; -1 if it did not start
  std::string output;  // stdout and stderr together
};

/// Runs `command` through /bin/sh with stderr joined to stdout and waits.
inline CommandResult run_command(const std::string& command) {
  CommandResult result;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    result.output.append(buffer.data(), n);
  const int status = pclose(pipe);
  result.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

/// `path` in single quotes, for a /bin/sh command line.
inline std::string quoted(const std::filesystem::path& path) { return "'" + path.string() + "'"; }

/// An empty folder `<temp>/<prefix>_<name>_<pid>` (what an earlier run left
/// there removed first).
inline std::filesystem::path fresh_dir(const std::string& prefix, const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    (prefix + "_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

#ifdef SNOWMODEL_EXE
/// Runs the snowmodel under test with `args`.
inline CommandResult run_snowmodel(const std::string& args) {
  return run_command(std::string(SNOWMODEL_EXE) + " " + args);
}
#endif

}  // namespace snow::test
