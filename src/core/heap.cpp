#include "core/heap.h"

#include <dirent.h>
#include <malloc.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>

#include "core/heap_env.h"

namespace snow {
namespace {

constexpr const char* kTunable = SNOW_HUGE_PAGE_TUNABLE;
constexpr const char* kThresholdTunable = "glibc.malloc.mmap_threshold";
constexpr int kMmapThreshold = 32 << 20;
// Whether tune_heap set the threshold, for mmap_threshold_status().
bool threshold_set = false;
// Whether the heap has huge pages because of a tunable that is ours (added
// by tune_heap or the launcher, which set the marker), not the user's
// (AddressSanitizer's allocator ignores it: no huge pages then).
bool huge_pages_ours = false;
// Whether turn_off_huge_pages turned them off.
bool huge_pages_fitted = false;

constexpr bool kGlibcHasTunable = SNOW_GLIBC_HAS_HUGE_PAGE_TUNABLE;

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
  size_t length = 0;
  const char* value = env != nullptr ? snow_tunable_value(env, name, &length) : nullptr;
  return value != nullptr ? std::string(value, length) : std::string();
}

}  // namespace

void tune_heap(char** argv) {
#if defined(__GLIBC__)
  if (tunable_value(kThresholdTunable).empty() && !kSanitizerHeap) {
    threshold_set = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  }
#endif
  // The marker is set only across the re-execution (or by the launcher).
  if (std::getenv(SNOW_HUGE_PAGE_MARKER) != nullptr) {
    unsetenv(SNOW_HUGE_PAGE_MARKER);
    huge_pages_ours = tunable_value() == "1" && !kSanitizerHeap;
    return;
  }
  if (argv == nullptr || argv[0] == nullptr) return;
  const char* env = std::getenv("GLIBC_TUNABLES");
  const bool had = env != nullptr;
  const std::string before = had ? env : "";
  if (!snow_add_huge_page_tunable()) return;
  execv("/proc/self/exe", argv);
  // No /proc or no permission: go on with the usual pages, and leave the
  // environment as it was for any child process.
  unsetenv(SNOW_HUGE_PAGE_MARKER);
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
  std::string status = "on (GLIBC_TUNABLES " + std::string(kTunable) + "=" + value + ")";
  if (huge_pages_ours && free_pages_reported()) {
    status +=
        "; jobs of 512 x 512 texels or 32 MiB of input or more turn them off, as this machine "
        "hands free memory back to its host (virtio-balloon free page reporting)";
  }
  return status;
}

bool free_pages_reported(const char* devices) {
  DIR* dir = opendir(devices);
  if (dir == nullptr) return false;
  bool reported = false;
  while (const dirent* entry = readdir(dir)) {
    const std::string device = std::string(devices) + "/" + entry->d_name;
    std::string id, features;
    if (entry->d_name[0] == '.' || !std::getline(std::ifstream(device + "/device"), id) ||
        std::strtol(id.c_str(), nullptr, 0) != 5 ||
        access((device + "/driver").c_str(), F_OK) != 0 ||
        !std::getline(std::ifstream(device + "/features"), features)) {
      continue;
    }
    if (features.size() > 5 && features[5] == '1') {
      reported = true;
      break;
    }
  }
  closedir(dir);
  return reported;
}

bool turn_off_huge_pages() {
  if (huge_pages_fitted || !huge_pages_ours) return false;
  huge_pages_fitted = prctl(PR_SET_THP_DISABLE, 1, 0, 0, 0) == 0;
  return huge_pages_fitted;
}

}  // namespace snow
