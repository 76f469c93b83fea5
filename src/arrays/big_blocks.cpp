#include <broadphase/arrays/arrays.hpp>
#include <chrono>
#include <cstdlib>
#include <mutex>

#include "big_vector.hpp"

// Under AddressSanitizer no block is kept: a use after free of a kept
// block would go unseen.
#if defined(__SANITIZE_ADDRESS__)
#define BROADPHASE_KEEP_BLOCKS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define BROADPHASE_KEEP_BLOCKS 0
#endif
#endif
#ifndef BROADPHASE_KEEP_BLOCKS
#define BROADPHASE_KEEP_BLOCKS 1
#endif

namespace broadphase::arrays::detail {

namespace {

// Freed blocks kept for the next call, at most kSlots of them and the limit
// bytes in all, each for at most kKeepFor: a block not taken again by then
// is returned to the system at the next take or keep. A kept block's pages
// are already there; a fresh block's are cleared by the kernel on first
// touch, and on every call the per-call arrays were fresh. Measured on one
// core of the 2-core VM, alternated: the tracker's calls at scaled-even
// 1 024 000 (40 calls) 93.0-93.7 -> 77.2-78.6 ms median; 102 400 and
// scaled-uneven 1 024 000 unchanged within 1%; sphere_pairs at 10^6
// spheres from Python about 3 ms faster. And the process smaller: at
// 1 024 000 after 40 calls VmHWM 427 -> 205 MB (freed to the C heap, the
// blocks had stayed resident and the next call's came fresh), with 14-55
// bytes an object kept here between calls. Sixteen slots rather than
// eight since a movers call has more per-call arrays (the lists laid out
// in the visit order, the movers' columns): at scaled-even 10 240 000,
// with eight, perf put 9.5% of a call on clearing fresh pages; alternated,
// 16 calls, median 667 -> 615 ms, VmHWM 1.76 -> 1.62 GB; the million the
// same (50.7-53.6 ms against 52.8-53.6), its scratch kept 30 -> 72 B/object.
constexpr std::size_t kSlots = 16;
constexpr std::size_t kDefaultLimit = std::size_t{512} << 20;
constexpr auto kKeepFor = std::chrono::seconds(2);

struct Kept {
  void* p = nullptr;
  std::size_t bytes = 0;
  std::chrono::steady_clock::time_point since;
};

struct Blocks {
  std::mutex mutex;
  Kept slot[kSlots];
  // Blocks handed out again, with their sizes: a vector may take a block
  // up to twice its need, and gives back only its own size.
  Kept lent[kSlots];
  std::size_t kept = 0;  // bytes
  std::size_t limit = kDefaultLimit;

  // Frees the blocks kept too long (under the mutex).
  void expire(std::chrono::steady_clock::time_point now) {
    for (Kept& k : slot)
      if (k.p != nullptr && now - k.since > kKeepFor) {
        std::free(k.p);
        kept -= k.bytes;
        k = Kept{};
      }
  }
};

// Never destroyed: a vector freed during the program's exit, after the
// statics' destructors, may still keep a block here.
Blocks& blocks() {
  static Blocks* b = new Blocks;
  return *b;
}

}  // namespace

bool keeps_big_blocks() noexcept { return BROADPHASE_KEEP_BLOCKS != 0; }

void* take_big_block(std::size_t bytes) noexcept {
  if (!BROADPHASE_KEEP_BLOCKS) return nullptr;
  Blocks& b = blocks();
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard<std::mutex> lock(b.mutex);
  b.expire(now);
  Kept* best = nullptr;
  for (Kept& k : b.slot)
    if (k.p != nullptr && k.bytes >= bytes && k.bytes / 2 <= bytes &&
        (best == nullptr || k.bytes < best->bytes))
      best = &k;
  if (best == nullptr) return nullptr;
  void* p = best->p;
  b.kept -= best->bytes;
  for (Kept& l : b.lent)
    if (l.p == nullptr) {
      l = *best;
      break;
    }
  *best = Kept{};
  return p;
}

bool keep_big_block(void* p, std::size_t bytes) noexcept {
  if (!BROADPHASE_KEEP_BLOCKS) return false;
  Blocks& b = blocks();
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard<std::mutex> lock(b.mutex);
  b.expire(now);
  for (Kept& l : b.lent)
    if (l.p == p) {
      bytes = l.bytes;
      l = Kept{};
      break;
    }
  if (b.kept + bytes > b.limit) return false;
  for (Kept& k : b.slot)
    if (k.p == nullptr) {
      k = Kept{p, bytes, now};
      b.kept += bytes;
      return true;
    }
  return false;
}

}  // namespace broadphase::arrays::detail

namespace broadphase::arrays {

std::size_t scratch_bytes() {
  detail::Blocks& b = detail::blocks();
  std::lock_guard<std::mutex> lock(b.mutex);
  return b.kept;
}

void set_scratch_limit(std::size_t bytes) {
  detail::Blocks& b = detail::blocks();
  std::lock_guard<std::mutex> lock(b.mutex);
  b.limit = bytes;
  for (detail::Kept& k : b.slot)
    if (k.p != nullptr && b.kept > b.limit) {
      std::free(k.p);
      b.kept -= k.bytes;
      k = detail::Kept{};
    }
}

std::size_t scratch_limit() {
  detail::Blocks& b = detail::blocks();
  std::lock_guard<std::mutex> lock(b.mutex);
  return b.limit;
}

}  // namespace broadphase::arrays
