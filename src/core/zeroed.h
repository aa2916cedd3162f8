#pragma once
// A fixed-size array of zeros that costs nothing where it is never written.
//
// Large blocks come straight from the operating system as zero pages, so
// the pages that a stage never writes are never faulted in or cleared: the
// per layer texel arrays of a map whose lower layers hold few surfaces (a
// terrain with a few tables: three layers, two of them nearly empty) cost
// what their surfaces do. A std::vector would write every element first.
//
// Those blocks are mapped here in small pages (MADV_NOHUGEPAGE), not taken
// from calloc: the heap has transparent huge pages (core/heap.h), and the
// kernel clears a huge page whole, 2 MiB, at the first write anywhere in
// it, which undoes the sparse writing (and raises the peak memory).
// Smaller blocks come from calloc, whose huge pages serve the small jobs
// (their arrays are few and mostly written).
//
// A mapped page that is read before it is written maps the kernel's shared
// zero page, and its first write then copies that and flushes the TLBs of
// the other cores running the process's threads, several times what
// writing a fresh page first costs.
// Where a stage knows which pages it will write, populate() faults them in
// for writing first, a run of pages per call.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <new>
#include <type_traits>

#include <sys/mman.h>
#include <unistd.h>

namespace snow {

template <class T>
class ZeroedArray {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>,
                "ZeroedArray holds plain values whose all-zero bytes are a zero");

 public:
  ZeroedArray() = default;
  /// Blocks of at least this many bytes are mapped in small pages.
  static constexpr size_t kMappedBytes = size_t(2) << 20;

  /// `count` zeros; throws std::bad_alloc when the memory cannot be had.
  explicit ZeroedArray(size_t count) : size_(count) {
    if (count == 0) return;
    if (count > SIZE_MAX / sizeof(T)) throw std::bad_alloc();
    const size_t bytes = count * sizeof(T);
    void* p = nullptr;
    if (bytes >= kMappedBytes) {
      p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      madvise(p, bytes, MADV_NOHUGEPAGE);  // where the kernel's THP mode is "always"
    } else {
      p = std::calloc(count, sizeof(T));
      if (!p) throw std::bad_alloc();
    }
    data_ = std::unique_ptr<T[], Free>(static_cast<T*>(p), Free{bytes});
  }

  /// Faults in the pages holding elements [begin, end) (end clamped to the
  /// size) for writing, in one call (MADV_POPULATE_WRITE, Linux 5.14). The
  /// values stay zero where never written. Returns whether it did: false for
  /// blocks from calloc, an empty range, or a kernel without it.
  bool populate(size_t begin, size_t end) {
    end = std::min(end, size_);
    if (!data_ || size_ * sizeof(T) < kMappedBytes || begin >= end) return false;
    static const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
    const uintptr_t lo = reinterpret_cast<uintptr_t>(data_.get() + begin) / page * page;
    const uintptr_t hi = reinterpret_cast<uintptr_t>(data_.get() + end);
    constexpr int kPopulateWrite = 23;  // MADV_POPULATE_WRITE, where the headers lack it
    return madvise(reinterpret_cast<void*>(lo), hi - lo, kPopulateWrite) == 0;
  }
  size_t size() const { return size_; }
  T* data() { return data_.get(); }
  const T* data() const { return data_.get(); }
  T& operator[](size_t k) { return data_[k]; }
  const T& operator[](size_t k) const { return data_[k]; }
  const T* begin() const { return data_.get(); }
  const T* end() const { return data_.get() + size_; }

 private:
  struct Free {
    size_t bytes = 0;
    void operator()(T* p) const {
      if (bytes >= kMappedBytes) {
        munmap(p, bytes);
      } else {
        std::free(p);
      }
    }
  };
  std::unique_ptr<T[], Free> data_;
  size_t size_ = 0;
};

}  // namespace snow
