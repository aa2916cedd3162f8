#pragma once
// Logging and progress reporting for long stages.
//
// Messages go to stderr. Warnings are also collected so that commands can
// repeat them in summaries or JSON output. Progress shows a bar with
// percentage and ETA on a terminal, plain lines otherwise, nothing when quiet.
#include <chrono>
#include <string>
#include <vector>

namespace snow {

enum class LogLevel { Quiet = 0, Warn = 1, Info = 2, Debug = 3 };

/// Global verbosity (default Info). Not thread-safe to change while stages run.
void set_log_level(LogLevel level);
LogLevel log_level();

void log_info(const std::string& message);
void log_debug(const std::string& message);
/// Prints "warning: <message>" (unless Quiet) and records it.
void log_warn(const std::string& message);
/// Warnings recorded since the last clear_warnings().
const std::vector<std::string>& recorded_warnings();
void clear_warnings();

/// While one lives, this thread logs nothing (warnings are still recorded):
/// for work done ahead in the background whose messages the foreground
/// prints when it does the same work.
class QuietThread {
 public:
  QuietThread();
  ~QuietThread();
  QuietThread(const QuietThread&) = delete;
  QuietThread& operator=(const QuietThread&) = delete;

 private:
  bool was_;
};

/// Progress of one stage. update() may be called often; output is throttled.
/// Destruction (or finish()) closes the line and logs the stage time.
/// Prints nothing on a thread a QuietThread quiets.
class Progress {
 public:
  Progress(std::string stage, double total);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void update(double done);
  void finish();
  double seconds() const;

 private:
  std::string stage_;
  double total_;
  bool finished_ = false;
  bool tty_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_print_;
  int last_percent_ = -1;
};

}  // namespace snow
