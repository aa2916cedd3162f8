#include <gtest/gtest.h>
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"
#include "core/fs.h"
#include "core/heap.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/zeroed.h"

namespace fs = std::filesystem;

namespace {
fs::path temp_dir(const char* name) {
  fs::path dir = fs::temp_directory_path() / ("snow_test_core_" + std::string(name));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}
}  // namespace

TEST(AtomicWrite, WritesAndLeavesNoTemporary) {
  const fs::path dir = temp_dir("write");
  snow::write_text_atomically(dir / "out.txt", "hello");
  std::ifstream in(dir / "out.txt");
  std::string text;
  in >> text;
  EXPECT_EQ(text, "hello");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

// An existing file is swapped out and removed (replace_file), not renamed
// over: the target then holds the new text, nothing else is left in the
// folder, and a reader that had the old file open still reads it whole.
TEST(AtomicWrite, ReplacesAnExistingFileAndLeavesNoTemporary) {
  const fs::path dir = temp_dir("replace");
  snow::write_text_atomically(dir / "out.txt", "old");
  std::ifstream reader(dir / "out.txt");
  snow::write_text_atomically(dir / "out.txt", "new");
  std::ifstream in(dir / "out.txt");
  std::string text, old_text;
  in >> text;
  reader >> old_text;
  EXPECT_EQ(text, "new");
  EXPECT_EQ(old_text, "old");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(AtomicWrite, FailureKeepsOldFileAndRemovesTemporary) {
  const fs::path dir = temp_dir("fail");
  snow::write_text_atomically(dir / "out.txt", "old");
  EXPECT_THROW(snow::write_file_atomically(dir / "out.txt",
                                           [](const fs::path& tmp) {
                                             std::ofstream(tmp) << "partial";
                                             throw snow::IOError("disk full");
                                           }),
               snow::IOError);
  std::ifstream in(dir / "out.txt");
  std::string text;
  in >> text;
  EXPECT_EQ(text, "old");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(AtomicWrite, MissingFolderIsIOError) {
  EXPECT_THROW(snow::write_text_atomically("/nonexistent_snow_dir/x.txt", "x"), snow::IOError);
}

TEST(Errors, ExitCodes) {
  EXPECT_EQ(snow::InputError("x").exit_code(), snow::kExitBadInput);
  EXPECT_EQ(snow::GLError("x").exit_code(), snow::kExitNoGL);
  EXPECT_EQ(snow::IOError("x").exit_code(), snow::kExitIO);
}

TEST(ParallelFor, CallsEveryIndexOnce) {
  for (unsigned threads : {0u, 1u, 3u, 64u}) {
    std::vector<std::atomic<int>> calls(1000);
    snow::parallel_for(
        calls.size(), [&](size_t i) { ++calls[i]; }, threads);
    for (size_t i = 0; i < calls.size(); ++i) ASSERT_EQ(calls[i].load(), 1) << i << ", " << threads;
  }
  int none = 0;
  snow::parallel_for(0, [&](size_t) { ++none; });
  EXPECT_EQ(none, 0);
}

// parallel_sum adds its parts in range order: the bits of the serial sum of
// the parts, whatever the number of cores, where a sum in another order
// rounds differently.
TEST(ParallelSum, AddsThePartsInOrder) {
  std::vector<double> values(100003);
  for (size_t i = 0; i < values.size(); ++i) values[i] = 1.0 / double(i + 1) * (i % 2 ? 1e8 : 1.0);
  const size_t chunk = 1000;
  const auto part = [&](size_t begin, size_t end) {
    double s = 0.0;
    for (size_t i = begin; i < end; ++i) s += values[i];
    return s;
  };
  double serial = 0.0;
  for (size_t begin = 0; begin < values.size(); begin += chunk) {
    serial += part(begin, std::min(values.size(), begin + chunk));
  }
  for (int run = 0; run < 5; ++run) {
    EXPECT_EQ(snow::parallel_sum(values.size(), chunk, part), serial);
  }
  EXPECT_EQ(snow::parallel_sum(0, chunk, part), 0.0);
  EXPECT_EQ(snow::parallel_sum(5, 0, part), part(0, 5));  // a chunk of 0 is taken as 1
}

TEST(ParallelFor, RethrowsTheFirstErrorAfterAllThreadsStop) {
  for (unsigned threads : {1u, 4u}) {
    std::atomic<int> calls{0};
    std::atomic<bool> thrown{false};
    EXPECT_THROW(snow::parallel_for(
                     100000,
                     [&](size_t i) {
                       ++calls;
                       if (i == 10) {
                         thrown = true;
                         throw std::runtime_error("index 10");
                       }
                       // Later indices wait for the throw (the thread holding
                       // index 10 may be descheduled for all the others), then
                       // leave the thrower time to reach its handler.
                       if (i > 10) {
                         while (!thrown) std::this_thread::yield();
                         std::this_thread::sleep_for(std::chrono::milliseconds(1));
                       }
                     },
                     threads),
                 std::runtime_error);
    // The remaining indices are skipped once one call has thrown.
    EXPECT_LT(calls.load(), 1000) << threads;
  }
}

// tune_heap (without argv: no re-execution) sets glibc's mmap threshold, so
// that a block of 8 MiB comes from the heap rather than a mapping of its
// own (mallinfo2's hblks counts those), and says so in `info`'s line.
TEST(Heap, LargeBlocksComeFromTheHeap) {
  snow::tune_heap(nullptr);
  const std::string status = snow::mmap_threshold_status();
  if (status.rfind("as set", 0) == 0 || status.find("AddressSanitizer") != std::string::npos)
    GTEST_SKIP() << "the threshold is not ours to set here: " << status;
  ASSERT_EQ(status.rfind("32 MiB", 0), 0u) << status;
  const size_t mapped = mallinfo2().hblks;
  std::vector<char> block(size_t(8) << 20, 1);
  EXPECT_EQ(mallinfo2().hblks, mapped);
  std::vector<char> huge(size_t(40) << 20, 1);  // over the threshold: mapped
  EXPECT_EQ(mallinfo2().hblks, mapped + 1);
}

// free_pages_reported reads the virtio devices the kernel lists: only
// a memory balloon (device 5), bound to its driver, with free page
// reporting (feature bit 5) counts.
TEST(Heap, FreePageReportingIsFoundInTheVirtioDevices) {
  const fs::path dir = temp_dir("virtio");
  const auto device = [&](const std::string& name, const std::string& id,
                          const std::string& features, bool bound) {
    const fs::path d = dir / name;
    fs::create_directories(d);
    std::ofstream(d / "device") << id << "\n";
    std::ofstream(d / "features") << features << "\n";
    if (bound) fs::create_directories(d / "driver");
  };
  const std::string reporting = "0110010" + std::string(57, '0');  // bits 1, 2 and 5
  const std::string no_reporting = "0110000" + std::string(57, '0');
  const auto reported = [&] { return snow::free_pages_reported(dir.string().c_str()); };
  EXPECT_FALSE(snow::free_pages_reported((dir / "absent").string().c_str()));
  EXPECT_FALSE(reported());                      // no devices
  device("virtio0", "0x0002", reporting, true);  // a block device: bit 5 means something else
  EXPECT_FALSE(reported());
  device("virtio1", "0x0005", no_reporting, true);  // a balloon without reporting
  EXPECT_FALSE(reported());
  device("virtio2", "0x0005", reporting, false);  // no driver: nothing reported
  EXPECT_FALSE(reported());
  device("virtio3", "0x0005", reporting, true);
  EXPECT_TRUE(reported());
  fs::remove_all(dir);
}

namespace {

// The pages of `count` floats from `data` that are resident (mincore).
size_t resident_pages(const float* data, size_t count) {
  const size_t page = size_t(sysconf(_SC_PAGESIZE));
  const uintptr_t begin = reinterpret_cast<uintptr_t>(data) / page * page;
  const uintptr_t end = reinterpret_cast<uintptr_t>(data + count);
  std::vector<unsigned char> resident((end - begin + page - 1) / page);
  EXPECT_EQ(mincore(reinterpret_cast<void*>(begin), end - begin, resident.data()), 0);
  size_t pages = 0;
  for (unsigned char r : resident) pages += r & 1;
  return pages;
}

}  // namespace

// A large ZeroedArray reads as zeros and costs only the pages written: one
// write makes one small page resident, not the 2 MiB huge page (512 small
// ones) that the heap's huge pages (or the kernel's THP mode "always")
// would clear whole. Small arrays come from calloc, zeroed too.
TEST(ZeroedArray, LargeArraysCostOnlyThePagesWritten) {
  const size_t count = size_t(8) << 20;  // 32 MiB of floats
  snow::ZeroedArray<float> large(count);
  ASSERT_GE(count * sizeof(float), snow::ZeroedArray<float>::kMappedBytes);
  EXPECT_EQ(large[0], 0.0f);
  EXPECT_EQ(large[count - 1], 0.0f);
  large[count / 2] = 1.0f;
  const size_t pages = resident_pages(large.data(), count);
  EXPECT_LE(pages, 3u) << pages << " pages resident after one write";
  EXPECT_EQ(large[count / 2], 1.0f);
  // The kernel keeps it off huge pages whatever the heap or THP mode: its
  // mapping carries the "nh" flag (MADV_NOHUGEPAGE).
  const uintptr_t begin = reinterpret_cast<uintptr_t>(large.data());
  const uintptr_t end = reinterpret_cast<uintptr_t>(large.data() + count);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false, no_huge = false;
  while (std::getline(smaps, line)) {
    unsigned long lo = 0, hi = 0;
    if (std::sscanf(line.c_str(), "%lx-%lx ", &lo, &hi) == 2 && line.find(' ') < line.find(':')) {
      inside = lo <= begin && end <= hi;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      no_huge = line.find(" nh") != std::string::npos;
    }
  }
  EXPECT_TRUE(no_huge) << "the array's mapping is not marked MADV_NOHUGEPAGE";

  snow::ZeroedArray<double> small(1000);
  ASSERT_LT(1000 * sizeof(double), snow::ZeroedArray<double>::kMappedBytes);
  for (size_t k = 0; k < small.size(); ++k) ASSERT_EQ(small[k], 0.0);
  small[999] = 2.0;
  EXPECT_EQ(small[999], 2.0);
}

// populate() makes the pages of a range resident in one call, and only
// those: the values read as zeros, and writes land as before. Small arrays
// (calloc) have nothing to populate.
TEST(ZeroedArray, PopulateFaultsInOnlyTheRange) {
  const size_t count = size_t(8) << 20;  // 32 MiB of floats
  snow::ZeroedArray<float> large(count);
  const size_t page = size_t(sysconf(_SC_PAGESIZE));
  const size_t before = resident_pages(large.data(), count);
  const size_t first = count / 4, floats = 64 * page / sizeof(float);  // 64 pages
  if (!large.populate(first, first + floats)) GTEST_SKIP() << "no MADV_POPULATE_WRITE here";
  const size_t after = resident_pages(large.data(), count);
  EXPECT_GE(after, before + 64);
  EXPECT_LE(after, before + 66);  // the range's pages, one more at each end if unaligned
  for (size_t k = first; k < first + floats; k += 997) ASSERT_EQ(large[k], 0.0f);
  large[first + 5] = 3.0f;
  EXPECT_EQ(large[first + 5], 3.0f);
  EXPECT_FALSE(large.populate(count, count + 10));  // clamped: an empty range
  snow::ZeroedArray<float> small(1000);
  EXPECT_FALSE(small.populate(0, 1000));
}

// A quiet thread prints nothing but still records its warnings; other
// threads print as before.
TEST(Log, QuietThreadPrintsNothingAndKeepsWarnings) {
  snow::set_log_level(snow::LogLevel::Debug);
  snow::clear_warnings();
  testing::internal::CaptureStderr();
  std::thread([] {
    const snow::QuietThread quiet;
    snow::log_info("quiet info");
    snow::log_debug("quiet debug");
    snow::log_warn("quiet warning");
  }).join();
  snow::log_info("loud info");
  const std::string printed = testing::internal::GetCapturedStderr();
  EXPECT_EQ(printed.find("quiet"), std::string::npos) << printed;
  EXPECT_NE(printed.find("loud info"), std::string::npos) << printed;
  ASSERT_EQ(snow::recorded_warnings().size(), 1u);
  EXPECT_EQ(snow::recorded_warnings()[0], "quiet warning");
  snow::set_log_level(snow::LogLevel::Info);
}
