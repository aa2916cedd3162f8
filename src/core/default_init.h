#pragma once
// An allocator whose value-less construction default-initializes: a
// std::vector of plain values using it resizes without writing the new
// elements, so that the caller can fill them where it likes (on all cores,
// snow::SnowMaps). The other constructions are std::allocator's.
#include <memory>
#include <new>
#include <type_traits>
#include <utility>

namespace snow {

template <class T>
class DefaultInitAllocator : public std::allocator<T> {
 public:
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() noexcept = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}

  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

}  // namespace snow
