#include "core/log.h"

#include <unistd.h>

#include <cstdio>
#include <mutex>

namespace snow {
namespace {
LogLevel g_level = LogLevel::Info;
std::mutex g_mutex;
std::vector<std::string> g_warnings;
thread_local bool t_quiet = false;  // QuietThread
}  // namespace

QuietThread::QuietThread() : was_(t_quiet) { t_quiet = true; }
QuietThread::~QuietThread() { t_quiet = was_; }

void set_log_level(LogLevel level) { g_level = level; }
LogLevel log_level() { return g_level; }

void log_info(const std::string& message) {
  if (g_level >= LogLevel::Info && !t_quiet) std::fprintf(stderr, "%s\n", message.c_str());
}

void log_debug(const std::string& message) {
  if (g_level >= LogLevel::Debug && !t_quiet) std::fprintf(stderr, "debug: %s\n", message.c_str());
}

void log_warn(const std::string& message) {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_warnings.push_back(message);
  if (g_level >= LogLevel::Warn && !t_quiet) std::fprintf(stderr, "warning: %s\n", message.c_str());
}

const std::vector<std::string>& recorded_warnings() { return g_warnings; }

void clear_warnings() {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_warnings.clear();
}

Progress::Progress(std::string stage, double total)
    : stage_(std::move(stage)),
      total_(total > 0 ? total : 1),
      tty_(isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

Progress::~Progress() { finish(); }

double Progress::seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::update(double done) {
  if (finished_ || g_level < LogLevel::Info || t_quiet) return;
  const double fraction = done / total_ < 0 ? 0 : (done / total_ > 1 ? 1 : done / total_);
  const int percent = static_cast<int>(fraction * 100);
  const auto now = std::chrono::steady_clock::now();
  const double since_print = std::chrono::duration<double>(now - last_print_).count();
  if (tty_) {
    if (percent == last_percent_ && since_print < 0.25) return;
    const double elapsed = seconds();
    const double eta = fraction > 0.01 ? elapsed * (1 - fraction) / fraction : 0;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(fraction * kWidth);
    std::string bar(static_cast<size_t>(filled), '#');
    bar.append(static_cast<size_t>(kWidth - filled), '.');
    std::fprintf(stderr, "\r%-12s [%s] %3d%%  ETA %5.1fs ", stage_.c_str(), bar.c_str(), percent,
                 eta);
    std::fflush(stderr);
  } else {
    // Plain log: a line every 10% at most, and not more than every 2 s.
    if (percent / 10 == last_percent_ / 10 || since_print < 2.0) return;
    std::fprintf(stderr, "%s: %d%%\n", stage_.c_str(), percent);
  }
  last_percent_ = percent;
  last_print_ = now;
}

void Progress::finish() {
  if (finished_) return;
  finished_ = true;
  if (g_level < LogLevel::Info || t_quiet) return;
  if (tty_) std::fprintf(stderr, "\r\033[K");
  std::fprintf(stderr, "%-12s done in %.2f s\n", (stage_ + ":").c_str(), seconds());
}

}  // namespace snow
