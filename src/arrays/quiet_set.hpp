// The tracker's quiet objects (PairTracker, quiet_set.hpp): those unchanged
// when the candidates were last partitioned, and the pairs among them.
// Private to the library.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "calls.hpp"
#include "pairs_by_first.hpp"
#include "tracker_tuning.hpp"

namespace broadphase::arrays::detail {

// Quiet objects: unchanged when the candidates were last partitioned.
// A candidate pair of two quiet objects is not kept: when it overlapped,
// it is in `hits`, which a call hands over as it stands (grid-verlet does
// the same with the pairs among its fixed objects). A quiet object the
// caller changes is woken: renewed, so that its candidates are found
// again (its pairs in `hits` are then dead). At scaled-even 1 024 000,
// four objects in five never move: their pairs are then copied, not
// scanned. The index and movers mode both keep their quiet objects here.
struct QuietSet {
  std::vector<std::uint64_t> bits;  // one an object, or none while no object is quiet
  std::size_t count = 0;
  PairsByFirst hits;
  // A call that says everything may have changed wakes every quiet object
  // (which costs a rebuild when they are many), so objects become quiet
  // only after `after` calls in a row that listed their changes, four
  // times as many each time such a call woke quiet objects: a caller that
  // mixes the two kinds of call pays a few rebuilds (2, 8, 32, ... listed
  // calls apart), not one every few calls.
  std::uint32_t listed_calls = 0;
  std::uint32_t after = kQuietAfter;

  bool has(std::uint32_t i) const { return !bits.empty() && test_bit(bits, i); }
  // Makes every one of the `n` objects that `changed` does not list quiet,
  // and no other.
  void set(const std::vector<std::uint64_t>& changed, std::size_t n) {
    bits.resize(changed.size());
    for (std::size_t w = 0; w < changed.size(); ++w) bits[w] = ~changed[w];
    if (n % 64 != 0) bits.back() &= (std::uint64_t{1} << (n % 64)) - 1;
    count = 0;
    for (std::uint64_t w : bits) count += static_cast<std::size_t>(std::popcount(w));
  }
  // Object i, quiet, is quiet no more.
  void wake(std::uint32_t i) {
    bits[i >> 6] &= ~(std::uint64_t{1} << (i & 63));
    --count;
  }
  // No object quiet, no quiet pair.
  void clear() {
    bits.clear();
    bits.shrink_to_fit();
    count = 0;
    hits.clear();
  }
  // Hands the quiet pairs over in order, those with an object no longer
  // quiet left out when `any_dead`; false when the sink stopped.
  bool deliver(Emitter& emit, unsigned threads, bool any_dead) const {
    if (!any_dead && hits.plain()) return emit.deliver_slices(hits.pairs());
    return run_in_order<PairChunk>(
        hits.size(), threads,
        [&](std::size_t begin, std::size_t end, PairChunk& out) {
          out.pairs.clear();
          out.tests = 0;
          if (any_dead)
            hits.expand(begin, end, out.pairs,
                        [&](const IndexPair& q) { return has(q.i) && has(q.j); });
          else
            hits.expand(begin, end, out.pairs, [](const IndexPair&) { return true; });
        },
        [&](PairChunk& c) { return emit.deliver(c); });
  }
  std::size_t memory_bytes() const {
    return bits.capacity() * sizeof(std::uint64_t) + hits.memory_bytes();
  }
};

}  // namespace broadphase::arrays::detail
