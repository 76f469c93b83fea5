// Vectors for the lean path's large per-call arrays (a million objects'
// boxes, grid entries, bucket starts): their elements are not zeroed on
// resize (every one is written before it is read), and blocks of 2 MiB and
// more are aligned to 2 MiB and offered to the kernel as transparent huge
// pages. Measured at 1 000 000 spheres on the 2-core EPYC VM: zeroing and
// first-touch page faults of these arrays took about 40% of a one-shot call;
// at 100 000 (4 MB of records, under the first threshold of 4 MiB) the
// faults took 24 of 38 ms of `sphere_pairs`.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>
#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace broadphase::arrays::detail {

// Whether freed blocks are kept (not under AddressSanitizer).
bool keeps_big_blocks() noexcept;
// A freed block of `bytes` (a multiple of 2 MiB) kept for reuse, or null.
void* take_big_block(std::size_t bytes) noexcept;
// Keeps a freed block for reuse; false when the cache is full (the caller
// frees it).
bool keep_big_block(void* p, std::size_t bytes) noexcept;

template <class T>
struct BigAllocator {
  using value_type = T;
  static constexpr std::size_t kHuge = std::size_t{2} << 20;

  BigAllocator() = default;
  template <class U>
  BigAllocator(const BigAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    if (n > static_cast<std::size_t>(-1) / sizeof(T)) throw std::bad_array_new_length();
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHuge) return static_cast<T*>(::operator new(bytes));
    const std::size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
    if (void* kept = take_big_block(rounded)) return static_cast<T*>(kept);
    void* p = std::aligned_alloc(kHuge, rounded);
    if (p == nullptr) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    ::madvise(p, rounded, MADV_HUGEPAGE);  // advice only: failure changes nothing
#endif
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHuge)
      ::operator delete(p);
    else if (!keep_big_block(p, (bytes + kHuge - 1) / kHuge * kHuge))
      std::free(p);
  }
  // Default-initialises (no zeroing) where a std::vector would value-initialise.
  template <class U>
  void construct(U* p) noexcept(noexcept(::new (static_cast<void*>(p)) U)) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  friend bool operator==(const BigAllocator&, const BigAllocator&) { return true; }
};

template <class T>
using BigVector = std::vector<T, BigAllocator<T>>;

// Empties a vector and returns its memory. (`v = {}` does not: it is the
// assignment from an empty initializer list, which keeps the capacity.)
template <class V>
void free_vector(V& v) noexcept {
  V().swap(v);
}

}  // namespace broadphase::arrays::detail
