// The lean tracker's state (PairTracker::Impl) and constants, shared by
// src/arrays/pair_tracker.cpp (the index, the calls, validate) and
// src/arrays/movers.cpp (movers mode). Private to the library.
#pragma once

#include <algorithm>
#include <bit>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/detail/in_order.hpp>
#include <broadphase/detail/sort_keys.hpp>
#include <broadphase/handle.hpp>
#include <cmath>
#include <limits>
#include <thread>
#include <unordered_set>

#include "box_grid.hpp"
#include "calls.hpp"
#include "pairs_by_first.hpp"
#include "sphere_kernel.hpp"

namespace broadphase::arrays {

// The grid, the chunk hand-over and the sphere kernel (src/arrays/).
using namespace detail;  // NOLINT(google-build-using-namespace)

// ---------------------------------------------------------------------------
// PairTracker

// Candidate entries: the partner's index, and in the top bit whether the
// pair overlapped at the last call (valid while neither object changes).
constexpr std::uint32_t kOverlapBit = 0x80000000u;
constexpr std::uint32_t kIndexMask = 0x7FFFFFFFu;
constexpr std::size_t kMaxTracked = kIndexMask;

// A candidate pair of a renewed object, as the places of its two objects
// (their data in the rows' order lie near each other): a < b, b's top bit
// the overlap bit.
struct LoosePair {
  std::uint32_t a, b;
};

// When more than this fraction of the objects leave in one call, a rebuild
// is cheaper than renewing each (a renewal queries the grid on every level,
// several times the work of one object's probe in a build).
constexpr double kRebuildFraction = 0.25;
// The default skin widens once, by this factor, at a call where more than
// one changed object in kSkinGrowShare left its fat box (the motion
// outruns the skin, beyond the waves of renewals of steady movers): the
// index is then built again with the wider skin. Alternated with the
// build before on one core (20 000 objects, 20% movers, 60 calls,
// docs/arrays.md point 24): boxes 6.4-8.3 -> 1.4-1.5 ms a call,
// half-boxes 3.9-4.0 -> 1.0-1.2, box-decades 33-34 -> 7.7-9.1. Widened
// at renewals alone, without the build, the boxes not renewed kept the
// narrow skin: boxes 3.2 ms, box-decades 16. With one in four, city
// widened too (a wave of 29% at its third call) and got slower, 1.2-1.9
// -> 1.5-2.3 ms.
constexpr double kDefaultSkin = 0.25;  // ArrayOptions::skin's default
constexpr double kSkinGrowth = 4;
constexpr std::size_t kSkinGrowShare = 2;
// Afresh only in cells this crowded at most (the largest, over the
// kernel's grids, of the spheres sharing a sphere's cell, itself included,
// on average): all-moving 20 000 gives 1.3, scaled-even 1 024 000 at most
// 4.4; the study's scenes at 6 400, where the index is faster, 8.5 and 15.
constexpr double kAfreshCrowd = 5;
constexpr std::uint32_t kAfreshCalls = 8;
// Compaction folds the loose pairs into the rows once this fraction of the
// objects is renewed, or the loose pairs (8 bytes each) take more than half
// the memory of the rows' partners and the quiet pairs (docs/arrays.md).
constexpr double kCompactFraction = 0.1;
// A renewed object's box reaches ahead by this times its last displacement,
// if that was at most kAheadSkins skins. Renewals over 16 frames at
// scaled-even 1 024 000: 305 543 with no reach, 209 304 with 1, 160 022
// with 2, 160 020 with 3; own memory 88, 89, 81, 82 B/object.
constexpr double kAheadFactor = 2.0;
constexpr double kAheadSkins = 4.0;
// An object's skin is at least this share of the skin relative to its own
// size (the global skin is relative to the median size): objects much larger
// than the median then keep their fat box longer (their renewals query every
// finer level, the costliest).
constexpr double kOwnSkinShare = 0.25;
// A call copies the shapes into the rows' order when at least one object in
// this many changed.
constexpr std::size_t kGatherShare = 8;
// Objects become quiet after this many calls in a row that listed their
// changes (at first; see PairTracker::Impl::quiet_after).
constexpr std::uint32_t kQuietAfter = 2;
// The scan asks for the shapes of the partners this many rows ahead.
constexpr std::size_t kPrefetchRows = 8;
// Movers mode (PairTracker::Impl::movers): taken when the objects listed at
// a partition are at most one in kMoversShare, all objects are spheres and
// the quiet ones are at most this crowded (SphereCells::crowd); left for a
// new partition when one quiet object in kWokenShare has been changed since,
// or when, kMoversPatience calls after it, the movers are more than twice
// the objects listed in a call (many stopped).
constexpr std::size_t kMoversShare = 4;
// As crowded as the sphere kernel takes (SphereCells::kMaxCrowd). At 5,
// crowded sets stayed on the index; measured on one core, 20% movers,
// index -> movers mode (median call): decades 20 000 38.4 -> 2.8 ms,
// clusters 3.6 -> 0.9, coincident 2.4 -> 0.6, outside 3.9 -> 1.1, study
// uneven 6 400 1.41 -> 1.03, scaled-uneven 1 024 000 580 -> 306 ms and
// 257 -> 125 B/object; the others do not change.
constexpr double kMoversCrowd = detail::SphereCells::kMaxCrowd;
// ArrayOptions::spare_bytes by default.
constexpr std::size_t kSpareBytes = std::size_t{16} << 20;
constexpr std::size_t kWokenShare = 8;
// A mover's list of quiet candidates reaches this many calls of its last
// speed past it, at least kListSkinShare of its radius, at most four radii
// plus kListSkinQuiet of the largest quiet radius (see MoverList). A
// renewal (a probe of the quiet grids, 60 tests and most of a microsecond
// at scaled-even 1 024 000) costs a hundred list tests: at 3 calls, 15 000
// to 67 000 movers of 204 800 renewed a call over 40 calls there, the
// median call 88-94 ms; at 12, 5 000-22 000 and 80-83 ms, for 2.3 bytes an
// object more (at 20: 80 ms, 4.6 more). The cap was four radii: a small
// fast mover renewed every call, though among quiet spheres far larger
// than it a longer skin adds few candidates.
constexpr double kListSkinCalls = 12;
constexpr double kListSkinShare = 0.25;
constexpr double kListSkinQuiet = 0.5;
// A new list's centre is put ahead of its mover, along the way it went
// since its last list, by this many times its skin beyond kListSkinShare
// of its radius (at most the skin): a mover in steady motion then lasts
// about twice as many calls on one list of the same reach, and a slow one
// (a skin of kListSkinShare) stays centred. A renewal took about 1.25 us
// at scaled-even 1 024 000. Alternated on one core against centred lists
// (the same pairs): there, 60 calls, median 72.4-73.2 -> 63.9-67.1 ms,
// mean 74.5-76.9 -> 68.0-71.4; study even and uneven 6 400 4-5% faster;
// a random walk the same within 1.2% (docs/arrays.md, point 16). At 1, 2,
// 4 and 8 times, the million's mean 71.7, 70.9, 68.0 ms and 1% over 4's.
constexpr double kListAhead = 4;
constexpr std::size_t kCoarseCellsPerObject = 1;
constexpr double kCoarseCrowd = 8;
constexpr double kCoarseSpread = 2;
constexpr std::uint32_t kMoversPatience = 8;

// (Inline with external linkage: the header is read by two sources.)
inline bool test_bit(const std::vector<std::uint64_t>& bits, std::uint32_t k) {
  return (bits[k >> 6] >> (k & 63)) & 1;
}
inline void set_bit(std::vector<std::uint64_t>& bits, std::uint32_t k) {
  bits[k >> 6] |= std::uint64_t{1} << (k & 63);
}

// The quiet spheres' cells (movers.cpp), over the spheres
// `still` of `o`, or over all of them when `still` is empty (the cells a
// call without an index keeps for the next call's partition): coarse ones
// where they suit (one cell a sphere, where the radii spread over more
// than kCoarseSpread and crowd at most kCoarseCrowd), else as many as the
// one-shot kernel takes. False when the kernel refuses them.
bool build_quiet_cells(detail::SphereCells& cells, const Objects& o,
                       std::span<const std::uint32_t> still);

struct PairTracker::Impl {
  ArrayOptions options;
  // Half of ArrayOptions::spare_bytes: for the quiet pairs as IndexPairs,
  // and for the movers' lists in sets where the quiet pairs are many.
  std::size_t spare_half() const {
    return (options.spare_bytes > 0 ? options.spare_bytes : kSpareBytes) / 2;
  }
  bool built = false;
  std::uint32_t afresh_left = 0;  // calls still to search afresh (see find_pairs)
  bool fresh = false;             // rebuilt and not yet tested: every candidate is tested
  std::size_t count = 0;
  double margin_used = 0;  // the skin as a distance, fixed at the last build
  double rel_skin = 0;     // the skin relative to an object's own size
  double skin_growth = 1;  // kSkinGrowth once the default skin was outrun
  // Per object: its bounds when it was last (re)placed, fattened by the
  // skin. While every object's bounds stay inside its fat box, every
  // overlapping pair is among the candidates (pairs of overlapping fat boxes).
  // Kept in the grid's probe order, object i's at place[i]: a renewal's
  // query reads the boxes of neighbours in space from memory close together
  // (kept by object, they were a cache miss per box the query tested, half
  // of a renewal at scaled-even 1 024 000).
  std::vector<AabbF> fat;
  std::vector<std::uint32_t> place;
  // The grid of the fat boxes at the last build (or compaction), kept to
  // find the partners of renewed objects; slimmed to object indices that
  // read their boxes from `fat` (4 bytes an object instead of 28). Renewed
  // objects sit where their old box put them: a query skips them.
  ArrayGrid grid;
  // Candidates of the last build in rows, one row per object in the grid's
  // probe order (so that a row's neighbours in memory are its neighbours in
  // space): row k belongs to grid.probe_object(k) and holds
  // partner[offset[k] .. offset[k+1]), each the partner's place (its row),
  // so that the partners' data kept in the rows' order is read as a few
  // streams, not by a lookup per entry. Entries with a renewed object are
  // dead.
  std::vector<std::uint32_t> offset;
  std::vector<std::uint32_t> partner;
  std::uint32_t partner_object(std::uint32_t entry) const {
    return grid.probe_object(entry & kIndexMask);
  }
  // Objects renewed since the last build (left their fat box and got a new
  // one): a bit each, and their list. Every candidate pair with a renewed
  // object is in `loose`, once.
  std::vector<std::uint64_t> renewed;
  std::vector<std::uint32_t> renewed_list;
  std::vector<LoosePair> loose;
  // Quiet objects: unchanged when the candidates were last partitioned.
  // A candidate pair of two quiet objects is not kept: when it overlapped,
  // it is in `quiet_hits`, which a call hands over as it stands (grid-verlet
  // does the same with the pairs among its fixed objects). A quiet object
  // the caller changes is woken: renewed, so that its candidates are found
  // again from the grid (its pairs in `quiet_hits` are then dead, as are
  // its rows' entries). At scaled-even 1 024 000, four objects in five never
  // move: their pairs are then copied, not scanned.
  std::vector<std::uint64_t> quiet;
  std::size_t quiet_count = 0;
  detail::PairsByFirst quiet_hits;
  // Hands the quiet pairs over in order, those with a renewed or woken
  // object (`dead`) left out; false when the sink stopped.
  bool deliver_quiet(Emitter& emit, unsigned threads, bool any_dead) const;
  // A call that says everything may have changed wakes every quiet object
  // (which costs a rebuild when they are many), so objects become quiet
  // only after this many calls in a row that listed their changes, four
  // times as many each time such a call woke quiet objects: a caller that
  // mixes the two kinds of call pays a few rebuilds (2, 8, 32, ... listed
  // calls apart), not one every few calls.
  std::uint32_t listed_calls = 0;
  std::uint32_t quiet_after = kQuietAfter;
  bool is_quiet(std::uint32_t i) const { return !quiet.empty() && test_bit(quiet, i); }
  // Makes every object that `changed` does not list quiet, and no other.
  void set_quiet(const std::vector<std::uint64_t>& changed);

  // Movers mode: a set of spheres most of whose objects are quiet keeps no
  // fat boxes, rows or grid. The quiet spheres, as they were when they
  // became quiet, sit in `quiet_cells` (the sphere kernel's grids), their
  // overlapping pairs in `quiet_hits`; the other objects, the movers
  // (`active`, and `woken`: quiet ones the caller has changed since), have
  // their pairs found afresh on every call: among themselves by the
  // one-shot kernel over their gathered shapes, with the quiet ones by a
  // probe of `quiet_cells` each. Nothing depends on how far a mover went,
  // so there is no skin to leave, nothing to renew or compact: the work of
  // a call follows the movers' count. Measured on one core (docs/arrays.md,
  // point 9): 100 000 spheres with 20% moving a tenth of a radius a frame,
  // 100 calls, median 9.2 -> 5.9 ms and mean 14.7 -> 6.0 ms (the renewal
  // waves and compactions gone), own memory 76.6 -> 51.9 B/object;
  // scaled-even 1 024 000, 16 calls, median 206-215 -> 143-160 ms, mean
  // 263-269 -> 154-163, 73.8 -> 54.8 B/object.
  bool movers = false;
  detail::SphereCells quiet_cells;
  std::vector<std::uint32_t> active;  // increasing
  std::vector<std::uint32_t> woken;   // in the order the calls listed them
  std::size_t quiet_at_partition = 0;
  std::uint32_t movers_calls = 0;  // calls since the partition
  // Each mover's list of quiet candidates (slot k: the k-th of `active`,
  // then `woken`; its list is mover_lists[list_of[k]]): the quiet records
  // within `reach` plus their radius of the centre (cx, cy, cz) when it
  // was made. While the mover's distance from that centre plus its radius
  // is at most `reach` (with a margin for rounding), every quiet sphere it
  // overlaps is in the list, so a call tests the list, not the quiet
  // grids; past it, the mover probes them
  // again (a renewal). The centre is the mover's, or ahead of it along the
  // way it went (kListAhead), rounded to float (exact as a double); the
  // reach is its radius plus a skin of kListSkinCalls calls at its speed
  // since its last list, or kListSkinShare of its radius, at most four
  // radii plus kListSkinQuiet of the largest quiet radius, rounded up. 24
  // bytes a mover (and 4 in list_of) and 4 a candidate.
  struct MoverList {
    float cx = 0, cy = 0, cz = 0;
    float reach = -1;  // < 0: no list (a new slot; -2: too long, or no room)
    std::uint32_t first = 0;
    std::uint16_t len = 0;
    std::uint16_t stamp = 0;  // movers_calls (mod 2^16) when it was made
    // Whether a mover at (x, y, z) of radius r is within its reach.
    bool holds(double x, double y, double z, double r, double quiet_rmax) const;
    // The next list of a mover at (x, y, z) of radius r on call `now`.
    MoverList next(double x, double y, double z, double r, std::uint16_t now,
                   double quiet_rmax) const;
  };
  // (In huge pages: at scaled-even 10 240 000, 49 MB of lists and 100 MB
  // of pool read in no order a page could follow; steady calls 920-928 ->
  // 894-901 ms, the million's the same.)
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
  detail::BigVector<MoverList> mover_lists;
  detail::BigVector<std::uint32_t> list_of;    // a permutation of the lists
  detail::BigVector<std::uint32_t> list_pool;  // the lists' quiet records
  std::size_t list_pool_live = 0;              // entries of the current lists
  void free_mover_lists() {
    free_vector(mover_lists);
    free_vector(list_of);
    free_vector(list_pool);
    list_pool_live = 0;
  }
  bool movers_refused = false;  // the quiet spheres did not suit it (since the rebuild)
  std::uint32_t last_box = std::numeric_limits<std::uint32_t>::max();  // a box that kept it out
  // The last call searched afresh with no index, keeping the count and
  // (when its sink took them all) its cells and pairs, so that a call
  // listing its changes may enter movers mode from them.
  bool pending = false;
  // Partitions the objects by `changed` (those it does not list become
  // quiet) into movers mode, dropping the index; false, with nothing
  // changed, when the set does not suit it.
  bool enter_movers(const Objects& o, const std::vector<std::uint64_t>& changed);
  // Enters movers mode from the pairs of a pending call: the objects
  // `changed` lists become movers and their pairs go, the others are quiet
  // and sorted into cells of their own; false, with nothing changed, when
  // the set does not suit it.
  bool enter_from_pending(const Objects& o, const std::vector<std::uint64_t>& changed);
  // Whether the movers mode can take this call (else the index is rebuilt).
  bool movers_suit(const Objects& o, const Changes& changes,
                   const std::vector<std::uint64_t>& changed) const;
  // Whether a new partition is due: many quiet objects woke (counting those
  // `changed` wakes), or, a while after it, many movers stopped.
  bool movers_stale(const std::vector<std::uint64_t>& changed, std::size_t changed_count) const;
  // A call in movers mode; with `check_listed`, it checks the values of the
  // objects `changed` lists first (throwing InvalidObjects, nothing changed).
  ArrayCallStats movers_call(const Objects& o, const std::vector<std::uint64_t>& changed,
                             const PairSink& sink, bool check_listed);
  void check_movers(const Objects& o) const;  // validate() in movers mode

  AabbF& fat_of(std::uint32_t i) { return fat[place[i]]; }
  const AabbF& fat_of(std::uint32_t i) const { return fat[place[i]]; }
  // The skin relative to the objects' size: the caller's, or the default
  // (kDefaultSkin, times skin_growth once it was outrun).
  double skin() const { return options.skin > 0 ? options.skin : skin_growth * kDefaultSkin; }
  double margin(const Objects& o) const;
  void rebuild(const Objects& o);
  // Takes the fat boxes (by object) into `fat` and `place` in the grid's
  // probe order, and slims the grid over them.
  void adopt(const std::vector<AabbF>& by_object);
  // Renews the objects in `leave` (distinct, sorted).
  void renew(const std::vector<std::uint32_t>& leave);
  // Folds the loose pairs into the rows and drops the dead entries; with
  // `changed`, the objects it does not list become quiet (the overlap bits
  // of unchanged pairs must hold).
  void compact(const Objects& o, const std::vector<std::uint64_t>* changed);
  bool wants_compaction() const {
    return static_cast<double>(renewed_list.size()) >
               kCompactFraction * static_cast<double>(count) ||
           loose.size() * 4 > partner.size() + 2 * quiet_hits.size();
  }
  AabbF fat_box(const Shape& s) const {
    const Aabb b = bounds(s);
    const double m = std::max(margin_used, rel_skin * s.max_half());
    return {{round_down(b.lo.x - m), round_down(b.lo.y - m), round_down(b.lo.z - m)},
            {round_up(b.hi.x + m), round_up(b.hi.y + m), round_up(b.hi.z + m)}};
  }
  // The fat box of an object leaving `old`: the skin all round, and ahead
  // of it, kAheadFactor times as far as it went since `old` was made, on
  // the axes it moved along (an object in steady motion then stays inside
  // longer). A jump of more than a few skins gets the plain box.
  AabbF renewed_box(const Shape& s, const AabbF& old) const {
    AabbF f = fat_box(s);
    const Aabb b = bounds(s);
    double d[3];
    const double c[3] = {b.lo.x + b.hi.x, b.lo.y + b.hi.y, b.lo.z + b.hi.z};
    for (int a = 0; a < 3; ++a) {
      d[a] = 0.5 * (c[a] - (static_cast<double>(old.lo[a]) + static_cast<double>(old.hi[a])));
      if (!(std::abs(d[a]) <= kAheadSkins * margin_used)) return f;
    }
    for (int a = 0; a < 3; ++a) {
      if (d[a] < 0) f.lo[a] = round_down(static_cast<double>(f.lo[a]) + kAheadFactor * d[a]);
      if (d[a] > 0) f.hi[a] = round_up(static_cast<double>(f.hi[a]) + kAheadFactor * d[a]);
    }
    return f;
  }
  bool is_renewed(std::uint32_t k) const { return test_bit(renewed, k); }
  bool contained(const Objects& o, std::uint32_t i) const {
    const AabbF b = bounds_f(read_shape(o, i));
    const AabbF& f = fat_of(i);
    return f.lo[0] <= b.lo[0] && f.lo[1] <= b.lo[1] && f.lo[2] <= b.lo[2] && b.hi[0] <= f.hi[0] &&
           b.hi[1] <= f.hi[1] && b.hi[2] <= f.hi[2];
  }
};

}  // namespace broadphase::arrays
