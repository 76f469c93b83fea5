// The tracker's index (PairTracker in its index mode): a multi-level hashed
// grid over skin-fattened float boxes kept between calls, candidate rows
// per object, and the renewal of objects that leave their box. Private to
// the library; its functions are in tracker_index.cpp.
#pragma once

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <cmath>
#include <cstdint>
#include <vector>

#include "box_grid.hpp"
#include "calls.hpp"
#include "quiet_set.hpp"
#include "tracker_tuning.hpp"

namespace broadphase::arrays::detail {

// A candidate pair of a renewed object, as the places of its two objects
// (their data in the rows' order lie near each other): a < b, b's top bit
// the overlap bit.
struct LoosePair {
  std::uint32_t a, b;
};

struct TrackerIndex {
  double margin_used = 0;  // the skin as a distance, fixed at the last build
  double rel_skin = 0;     // the skin relative to an object's own size
  // Built and not yet tested (or a scan did not finish): every candidate
  // is tested, its overlap bit not trusted.
  bool fresh = false;
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
  // Objects renewed since the last build (left their fat box and got a new
  // one): a bit each, and their list. Every candidate pair with a renewed
  // object is in `loose`, once.
  std::vector<std::uint64_t> renewed;
  std::vector<std::uint32_t> renewed_list;
  std::vector<LoosePair> loose;

  std::size_t count() const { return place.size(); }
  std::uint32_t partner_object(std::uint32_t entry) const {
    return grid.probe_object(entry & kIndexMask);
  }
  AabbF& fat_of(std::uint32_t i) { return fat[place[i]]; }
  const AabbF& fat_of(std::uint32_t i) const { return fat[place[i]]; }
  bool is_renewed(std::uint32_t k) const { return test_bit(renewed, k); }

  // The skin as a distance: `skin` times the median largest half-extent
  // (of a sample), so it scales with the objects.
  static double margin(const Objects& o, double skin);
  // Builds the index of `o` afresh with relative skin `skin`: fat boxes,
  // grid, every candidate row (on `threads` threads); nothing renewed, and
  // every candidate to be tested (`fresh`).
  void build(const Objects& o, double skin, unsigned threads);
  // The objects a call renews: those of `o` that left their fat box (which
  // then takes them again with renewed_box), and the quiet ones the caller
  // changed (woken), among all of them or those `changed` lists.
  struct Leavers {
    std::vector<std::uint32_t> renew;  // distinct, sorted
    std::size_t left = 0;              // how many of them left their box
    std::size_t quiet_changed = 0;     // how many changed objects were quiet
  };
  Leavers leavers(const Objects& o, bool all, const std::vector<std::uint64_t>& changed,
                  std::size_t changed_count, const QuietSet& quiet);
  // Renews the objects in `leave` (distinct, sorted); a quiet one wakes.
  void renew(const std::vector<std::uint32_t>& leave, QuietSet& quiet);
  // Folds the loose pairs into the rows and drops the dead entries; with
  // `changed`, the objects it does not list become quiet (the overlap bits
  // of unchanged pairs must hold), their pairs moving to `quiet`.
  void compact(const Objects& o, const std::vector<std::uint64_t>* changed, QuietSet& quiet,
               std::size_t spare);
  // Hands over every overlapping pair of `o`: the rows, the loose pairs,
  // then the quiet pairs, testing the candidates with a changed object
  // (every one when `all`, or while `fresh`) and keeping each one's overlap
  // bit; the other candidates keep the answer of their bit.
  void scan(const Objects& o, bool all, const std::vector<std::uint64_t>& changed,
            std::size_t changed_count, const QuietSet& quiet, const ArrayOptions& options,
            const PairSink& sink, ArrayCallStats& stats);
  bool wants_compaction(const QuietSet& quiet) const {
    return static_cast<double>(renewed_list.size()) >
               kCompactFraction * static_cast<double>(count()) ||
           loose.size() * 4 > partner.size() + 2 * quiet.hits.size();
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
  bool contained(const Objects& o, std::uint32_t i) const {
    const AabbF b = bounds_f(read_shape(o, i));
    const AabbF& f = fat_of(i);
    return f.lo[0] <= b.lo[0] && f.lo[1] <= b.lo[1] && f.lo[2] <= b.lo[2] && b.hi[0] <= f.hi[0] &&
           b.hi[1] <= f.hi[1] && b.hi[2] <= f.hi[2];
  }
  std::size_t memory_bytes() const;
  // The index's invariants against `o` with the quiet set `quiet` (a part
  // of PairTracker::validate); throws std::logic_error.
  void check(const Objects& o, const QuietSet& quiet) const;

 private:
  // Takes the fat boxes (by object) into `fat` and `place` in the grid's
  // probe order, and slims the grid over them.
  void adopt(const std::vector<AabbF>& by_object);
};

}  // namespace broadphase::arrays::detail
