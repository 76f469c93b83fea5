// Sorting 64-bit keys by their high word, for the lean path and the
// handle structures' pools.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace broadphase::detail {

// Sorts keys by their high 32 bits, stably: an LSD radix sort, 11 bits a
// pass, as many passes as the largest key needs (std::sort took half of a
// pool compaction's time at 102 400 objects). `Keys`: a vector of
// std::uint64_t with any allocator.
template <class Keys>
void sort_by_high_word(Keys& keys) {
  constexpr int kBits = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kBits;
  std::uint64_t top = 0;
  for (const std::uint64_t k : keys) top = std::max(top, k >> 32);
  Keys out(keys.size());
  for (int shift = 32; shift < 64 && (top >> (shift - 32)) > 0; shift += kBits) {
    std::vector<std::uint32_t> start(kBuckets + 1, 0);
    for (const std::uint64_t k : keys) ++start[((k >> shift) & (kBuckets - 1)) + 1];
    for (std::size_t b = 0; b < kBuckets; ++b) start[b + 1] += start[b];
    for (const std::uint64_t k : keys) out[start[(k >> shift) & (kBuckets - 1)]++] = k;
    keys.swap(out);
  }
}

}  // namespace broadphase::detail
