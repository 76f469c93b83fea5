// The tracker's movers mode (PairTracker in movers mode): the quiet spheres
// in the sphere kernel's grids, each mover's list of quiet candidates, and
// the movers' pairs found afresh on every call. Private to the library; its
// functions are in movers.cpp.
#pragma once

#include <broadphase/arrays/arrays.hpp>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "big_vector.hpp"
#include "calls.hpp"
#include "quiet_set.hpp"
#include "sphere_kernel.hpp"
#include "tracker_tuning.hpp"

namespace broadphase::arrays::detail {

// The quiet spheres' cells, over the spheres `still` of `o`, or over all
// of them when `still` is empty (the cells a call without an index keeps
// for the next call's partition): coarse ones where they suit (one cell a
// sphere, where the radii spread over more than kCoarseSpread and crowd at
// most kCoarseCrowd), else as many as the one-shot kernel takes. False
// when the kernel refuses them.
bool build_quiet_cells(SphereCells& cells, const Objects& o, std::span<const std::uint32_t> still);

// A mover's list of quiet candidates: the quiet records within `reach`
// plus their radius of the centre (cx, cy, cz) when it was made. While the
// mover's distance from that centre plus its radius is at most `reach`
// (with a margin for rounding), every quiet sphere it overlaps is in the
// list, so a call tests the list, not the quiet grids; past it, the mover
// probes them again (a renewal). The centre is the mover's, or ahead of it
// along the way it went (kListAhead), rounded to float (exact as a
// double); the reach is its radius plus a skin of kListSkinCalls calls at
// its speed since its last list, or kListSkinShare of its radius, at most
// four radii plus kListSkinQuiet of the largest quiet radius, rounded up.
// 24 bytes a mover (and 4 in Movers::list_of) and 4 a candidate.
struct MoverList {
  float cx = 0, cy = 0, cz = 0;
  float reach = -1;  // < 0: no list (a new slot; -2: too long, or no room)
  std::uint32_t first = 0;
  std::uint16_t len = 0;
  std::uint16_t stamp = 0;  // Movers::calls (mod 2^16) when it was made
  // Whether a mover at (x, y, z) of radius r is within its reach.
  bool holds(double x, double y, double z, double r, double quiet_rmax) const;
  // The next list of a mover at (x, y, z) of radius r on call `now`.
  MoverList next(double x, double y, double z, double r, std::uint16_t now,
                 double quiet_rmax) const;
};

// Movers mode: a set of spheres most of whose objects are quiet keeps no
// fat boxes, rows or grid. The quiet spheres, as they were when they
// became quiet, sit in `quiet_cells` (the sphere kernel's grids), their
// overlapping pairs in the QuietSet; the other objects, the movers
// (`active`, and `woken`: quiet ones the caller has changed since), have
// their pairs found afresh on every call: among themselves by the
// one-shot kernel over their gathered shapes, with the quiet ones from
// each mover's list of quiet candidates. Nothing depends on how far a
// mover went, so there is no skin to leave, nothing to renew or compact:
// the work of a call follows the movers' count. Measured on one core
// (docs/arrays.md): 100 000 spheres with 20% moving a tenth of a radius a
// frame, 100 calls, median 9.2 -> 5.9 ms and mean 14.7 -> 6.0 ms (the
// renewal waves and compactions gone), own memory 76.6 -> 51.9 B/object;
// scaled-even 1 024 000, 16 calls, median 206-215 -> 143-160 ms, mean
// 263-269 -> 154-163, 73.8 -> 54.8 B/object.
struct Movers {
  SphereCells quiet_cells;
  std::vector<std::uint32_t> active;  // increasing
  std::vector<std::uint32_t> woken;   // in the order the calls listed them
  std::size_t quiet_at_partition = 0;
  std::uint32_t calls = 0;  // calls since the partition
  // Each mover's list (slot k: the k-th of `active`, then `woken`; its list
  // is mover_lists[list_of[k]]), in huge pages: at scaled-even 10 240 000,
  // 49 MB of lists and 100 MB of pool read in no order a page could follow;
  // steady calls 920-928 -> 894-901 ms, the million's the same.
  //
  // The lists lie in the order in which the last call went through the
  // movers (the quiet cells' order, which a mover rarely leaves), so that a
  // call reads them, and the pool after a compaction, nearly in sequence;
  // `list_of[k]` is the list of slot k (4 bytes a mover more). In slot
  // order (the caller's indices), perf put a quarter of the movers' loop
  // at scaled-even 1 024 000 on the misses of the headers and entries.
  // Alternated on one core: there 40 calls, median 59.7-62.0 -> 52.0-52.6
  // ms; 10 240 000, 12 calls, 834 -> 702 ms; study even 6 400, where they
  // fit in the caches, 0.213-0.214 -> 0.215-0.216 ms (the pass that lays
  // them out).
  BigVector<MoverList> mover_lists;
  BigVector<std::uint32_t> list_of;    // a permutation of the lists
  BigVector<std::uint32_t> list_pool;  // the lists' quiet records
  std::size_t list_pool_live = 0;      // entries of the current lists

  void free_lists() {
    free_vector(mover_lists);
    free_vector(list_of);
    free_vector(list_pool);
    list_pool_live = 0;
  }
  // Whether a new partition is due: many quiet objects woke (counting those
  // `changed` wakes), or, a while after it, many movers stopped.
  bool stale(const QuietSet& quiet, const std::vector<std::uint64_t>& changed,
             std::size_t changed_count) const;
  // A call: the quiet pairs, the movers' pairs among themselves and with
  // the quiet ones; the quiet objects `changed` lists wake. With
  // `check_listed`, it checks the values of the objects `changed` lists
  // first (throwing InvalidObjects, nothing changed).
  ArrayCallStats call(const Objects& o, const std::vector<std::uint64_t>& changed,
                      const PairSink& sink, bool check_listed, QuietSet& quiet,
                      const ArrayOptions& options);
  std::size_t memory_bytes() const;
  // Movers mode's invariants against `o` (a part of PairTracker::validate);
  // throws std::logic_error.
  void check(const Objects& o, const QuietSet& quiet) const;
};

}  // namespace broadphase::arrays::detail
