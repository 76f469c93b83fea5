/// \file pair_cache.hpp
/// `PairCache`, which turns each frame's overlapping pairs, from any
/// structure, into contact events: begun, persisting, ended.
#pragma once

#include <broadphase/handle.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

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
