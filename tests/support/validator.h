#pragma once
// Runs the Khronos glTF validator (tools/validator, installed with `npm ci`
// there) over files the tests write; does nothing where node or the
// validator is not installed.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace snow::test {

struct Validation {
  bool ran = false;
  int status = -1;
  std::string output;
};

/// Runs tools/validator/validate.mjs over `files` (not run when node or the
/// validator is not installed).
inline Validation run_validator(const std::vector<std::filesystem::path>& files) {
  Validation v;
  const std::filesystem::path dir = std::filesystem::path(SNOW_SOURCE_DIR) / "tools" / "validator";
  if (!std::filesystem::exists(dir / "node_modules" / "gltf-validator" / "package.json")) return v;
  if (std::system("command -v node >/dev/null 2>&1") != 0) return v;
  std::string command = "node '" + (dir / "validate.mjs").string() + "'";
  for (const std::filesystem::path& f : files) command += " '" + f.string() + "'";
  command += " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return v;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) v.output.append(buf, n);
  const int status = pclose(pipe);
  v.ran = true;
  v.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return v;
}

inline void expect_valid_gltf(const std::vector<std::filesystem::path>& files) {
  const Validation v = run_validator(files);
  if (!v.ran) {
    std::printf("glTF validator not installed (npm ci in tools/validator): not validated\n");
    return;
  }
  std::printf("%s", v.output.c_str());
  EXPECT_EQ(v.status, 0) << v.output;
  for (const std::filesystem::path& f : files) {
    EXPECT_NE(v.output.find(f.string() + ": 0 errors"), std::string::npos) << v.output;
  }
}

}  // namespace snow::test
