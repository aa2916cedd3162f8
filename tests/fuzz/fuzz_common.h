#pragma once
// Shared helpers of the libFuzzer targets (tests/fuzz): the loader reads
// files, so each input is written to a private scratch folder first.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

namespace snow::fuzz {

/// A private scratch folder (in /dev/shm when it exists), made once per process.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    std::filesystem::path base = std::filesystem::exists("/dev/shm")
                                     ? std::filesystem::path("/dev/shm")
                                     : std::filesystem::temp_directory_path();
    std::filesystem::path d = base / ("snow_fuzz_" + std::to_string(getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

/// Writes `data` to <scratch>/input (overwritten per input) and returns the path.
inline std::filesystem::path write_input(const uint8_t* data, size_t size) {
  const std::filesystem::path path = scratch_dir() / "input.glb";
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) __builtin_trap();
  if (size) std::fwrite(data, 1, size, f);
  std::fclose(f);
  return path;
}

}  // namespace snow::fuzz
