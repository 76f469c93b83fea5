/// \file output.cpp
/// Filling the module's int64 output arrays with pairs and ids, and sorting
/// pairs by (i, j).
#include "output.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <numeric>

namespace broadphase_python {

namespace {
constexpr std::size_t kHuge = std::size_t{2} << 20;
constexpr std::size_t kMapFrom = std::size_t{4} << 20;  // bytes
// Address space reserved for one growing array: nothing is committed
// until written. Outputs past it fall back to a copy into a larger range.
constexpr std::size_t kReserve = std::size_t{1} << 40;

// The range of the last output array freed, kept for the next call's
// output (at most one, of at most kKeepAtMost bytes): its pages are
// already there, where a fresh range's are cleared by the kernel on first
// touch. Measured at 3 000 000 pairs (48 MB) on the 2-core VM: the
// clearing took an eighth of sphere_pairs.
struct KeptRange {
  std::mutex mutex;
  void* p = nullptr;
  std::size_t bytes = 0;
  std::size_t limit = std::size_t{512} << 20;  // the most kept
};
// Never destroyed: arrays may be freed during the interpreter's exit.
KeptRange& kept_range() {
  static KeptRange* k = new KeptRange;
  return *k;
}
}  // namespace

void I64Buffer::grow(std::size_t need) {
  const std::size_t want = std::max(need, 2 * cap_);
  const std::size_t bytes = want * sizeof(std::int64_t);
  if (bytes < kMapFrom) {
    auto* q = static_cast<std::int64_t*>(std::realloc(p_, std::max<std::size_t>(bytes, 64)));
    if (q == nullptr) throw std::bad_alloc();
    p_ = q;
    cap_ = want;
    return;
  }
  const std::size_t writable = (bytes + kHuge - 1) / kHuge * kHuge;
  if (reserved_ == 0) {
    KeptRange& k = kept_range();
    std::unique_lock<std::mutex> lock(k.mutex);
    if (k.p != nullptr && k.bytes >= writable) {
      auto* q = static_cast<std::int64_t*>(k.p);
      const std::size_t held = k.bytes;
      k.p = nullptr;
      k.bytes = 0;
      lock.unlock();
      if (size_ > 0) std::memcpy(q, p_, size_ * sizeof(std::int64_t));
      std::free(p_);
      p_ = q;
      reserved_ = mapped_ = held;
      cap_ = held / sizeof(std::int64_t);
      return;
    }
  }
  if (reserved_ > 0 && mapped_ == reserved_ && writable > reserved_) {
    // A kept range, all writable, grown where it is or moved (its pages
    // move with it, not copied).
    void* q = ::mremap(p_, reserved_, writable, MREMAP_MAYMOVE);
    if (q != MAP_FAILED) {
#ifdef MADV_HUGEPAGE
      ::madvise(q, writable, MADV_HUGEPAGE);  // advice only
#endif
      p_ = static_cast<std::int64_t*>(q);
      reserved_ = mapped_ = writable;
      cap_ = writable / sizeof(std::int64_t);
      return;
    }
  }
  if (reserved_ == 0 || writable > reserved_) {
    // A new range, aligned to 2 MiB (huge pages), the contents copied once.
    const std::size_t span = std::max(kReserve, writable) + kHuge;
    void* base =
        ::mmap(nullptr, span, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (base == MAP_FAILED) throw std::bad_alloc();
    const auto addr = reinterpret_cast<std::uintptr_t>(base);
    const std::uintptr_t aligned = (addr + kHuge - 1) / kHuge * kHuge;
    if (aligned != addr) ::munmap(base, aligned - addr);
    const std::size_t held = span - (aligned - addr);
    auto* q = reinterpret_cast<std::int64_t*>(aligned);
    if (::mprotect(q, writable, PROT_READ | PROT_WRITE) != 0) {
      ::munmap(q, held);
      throw std::bad_alloc();
    }
#ifdef MADV_HUGEPAGE
    ::madvise(q, held, MADV_HUGEPAGE);  // advice only: failure changes nothing
#endif
    if (size_ > 0) std::memcpy(q, p_, size_ * sizeof(std::int64_t));
    release();
    p_ = q;
    reserved_ = held;
    mapped_ = writable;
    cap_ = writable / sizeof(std::int64_t);
    return;
  }
  if (::mprotect(reinterpret_cast<char*>(p_) + mapped_, writable - mapped_,
                 PROT_READ | PROT_WRITE) != 0)
    throw std::bad_alloc();
  mapped_ = writable;
  cap_ = writable / sizeof(std::int64_t);
}

void I64Buffer::trim() {
  if (reserved_ == 0 || mapped_ == reserved_) return;
  ::munmap(reinterpret_cast<char*>(p_) + mapped_, reserved_ - mapped_);
  reserved_ = mapped_;
}

void I64Buffer::release() {
  if (reserved_ > 0) {
    // A whole writable range (trimmed) is kept for the next output in
    // place of a smaller one; the other is returned.
    if (mapped_ == reserved_) {
      KeptRange& k = kept_range();
      std::lock_guard<std::mutex> lock(k.mutex);
      if (reserved_ <= k.limit && (k.p == nullptr || k.bytes < reserved_)) {
        void* old = k.p;
        k.p = p_;
        p_ = static_cast<std::int64_t*>(old);
        std::swap(k.bytes, reserved_);
      }
    }
    if (p_ != nullptr) ::munmap(p_, reserved_);
  } else
    std::free(p_);
  p_ = nullptr;
  size_ = cap_ = reserved_ = mapped_ = 0;
}

std::size_t kept_output_bytes() {
  KeptRange& k = kept_range();
  std::lock_guard<std::mutex> lock(k.mutex);
  return k.bytes;
}

void set_output_keep_limit(std::size_t bytes) {
  KeptRange& k = kept_range();
  std::lock_guard<std::mutex> lock(k.mutex);
  k.limit = bytes;
  if (k.p != nullptr && k.bytes > bytes) {
    ::munmap(k.p, k.bytes);
    k.p = nullptr;
    k.bytes = 0;
  }
}

void append_pairs(I64Vec& out, std::span<const bp::IndexPair> chunk) {
  const std::size_t k = out.size();
  out.resize(k + 2 * chunk.size());
  std::int64_t* p = out.data() + k;
  for (const bp::IndexPair& q : chunk) {
    *p++ = q.i;
    *p++ = q.j;
  }
}

void sort_pairs(PairVec& pairs, std::size_t n) {
  if (pairs.size() < 2) return;
  std::vector<std::uint32_t> start(n + 1, 0);
  for (const bp::IndexPair& p : pairs) ++start[p.i + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  PairVec out(pairs.size());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const bp::IndexPair& p : pairs) out[fill[p.i]++] = p;
  for (std::size_t i = 0; i < n; ++i)
    std::sort(out.begin() + start[i], out.begin() + start[i + 1],
              [](const bp::IndexPair& a, const bp::IndexPair& b) { return a.j < b.j; });
  pairs.swap(out);
}

IntArray to_int_array(std::span<const bp::IndexPair> pairs) {
  IntArray a;
  a.cols = 2;
  a.rows = pairs.size();
  append_pairs(a.data, pairs);
  a.data.trim();
  return a;
}

IntArray ids_array(std::span<const std::uint32_t> ids) {
  IntArray a;
  a.rows = ids.size();
  a.data.assign(ids.begin(), ids.end());
  return a;
}

}  // namespace broadphase_python
