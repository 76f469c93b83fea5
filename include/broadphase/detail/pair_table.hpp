/// \file detail/pair_table.hpp
/// A hash set of unordered object pairs (`detail::PairTable`, shared by the
/// sweep-and-prune and the pair cache) and `PairCache`, which turns each
/// frame's overlapping pairs into contact events: begun, persisting, ended.
#pragma once

#include <broadphase/structure.hpp>
#include <broadphase/handle.hpp>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

namespace detail {

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

/// What happened to a pair between two frames.
enum class ContactEvent : std::uint8_t {
  begun,       ///< overlaps now, did not in the previous frame
  persisting,  ///< overlapped in the previous frame and still does
  ended,       ///< overlapped in the previous frame, no longer does
};

/// Contact events for a whole world: feed it each frame's overlapping pairs
/// from any structure (`begin_frame`, `add` per pair, `end_frame`), then read
/// which pairs began, persisted and ended. Keyed by both handles (index and
/// generation), so a removed object's pairs end even if its slot is reused.
/// Per frame: O(pairs this frame + pairs last frame) expected; no allocation
/// once the tables have grown to the steady-state pair count.
/// Not thread-safe: one frame is fed by one thread.
class PairCache {
 public:
  /// Starts a new frame: the pairs added until `end_frame` form its set.
  void begin_frame();
  /// Adds an overlapping pair of this frame (either order; a duplicate is
  /// ignored). O(1) expected.
  void add(Handle a, Handle b);
  /// Closes the frame: computes the begun, persisting and ended lists.
  void end_frame();
  /// Convenience: one whole frame from a list of pairs.
  void frame(std::span<const HandlePair> pairs);

  /// Pairs of the last completed frame that did not overlap in the one before.
  std::span<const HandlePair> begun() const { return begun_; }
  /// Pairs that overlapped in both of the last two completed frames.
  std::span<const HandlePair> persisting() const { return persisting_; }
  /// Pairs of the frame before the last that no longer overlap.
  std::span<const HandlePair> ended() const { return ended_; }
  /// Pairs of the last completed frame.
  std::size_t size() const { return current_.size(); }
  /// True when the pair overlapped in the last completed frame.
  bool contains(Handle a, Handle b) const;
  /// Bytes held (capacities of both frames' tables and the event lists).
  std::size_t memory_bytes() const;

 private:
  struct Entry {
    Handle a, b;
  };
  static std::uint64_t handle_key(Handle h) {
    return (std::uint64_t(h.generation) << 32) | h.index;
  }
  // A set of pairs of full handles (index and generation, so a reused slot
  // is a different object). Cleared in O(1) by bumping a stamp: a slot is
  // live only when it carries the current stamp.
  class Table {
   public:
    bool insert(Handle a, Handle b);
    bool contains(Handle a, Handle b) const;
    void clear();
    std::size_t size() const { return pairs_.size(); }
    const std::vector<Entry>& pairs() const { return pairs_; }
    std::size_t memory_bytes() const {
      return slots_.capacity() * sizeof(Slot) + pairs_.capacity() * sizeof(Entry);
    }

   private:
    struct Slot {
      std::uint64_t lo = 0, hi = 0;  // the two handle keys, lo < hi
      std::uint32_t used = 0;        // frame stamp; a slot is live when used == stamp_
    };
    std::size_t find_slot(std::uint64_t lo, std::uint64_t hi) const;
    void grow();
    std::vector<Slot> slots_;
    std::vector<Entry> pairs_;
    std::uint32_t stamp_ = 1;
  };

  Table previous_, current_;
  std::vector<HandlePair> begun_, persisting_, ended_;
  bool in_frame_ = false;
};

}  // namespace broadphase
