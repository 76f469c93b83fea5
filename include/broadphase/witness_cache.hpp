/// \file witness_cache.hpp
/// `WitnessCache`: answers "is this object touching anything?" by first
/// retesting the object that answered yes last time (its witness). Under
/// coherent motion a contact usually persists for many frames, so most
/// questions cost one exact test instead of a query.
#pragma once

#include <broadphase/structure.hpp>
#include <cstdint>
#include <vector>

namespace broadphase {

/// Per-object witnesses for yes/no contact queries against any structure
/// (a concrete one or AnyBroadPhase). Keyed by the handle's slot index; a
/// witness whose handle went stale, or the object itself being replaced in
/// its slot, is detected and simply misses. "Touching" follows the
/// structure's collision filters: an object overlapping only objects it may
/// not pair with (Filter, PairFilter) touches nothing, and a witness whose
/// filters changed is tested again before it answers.
///
/// touching(): O(1) on a hit, one early-out query on a miss. Memory: one
/// entry per slot index seen. Not thread-safe (it updates its witnesses).
class WitnessCache {
 public:
  /// True when the object `h` of `s` overlaps at least one other object.
  /// Throws InvalidHandle when `h` is not in `s`.
  template <class S>
  bool touching(const S& s, Handle h) {
    const Shape me = s.shape(h);
    if (h.index >= entries_.size()) entries_.resize(h.index + 1);
    Entry& e = entries_[h.index];
    if (e.self == h && !e.witness.is_null() && s.contains(e.witness) && may_pair(s, h, e.witness)) {
      ++tests_;
      if (overlaps(me, s.shape(e.witness))) {
        ++hits_;
        return true;
      }
    }
    ++misses_;
    Handle found;
    const QueryCost c = s.query(me, [&](Handle o) {
      if (o == h || !may_pair(s, h, o)) return true;
      found = o;
      return false;
    });
    tests_ += c.tests;
    e = {h, found};
    return !found.is_null();
  }

  /// Questions answered by the witness alone.
  std::uint64_t hits() const { return hits_; }
  /// Questions that needed a query (no witness, or it no longer touched).
  std::uint64_t misses() const { return misses_; }
  /// Exact predicate evaluations, witnesses and queries together.
  std::uint64_t tests() const { return tests_; }
  /// hits / (hits + misses), 0 before the first question.
  double hit_rate() const {
    const std::uint64_t n = hits_ + misses_;
    return n == 0 ? 0.0 : static_cast<double>(hits_) / static_cast<double>(n);
  }
  /// Forgets every witness and counter.
  void clear() {
    entries_.clear();
    hits_ = misses_ = tests_ = 0;
  }
  std::size_t memory_bytes() const { return entries_.capacity() * sizeof(Entry); }

 private:
  // The structure's filter rule (a structure without filters pairs all).
  template <class S>
  static bool may_pair(const S& s, Handle a, Handle b) {
    if constexpr (requires { s.pair_passes(a, b); }) {
      return s.pair_passes(a, b);
    } else {
      return true;
    }
  }
  struct Entry {
    Handle self;     // the object the witness belongs to
    Handle witness;  // null: it touched nothing last time
  };
  std::vector<Entry> entries_;
  std::uint64_t hits_ = 0, misses_ = 0, tests_ = 0;
};

}  // namespace broadphase
