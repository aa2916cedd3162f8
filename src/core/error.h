#pragma once
// Typed errors. Each maps to one process exit code (see exit_code()).
// Bad input -> InputError (2), no usable GL -> GLError (3), file system
// trouble -> IOError (4). Anything else that escapes is an internal error (1).
#include <stdexcept>
#include <string>

namespace snow {

/// Base of all snowmodel errors. what() is one line meant for the user.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
  virtual int exit_code() const { return 1; }
};

/// The input (scene file, settings) is broken, hostile or unusable.
class InputError : public Error {
 public:
  using Error::Error;
  int exit_code() const override { return 2; }
};

/// No usable OpenGL context, a GL allocation failed, a shader did not build.
/// log() carries the driver's log (shader info log, backend reasons).
class GLError : public Error {
 public:
  explicit GLError(const std::string& message, std::string log = {})
      : Error(message), log_(std::move(log)) {}
  int exit_code() const override { return 3; }
  const std::string& log() const { return log_; }

 private:
  std::string log_;
};

/// A file could not be read or written.
class IOError : public Error {
 public:
  using Error::Error;
  int exit_code() const override { return 4; }
};

/// Process exit codes, also documented in the README.
enum ExitCode : int {
  kExitOk = 0,
  kExitInternal = 1,
  kExitBadInput = 2,
  kExitNoGL = 3,
  kExitIO = 4,
};

}  // namespace snow
