#include "core/heap.h"

#include <malloc.h>
#include <sys/auxv.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>

namespace snow {
namespace {

constexpr const char* kTunable = "glibc.malloc.hugetlb";
constexpr const char* kReexecMarker = "SNOWMODEL_HUGE_PAGES_REEXEC";
constexpr const char* kThresholdTunable = "glibc.malloc.mmap_threshold";
constexpr int kMmapThreshold = 32 << 20;
// Whether tune_heap set the threshold, for mmap_threshold_status().
bool threshold_set = false;

#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 35))
constexpr bool kGlibcHasTunable = true;
#else
constexpr bool kGlibcHasTunable = false;
#endif

// AddressSanitizer brings its own allocator, which ignores glibc's tunables.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitizerHeap = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitizerHeap = true;
#else
constexpr bool kSanitizerHeap = false;
#endif
#else
constexpr bool kSanitizerHeap = false;
#endif

// The value of `name` in GLIBC_TUNABLES ("" when not named).
std::string tunable_value(const char* name = kTunable) {
  const char* env = std::getenv("GLIBC_TUNABLES");
  if (env == nullptr) return "";
  const std::string tunables = env;
  const std::string key = std::string(name) + "=";
  // Entries are separated by ':'; the last one naming the tunable wins.
  std::string value;
  size_t start = 0;
  while (start <= tunables.size()) {
    size_t end = tunables.find(':', start);
    if (end == std::string::npos) end = tunables.size();
    const std::string entry = tunables.substr(start, end - start);
    if (entry.compare(0, key.size(), key) == 0) value = entry.substr(key.size());
    start = end + 1;
  }
  return value;
}

}  // namespace

void tune_heap(char** argv) {
#if defined(__GLIBC__)
  if (tunable_value(kThresholdTunable).empty() && !kSanitizerHeap) {
    threshold_set = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  }
#endif
  // Set only across the re-execution, so it happens at most once even where
  // glibc drops GLIBC_TUNABLES from the environment (setuid programs).
  if (std::getenv(kReexecMarker) != nullptr) {
    unsetenv(kReexecMarker);
    return;
  }
  if (!kGlibcHasTunable || argv == nullptr || argv[0] == nullptr) return;
  if (getauxval(AT_SECURE) != 0) return;  // glibc ignores tunables there
  if (!tunable_value().empty()) return;   // the user's choice
  const char* env = std::getenv("GLIBC_TUNABLES");
  const bool had = env != nullptr;
  const std::string before = had ? env : "";
  const std::string tunables = (before.empty() ? "" : before + ":") + std::string(kTunable) + "=1";
  if (setenv("GLIBC_TUNABLES", tunables.c_str(), 1) != 0) return;
  if (setenv(kReexecMarker, "1", 1) == 0) execv("/proc/self/exe", argv);
  // No /proc or no permission: go on with the usual pages, and leave the
  // environment as it was for any child process.
  unsetenv(kReexecMarker);
  if (had) {
    setenv("GLIBC_TUNABLES", before.c_str(), 1);
  } else {
    unsetenv("GLIBC_TUNABLES");
  }
}

std::string mmap_threshold_status() {
  if (threshold_set) return "32 MiB (blocks up to that size come from the heap)";
  const std::string value = tunable_value(kThresholdTunable);
  if (!value.empty()) {
    return "as set (GLIBC_TUNABLES " + std::string(kThresholdTunable) + "=" + value + ")";
  }
  if (kSanitizerHeap) return "the allocator's own (AddressSanitizer's)";
  return "the allocator's own (glibc refused 32 MiB)";
}

std::string huge_pages_status() {
  if (!kGlibcHasTunable) return "off (this glibc has no glibc.malloc.hugetlb)";
  const std::string value = tunable_value();
  if (value != "1" && value != "2") {
    return "off (GLIBC_TUNABLES " + std::string(kTunable) + "=" +
           (value.empty() ? "unset" : value) + ")";
  }
  if (kSanitizerHeap) {
    return "off (AddressSanitizer's allocator ignores GLIBC_TUNABLES " + std::string(kTunable) +
           "=" + value + ")";
  }
  // Transparent huge pages: "always [madvise] never", the choice in brackets.
  std::string mode;
  std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
  if (std::getline(thp, mode)) {
    const size_t open = mode.find('['), close = mode.find(']');
    if (open != std::string::npos && close > open) mode = mode.substr(open + 1, close - open - 1);
  }
  if (mode == "never") return "off (the kernel's transparent huge pages are disabled)";
  return "on (GLIBC_TUNABLES " + std::string(kTunable) + "=" + value + ")";
}

}  // namespace snow
