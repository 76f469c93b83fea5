/// \file detail/pair_table.hpp
/// `detail::PairTable`: a hash set of unordered pairs of 32-bit object ids,
/// the persistent pair set of `sap` and `aabb-tree`.
#pragma once

#include <broadphase/handle.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

namespace detail {

/// The finaliser of splitmix64: cheap and mixes both halves of the key into
/// the low bits, which index the table.
inline std::uint64_t mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// An open-addressing (linear probing) set of unordered pairs of 32-bit
/// ids, with the members also kept densely in an array so that iterating
/// them touches only live pairs. insert / erase / contains: O(1) expected;
/// erase uses backward-shift deletion, so there are no tombstones and the
/// table never degrades. Not thread-safe for writers.
class PairTable {
 public:
  /// One member: ids with a <= b.
  struct Pair {
    std::uint32_t a, b;
  };

  /// Adds {a, b}; returns false when it was already there.
  bool insert(std::uint32_t a, std::uint32_t b);
  /// Removes {a, b}; returns false when it was not there.
  bool erase(std::uint32_t a, std::uint32_t b);
  /// True when {a, b} is a member.
  bool contains(std::uint32_t a, std::uint32_t b) const { return find(key(a, b)) != kEmpty; }
  /// The members, in no particular order (invalidated by insert and erase).
  std::span<const Pair> pairs() const { return dense_; }
  /// Number of members.
  std::size_t size() const { return dense_.size(); }
  /// Removes every member; keeps the capacity.
  void clear();
  /// Grows the table so that `n` members fit without rehashing.
  void reserve(std::size_t n);
  /// Bytes held (capacities).
  std::size_t memory_bytes() const {
    return slots_.capacity() * sizeof(Slot) + dense_.capacity() * sizeof(Pair);
  }
  /// Throws std::logic_error when the table and the dense array disagree.
  void validate() const;

  /// The 64-bit key of the unordered pair {a, b}: smaller id in the high half.
  static std::uint64_t key(std::uint32_t a, std::uint32_t b) {
    return a < b ? (std::uint64_t(a) << 32) | b : (std::uint64_t(b) << 32) | a;
  }

 private:
  struct Slot {
    std::uint64_t key;
    std::uint32_t dense;  // position in dense_
  };
  static constexpr std::uint32_t kEmpty = 0xffffffffu;
  static constexpr std::uint64_t kEmptyKey = ~std::uint64_t{0};

  std::size_t home(std::uint64_t k) const;
  // Slot index holding `k`, or kEmpty.
  std::uint32_t find(std::uint64_t k) const;
  void rehash(std::size_t capacity);

  std::vector<Slot> slots_;  // power-of-two size, at most half full
  std::vector<Pair> dense_;
};

}  // namespace detail

}  // namespace broadphase
