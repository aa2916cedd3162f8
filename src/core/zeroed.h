#pragma once
// A fixed-size array of zeros that costs nothing where it is never written.
//
// Large blocks come straight from the operating system as zero pages
// (calloc skips the clearing for them), so the pages that a stage never
// writes are never faulted in or cleared: the per layer texel arrays of a
// map whose lower layers hold few surfaces (a terrain with a few tables:
// three layers, two of them nearly empty) cost what their surfaces do. A
// std::vector would write every element first.
#include <cstddef>
#include <cstdlib>
#include <memory>
#include <new>
#include <type_traits>

namespace snow {

template <class T>
class ZeroedArray {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>,
                "ZeroedArray holds plain values whose all-zero bytes are a zero");

 public:
  ZeroedArray() = default;
  /// `count` zeros; throws std::bad_alloc when the memory cannot be had.
  explicit ZeroedArray(size_t count) : size_(count) {
    if (count == 0) return;
    data_.reset(static_cast<T*>(std::calloc(count, sizeof(T))));
    if (!data_) throw std::bad_alloc();
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
    void operator()(T* p) const { std::free(p); }
  };
  std::unique_ptr<T[], Free> data_;
  size_t size_ = 0;
};

}  // namespace snow
