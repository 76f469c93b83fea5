// The lean path's tracker (arrays.hpp, PairTracker): a multi-level hashed
// grid over skin-fattened float boxes kept between calls, candidate rows
// per object, renewals of objects that leave their box, quiet objects, and
// calls afresh when motion outruns the skin; for sets of spheres that are
// mostly quiet, movers mode instead (no index of the movers at all); exact
// tests read from the caller's data.
#include <algorithm>
#include <bit>
#include <broadphase/arrays.hpp>
#include <broadphase/handle.hpp>
#include <cmath>
#include <limits>
#include <thread>
#include <unordered_set>

#include "detail/array_calls.hpp"
#include "detail/array_grid.hpp"
#include "detail/in_order.hpp"
#include "detail/sort_keys.hpp"
#include "detail/sphere_cells.hpp"

namespace broadphase {

// The grid, the chunk hand-over and the sphere kernel (src/detail/).
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
constexpr double kMoversCrowd = 5;
constexpr std::size_t kWokenShare = 8;
constexpr std::uint32_t kMoversPatience = 8;

namespace {

inline bool test_bit(const std::vector<std::uint64_t>& bits, std::uint32_t k) {
  return (bits[k >> 6] >> (k & 63)) & 1;
}
inline void set_bit(std::vector<std::uint64_t>& bits, std::uint32_t k) {
  bits[k >> 6] |= std::uint64_t{1} << (k & 63);
}

}  // namespace

struct PairTracker::Impl {
  ArrayOptions options;
  bool built = false;
  std::uint32_t afresh_left = 0;  // calls still to search afresh (see find_pairs)
  bool fresh = false;             // rebuilt and not yet tested: every candidate is tested
  std::size_t count = 0;
  double margin_used = 0;  // the skin as a distance, fixed at the last build
  double rel_skin = 0;     // the skin relative to an object's own size
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
  std::vector<IndexPair> quiet_hits;
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
  bool movers_refused = false;     // the quiet spheres did not suit it (since the rebuild)
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
  ArrayCallStats movers_call(const Objects& o, const std::vector<std::uint64_t>& changed,
                             const PairSink& sink);
  void check_movers(const Objects& o) const;  // validate() in movers mode

  AabbF& fat_of(std::uint32_t i) { return fat[place[i]]; }
  const AabbF& fat_of(std::uint32_t i) const { return fat[place[i]]; }
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

// The skin as a distance: `options.skin` times the median largest
// half-extent (of a sample), so it scales with the objects.
double PairTracker::Impl::margin(const Objects& o) const {
  const double rel = options.skin > 0 ? options.skin : 0.25;
  std::vector<double> sample;
  const std::size_t step = std::max<std::size_t>(1, o.count / 1024);
  for (std::size_t i = 0; i < o.count; i += step) sample.push_back(o.shape(i).max_half());
  if (sample.empty()) return 0;
  std::nth_element(sample.begin(), sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2),
                   sample.end());
  const double m = rel * sample[sample.size() / 2];
  return std::isfinite(m) ? m : 0;
}

void PairTracker::Impl::rebuild(const Objects& o) {
  const std::size_t n = o.count;
  movers = false;
  movers_refused = false;
  pending = false;
  quiet_cells = detail::SphereCells{};
  active = {};
  woken = {};
  margin_used = margin(o);
  rel_skin = kOwnSkinShare * (options.skin > 0 ? options.skin : 0.25);
  std::vector<AabbF> boxes(n);
  for (std::size_t i = 0; i < n; ++i) boxes[i] = fat_box(o.shape(i));
  grid = ArrayGrid{};
  grid.build(boxes);
  struct Lists {
    std::vector<std::uint32_t> counts;
    std::vector<std::uint32_t> partners;
  };
  const std::size_t rows = grid.probe_count();
  offset.assign(rows + 1, 0);
  partner.clear();
  std::size_t filled = 0;
  run_in_order<Lists>(
      rows, thread_count(options.threads),
      [&](std::size_t begin, std::size_t end, Lists& out) {
        out.counts.clear();
        out.partners.clear();
        for (std::size_t k = begin; k < end; ++k) {
          const std::size_t before = out.partners.size();
          // A big object's partners have no place yet: their indices
          // until `adopt` gives them one below.
          grid.probe(k, [&](std::uint32_t j, std::uint32_t at) {
            out.partners.push_back(at == ArrayGrid::kNoPlace ? j : at);
          });
          out.counts.push_back(static_cast<std::uint32_t>(out.partners.size() - before));
        }
      },
      [&](Lists& l) {
        for (std::uint32_t c : l.counts) {
          offset[filled + 1] = offset[filled] + c;
          ++filled;
        }
        partner.insert(partner.end(), l.partners.begin(), l.partners.end());
        return true;
      });
  partner.shrink_to_fit();
  adopt(boxes);
  for (std::size_t k = rows - grid.big().size(); k < rows; ++k)
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p) partner[p] = place[partner[p]];
  renewed.assign((n + 63) / 64, 0);
  renewed.shrink_to_fit();
  renewed_list.clear();
  renewed_list.shrink_to_fit();
  loose.clear();
  loose.shrink_to_fit();
  quiet.clear();
  quiet.shrink_to_fit();
  quiet_count = 0;
  quiet_hits.clear();
  quiet_hits.shrink_to_fit();
  count = n;
  built = true;
  fresh = true;
}

void PairTracker::Impl::set_quiet(const std::vector<std::uint64_t>& changed) {
  quiet.resize(changed.size());
  for (std::size_t w = 0; w < changed.size(); ++w) quiet[w] = ~changed[w];
  if (count % 64 != 0) quiet.back() &= (std::uint64_t{1} << (count % 64)) - 1;
  quiet_count = 0;
  for (std::uint64_t w : quiet) quiet_count += static_cast<std::size_t>(std::popcount(w));
}

void PairTracker::Impl::adopt(const std::vector<AabbF>& by_object) {
  const std::size_t n = by_object.size();
  fat.resize(n);
  fat.shrink_to_fit();
  place.resize(n);
  place.shrink_to_fit();
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t i = grid.probe_object(k);
    place[i] = static_cast<std::uint32_t>(k);
    fat[k] = by_object[i];
  }
  grid.slim(fat);
}

void PairTracker::Impl::renew(const std::vector<std::uint32_t>& leave) {
  // Which objects are renewed now: their old candidates go.
  std::vector<std::uint64_t> now((count + 63) / 64, 0), now_at(now.size(), 0);
  for (std::uint32_t i : leave) {
    set_bit(now, i);
    set_bit(now_at, place[i]);
  }
  std::erase_if(loose, [&](const LoosePair& p) {
    return test_bit(now_at, p.a) || test_bit(now_at, p.b & kIndexMask);
  });
  for (std::uint32_t i : leave) {
    if (!is_renewed(i)) renewed_list.push_back(i);
    set_bit(renewed, i);
    if (is_quiet(i)) {
      quiet[i >> 6] &= ~(std::uint64_t{1} << (i & 63));
      --quiet_count;
    }
  }
  auto add_at = [&](std::uint32_t ki, std::uint32_t kj) {  // two places
    const IndexPair q = ordered(ki, kj);
    loose.push_back({q.i, q.j});
  };
  auto add = [&](std::uint32_t i, std::uint32_t j) { add_at(place[i], place[j]); };
  // Partners that were not renewed: the kept grid holds their fat boxes.
  // Queried in the probe order, one query reads much of the memory the
  // last one read.
  std::vector<std::uint32_t> by_place(leave);
  std::sort(by_place.begin(), by_place.end(),
            [&](std::uint32_t p, std::uint32_t q) { return place[p] < place[q]; });
  for (std::uint32_t i : by_place)
    grid.query(fat_of(i), [&](std::uint32_t j, std::uint32_t at) {
      if (j != i && !is_renewed(j)) add_at(place[i], at);
    });
  // Partners among the renewed ones (this call's included, each pair once:
  // a pair of two objects renewed now is added by the lower index).
  auto wanted = [&](std::uint32_t i, std::uint32_t j) {
    return j != i && (!test_bit(now, j) || j > i);
  };
  if (renewed_list.size() <= 64) {
    for (std::uint32_t i : leave)
      for (std::uint32_t j : renewed_list)
        if (wanted(i, j) && fat_of(i).overlaps(fat_of(j))) add(i, j);
    return;
  }
  std::vector<AabbF> boxes(renewed_list.size());
  for (std::size_t k = 0; k < boxes.size(); ++k) boxes[k] = fat_of(renewed_list[k]);
  ArrayGrid loose_grid;
  loose_grid.build(boxes);
  for (std::uint32_t i : leave)
    loose_grid.query(fat_of(i), [&](std::uint32_t k) {
      const std::uint32_t j = renewed_list[k];
      if (wanted(i, j)) add(i, j);
    });
}

// A new grid over the current fat boxes and rows in its order, holding the
// same candidates with the same bits: the rows' live entries, then the loose
// pairs of the row's object (as the lower index). No probe, so it costs a
// grid build and two passes over the candidates, against a probe of every
// object for a rebuild.
void PairTracker::Impl::compact(const Objects& o, const std::vector<std::uint64_t>* changed) {
  const std::size_t rows = grid.probe_count();
  std::erase_if(quiet_hits, [&](const IndexPair& q) { return is_renewed(q.i) || is_renewed(q.j); });
  std::vector<AabbF> by_object(count);
  for (std::size_t k = 0; k < rows; ++k) by_object[grid.probe_object(k)] = fat[k];
  // With `changed`, the objects it does not list become quiet. A quiet
  // object's box shrinks to its bounds: it never leaves the box unnoticed
  // (the caller lists it when it changes, and it is then renewed), so a
  // skin around it only adds candidates with the movers. The pairs of two
  // quiet objects leave the rows (see `quiet`), and those of a quiet and
  // an active object whose boxes no longer meet are dropped.
  if (changed != nullptr) {
    set_quiet(*changed);
    for (std::size_t w = 0; w < quiet.size(); ++w)
      for (std::uint64_t b = quiet[w]; b != 0; b &= b - 1) {
        const auto i =
            static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b)));
        by_object[i] = bounds_f(read_shape(o, i));
      }
  }
  // The passes below read every candidate's state and box by its place
  // (near its row's, as the partners are neighbours in space), not by its
  // object: by object, each was a cache miss (20 s of a compaction at
  // 10 240 000 objects).
  enum : std::uint8_t { kRenewedAt = 1, kQuietAt = 2 };
  std::vector<std::uint8_t> state(rows);
  std::vector<AabbF> box_at(changed != nullptr ? rows : 0);
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t i = grid.probe_object(k);
    state[k] = static_cast<std::uint8_t>((is_renewed(i) ? kRenewedAt : 0) |
                                         (changed != nullptr && test_bit(quiet, i) ? kQuietAt : 0));
    if (changed != nullptr) box_at[k] = by_object[i];
  }
  enum class Fate { row, quiet, drop };
  auto fate = [&](std::uint32_t ka, std::uint32_t kb) {  // two places
    if (changed == nullptr) return Fate::row;
    const bool qa = (state[ka] & kQuietAt) != 0, qb = (state[kb] & kQuietAt) != 0;
    if (qa && qb) return Fate::quiet;
    if ((qa || qb) && !box_at[ka].overlaps(box_at[kb])) return Fate::drop;
    return Fate::row;
  };
  // Candidates kept per place, then where they go.
  std::vector<std::uint32_t> cursor(rows, 0);
  for (std::size_t k = 0; k < rows; ++k) {
    if (state[k] & kRenewedAt) continue;
    std::uint32_t c = 0;
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p) {
      const std::uint32_t q = partner[p] & kIndexMask;
      c += !(state[q] & kRenewedAt) && fate(static_cast<std::uint32_t>(k), q) == Fate::row ? 1 : 0;
    }
    cursor[k] = c;
  }
  for (const LoosePair& lp : loose)
    cursor[lp.a] += fate(lp.a, lp.b & kIndexMask) == Fate::row ? 1 : 0;
  // The finest cells stay as wide as the last grid's: the quiet objects'
  // bounds are smaller than their fat boxes, and finer levels would make a
  // renewed object's query read many more rows of cells (2.2x slower frames
  // with renewals at scaled-even 1 024 000).
  ArrayGrid next;
  next.build(by_object, 1, grid.base_cell());
  std::vector<std::uint32_t> next_offset(rows + 1, 0);
  std::vector<std::uint32_t> moved(rows);  // an object's new place, by its old one
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t old = place[next.probe_object(k)];
    moved[old] = static_cast<std::uint32_t>(k);
    next_offset[k + 1] = next_offset[k] + cursor[old];
  }
  for (std::size_t k = 0; k < rows; ++k) cursor[k] = next_offset[moved[k]];
  std::vector<std::uint32_t> next_partner(next_offset[rows]);
  auto take = [&](std::uint32_t ka, std::uint32_t kb, std::uint32_t bit) {
    switch (fate(ka, kb)) {
      case Fate::row:
        next_partner[cursor[ka]++] = moved[kb] | bit;
        break;
      case Fate::quiet:
        if (bit != 0) quiet_hits.push_back(ordered(grid.probe_object(ka), grid.probe_object(kb)));
        break;
      case Fate::drop:
        break;
    }
  };
  for (std::size_t k = 0; k < rows; ++k) {
    if (state[k] & kRenewedAt) continue;
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p)
      if (const std::uint32_t q = partner[p] & kIndexMask; !(state[q] & kRenewedAt))
        take(static_cast<std::uint32_t>(k), q, partner[p] & kOverlapBit);
  }
  for (const LoosePair& lp : loose) take(lp.a, lp.b & kIndexMask, lp.b & kOverlapBit);
  quiet_hits.shrink_to_fit();
  grid = std::move(next);
  adopt(by_object);
  offset = std::move(next_offset);
  partner = std::move(next_partner);
  std::fill(renewed.begin(), renewed.end(), 0);
  renewed_list.clear();
  renewed_list.shrink_to_fit();
  loose.clear();
  loose.shrink_to_fit();
}

bool PairTracker::Impl::enter_movers(const Objects& o, const std::vector<std::uint64_t>& changed) {
  // The cheap refusals first: the index tries this on every call while it
  // has quiet objects.
  const auto n = static_cast<std::uint32_t>(o.count);
  if (o.radius.empty()) return false;
  std::size_t listed = 0;
  for (const std::uint64_t w : changed) listed += static_cast<std::size_t>(std::popcount(w));
  if (listed * kMoversShare > n) return false;
  if (o.kind != nullptr) {
    if (last_box < n && !o.is_sphere(last_box)) return false;  // still a box
    for (std::uint32_t i = 0; i < n; ++i)
      if (!o.is_sphere(i)) {
        last_box = i;
        return false;
      }
  }
  std::vector<std::uint32_t> still, moving;
  for (std::uint32_t i = 0; i < n; ++i) (test_bit(changed, i) ? moving : still).push_back(i);
  detail::SphereCells cells;
  if (!cells.build(o, still) || cells.crowd() > kMoversCrowd) {
    movers_refused = true;  // not tried again before a rebuild: a build is dear
    return false;
  }
  std::vector<IndexPair> hits;
  ArrayOptions unsorted = options;
  unsorted.sorted = false;
  cell_pairs(cells, append_to(hits), unsorted);
  hits.shrink_to_fit();
  Impl next;
  next.options = options;
  next.quiet_after = quiet_after;
  next.listed_calls = listed_calls;
  next.count = n;
  next.built = true;
  next.movers = true;
  next.quiet_cells = std::move(cells);
  next.quiet_hits = std::move(hits);
  next.active = std::move(moving);
  next.set_quiet(changed);
  next.quiet_at_partition = next.quiet_count;
  *this = std::move(next);
  return true;
}

bool PairTracker::Impl::enter_from_pending(const Objects& o,
                                           const std::vector<std::uint64_t>& changed) {
  const auto n = static_cast<std::uint32_t>(o.count);
  if (o.radius.empty()) return false;
  std::vector<std::uint32_t> moving;
  for (std::size_t w = 0; w < changed.size(); ++w)
    for (std::uint64_t b = changed[w]; b != 0; b &= b - 1)
      moving.push_back(
          static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b))));
  if (moving.size() * kMoversShare > n) return false;
  if (o.kind != nullptr)  // the others are the spheres the cells took
    for (std::uint32_t i : moving)
      if (!o.is_sphere(i)) return false;
  // The cells again, over the quiet objects alone: keeping the movers'
  // stale records took the own memory at scaled-even 1 024 000 from 54.8
  // to 70.3 B/object for as long as no new partition came.
  std::vector<std::uint32_t> still;
  still.reserve(n - moving.size());
  for (std::uint32_t i = 0; i < n; ++i)
    if (!test_bit(changed, i)) still.push_back(i);
  detail::SphereCells cells;
  if (!cells.build(o, still) || cells.crowd() > kMoversCrowd) return false;
  quiet_cells = std::move(cells);
  std::erase_if(quiet_hits, [&](const IndexPair& p) {
    return test_bit(changed, p.i) || test_bit(changed, p.j);
  });
  quiet_hits.shrink_to_fit();
  set_quiet(changed);
  active = std::move(moving);
  woken.clear();
  quiet_at_partition = quiet_count;
  movers_calls = 0;
  movers = true;
  built = true;
  pending = false;
  return true;
}

bool PairTracker::Impl::movers_suit(const Objects& o, const Changes& changes,
                                    const std::vector<std::uint64_t>& changed) const {
  if (changes.all || o.count != count || o.radius.empty()) return false;
  if (o.kind != nullptr)  // only a listed object can have changed its kind
    for (std::size_t w = 0; w < changed.size(); ++w)
      for (std::uint64_t b = changed[w]; b != 0; b &= b - 1)
        if (!o.is_sphere(w * 64 + static_cast<unsigned>(std::countr_zero(b)))) return false;
  return true;
}

bool PairTracker::Impl::movers_stale(const std::vector<std::uint64_t>& changed,
                                     std::size_t changed_count) const {
  std::size_t waking = 0;
  for (std::size_t w = 0; w < changed.size(); ++w)
    waking += static_cast<std::size_t>(std::popcount(changed[w] & quiet[w]));
  return (woken.size() + waking) * kWokenShare > quiet_at_partition ||
         (movers_calls >= kMoversPatience && active.size() + woken.size() > 2 * changed_count + 64);
}

ArrayCallStats PairTracker::Impl::movers_call(const Objects& o,
                                              const std::vector<std::uint64_t>& changed,
                                              const PairSink& sink) {
  ArrayCallStats stats;
  stats.movers = true;
  ++movers_calls;
  // Wake the quiet objects listed: their records in `quiet_cells` are stale
  // from now on (a probe skips them), and so are their quiet pairs.
  const std::size_t woken_before = woken.size();
  for (std::size_t w = 0; w < changed.size(); ++w)
    for (std::uint64_t b = changed[w] & quiet[w]; b != 0; b &= b - 1) {
      const auto i =
          static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b)));
      quiet[w] &= ~(std::uint64_t{1} << (i & 63));
      --quiet_count;
      woken.push_back(i);
    }
  stats.woken = woken.size() - woken_before;
  stats.quiet = quiet_count;
  const std::size_t m = active.size() + woken.size();
  // The movers' shapes, read from the caller's columns in increasing index
  // (the active ones are: a stream rather than a miss per value) and
  // widened exactly to double, then put in the order of the quiet cells'
  // finest grid, so that one probe reads much of what the last one read.
  struct Read {
    double x, y, z, r;
  };
  std::vector<Read> read(m);
  std::vector<std::uint64_t> keyed(m);
  auto mover = [&](std::size_t k) {
    return k < active.size() ? active[k] : woken[k - active.size()];
  };
  for (std::size_t k = 0; k < m; ++k) {
    const std::uint32_t i = mover(k);
    read[k] = {o.x.at(i), o.y.at(i), o.z.at(i), o.radius.at(i)};
    keyed[k] =
        (static_cast<std::uint64_t>(quiet_cells.cell_key(read[k].x, read[k].y, read[k].z)) << 32) |
        k;
  }
  sort_by_high_word(keyed);
  std::vector<std::uint32_t> ids(m);
  std::vector<double> xyzr(4 * m);
  for (std::size_t k = 0; k < m; ++k) {
    const auto from = static_cast<std::uint32_t>(keyed[k]);
    ids[k] = mover(from);
    xyzr[4 * k] = read[from].x;
    xyzr[4 * k + 1] = read[from].y;
    xyzr[4 * k + 2] = read[from].z;
    xyzr[4 * k + 3] = read[from].r;
  }
  Emitter emit(sink, options.sorted, stats);
  const unsigned threads = thread_count(options.threads);
  // The quiet pairs as they stand (without those of woken objects).
  bool go_on;
  if (woken.empty()) {
    go_on = emit.deliver_slices(quiet_hits);
  } else {
    go_on = run_in_order<PairChunk>(
        quiet_hits.size(), threads,
        [&](std::size_t begin, std::size_t end, PairChunk& out) {
          out.pairs.clear();
          out.tests = 0;
          for (std::size_t p = begin; p < end; ++p)
            if (is_quiet(quiet_hits[p].i) && is_quiet(quiet_hits[p].j))
              out.pairs.push_back(quiet_hits[p]);
        },
        [&](PairChunk& c) { return emit.deliver(c); });
  }
  // The movers among themselves: the one-shot call.
  if (go_on && !emit.stopped()) {
    Objects view;
    view.count = m;
    const auto stride = static_cast<std::ptrdiff_t>(4 * sizeof(double));
    view.x = {xyzr.data(), stride, Real::f64};
    view.y = {xyzr.data() + 1, stride, Real::f64};
    view.z = {xyzr.data() + 2, stride, Real::f64};
    view.radius = {xyzr.data() + 3, stride, Real::f64};
    ArrayOptions one = options;
    one.sorted = false;
    std::vector<IndexPair> among;
    stats.tests += broadphase::find_pairs(view, among, one).tests;
    for (IndexPair& p : among) p = ordered(ids[p.i], ids[p.j]);
    go_on = emit.deliver_slices(among);
  }
  // The movers with the quiet: a probe each.
  if (go_on && !emit.stopped())
    run_in_order<PairChunk>(
        m, threads,
        [&](std::size_t begin, std::size_t end, PairChunk& out) {
          out.pairs.clear();
          out.tests = 0;
          // (Woken objects' records are stale: skipped, when there are any.)
          const bool any_woken = quiet_cells.size() != quiet_count;
          for (std::size_t k = begin; k < end; ++k) {
            const std::uint32_t i = ids[k];
            out.tests += quiet_cells.probe(xyzr[4 * k], xyzr[4 * k + 1], xyzr[4 * k + 2],
                                           xyzr[4 * k + 3], [&](std::uint32_t j) {
                                             if (!any_woken || is_quiet(j))
                                               out.pairs.push_back(ordered(i, j));
                                           });
          }
        },
        [&](PairChunk& c) { return emit.deliver(c); });
  emit.finish();
  return stats;
}

PairTracker::PairTracker(const ArrayOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
}
PairTracker::~PairTracker() = default;
PairTracker::PairTracker(PairTracker&&) noexcept = default;
PairTracker& PairTracker::operator=(PairTracker&&) noexcept = default;

ArrayCallStats PairTracker::find_pairs(const Objects& objects, const PairSink& sink,
                                       const Changes& changes) {
  Impl& im = *impl_;
  // Everything that can throw on bad input runs before the tracker changes.
  check_objects(objects);
  if (objects.count > kMaxTracked)
    throw InvalidObjects("objects: " + std::to_string(objects.count) +
                             " objects, more than a tracker can name (" +
                             std::to_string(kMaxTracked) + ")",
                         SIZE_MAX);
  if (!changes.all)
    for (std::uint32_t k : changes.indices)
      if (k >= objects.count)
        throw InvalidObjects("changes: index " + std::to_string(k) + " is not below the count " +
                                 std::to_string(objects.count),
                             k);

  ArrayCallStats stats;
  const auto n = static_cast<std::uint32_t>(objects.count);
  bool rebuild = !im.built || objects.count != im.count;
  // The objects that left their fat box: renewed alone, unless so many
  // left in this call that a rebuild is cheaper. (Renewal and compaction
  // run on the calling thread only.)
  // Which objects changed: a pair of unchanged objects keeps the answer of
  // the last call (its bit), so only pairs with a changed object are tested.
  // (The renewed pairs of this call all have a changed object.)
  std::vector<std::uint64_t> changed;
  std::size_t changed_count = n;
  if (!changes.all) {
    changed.assign((objects.count + 63) / 64, 0);
    changed_count = 0;
    for (std::uint32_t k : changes.indices)
      if (!test_bit(changed, k)) {
        set_bit(changed, k);
        ++changed_count;
      }
  }
  // After a call afresh with no index (`pending`, below), a call that lists
  // its changes on as many objects enters movers mode if it can.
  if (im.pending && !changes.all && objects.count == im.count &&
      (im.quiet_cells.size() == objects.count ? im.enter_from_pending(objects, changed)
                                              : im.enter_movers(objects, changed))) {
    stats = im.movers_call(objects, changed, sink);
    stats.compacted = true;
    return stats;
  }
  // Movers mode: a call that lists its changes on the same spheres stays in
  // it (after a new partition if due); any other leaves it for the index.
  if (im.movers) {
    bool take = im.movers_suit(objects, changes, changed);
    bool partitioned = false;
    if (take && im.movers_stale(changed, changed_count)) {
      take = im.enter_movers(objects, changed);
      partitioned = take;
    }
    if (take) {
      stats = im.movers_call(objects, changed, sink);
      stats.compacted = partitioned;
      return stats;
    }
    rebuild = true;
  }
  // Renewed in this call: the objects that left their fat box, and the
  // quiet ones the caller changed (woken), unless so many that a rebuild
  // is cheaper. (Renewal and compaction run on the calling thread only.)
  std::vector<std::uint32_t> renew;
  std::size_t left = 0, quiet_changed = 0;
  bool outran = false;  // a rebuild is due because objects left their boxes
  if (!rebuild) {
    auto look = [&](std::uint32_t i) {
      quiet_changed += im.is_quiet(i) ? 1 : 0;
      if (!im.contained(objects, i)) {
        im.fat_of(i) = im.renewed_box(objects.shape(i), im.fat_of(i));
        renew.push_back(i);
        ++left;
      } else if (im.is_quiet(i)) {
        renew.push_back(i);
      }
    };
    // Each check reads the object's fat box, kept in the grid's order, so a
    // cache miss: the boxes of the objects a few ahead are asked for first.
    constexpr std::uint32_t kAhead = 16;
    if (changes.all) {
      for (std::uint32_t i = 0; i < n; ++i) {
        if (i + kAhead < n) __builtin_prefetch(&im.fat_of(i + kAhead));
        look(i);
      }
    } else {
      std::vector<std::uint32_t> list;
      list.reserve(changed_count);
      for (std::size_t w = 0; w < changed.size(); ++w)
        for (std::uint64_t b = changed[w]; b != 0; b &= b - 1)
          list.push_back(
              static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b))));
      for (std::size_t r = 0; r < list.size(); ++r) {
        if (r + kAhead < list.size()) __builtin_prefetch(&im.fat_of(list[r + kAhead]));
        look(list[r]);
      }
    }
    rebuild = static_cast<double>(renew.size()) > kRebuildFraction * static_cast<double>(n);
    outran = rebuild;
  }
  // Motion outran the skin: so many objects left their fat boxes that the
  // index would be built again. A set of spheres in cells that are not
  // crowded is then searched afresh by the one-shot kernel, several times
  // cheaper than a build, and so are the next kAfreshCalls calls, without
  // an index (the tracker holds nothing meanwhile); the call after them
  // builds one again, to see whether the motion has slowed. Measured on
  // one core, all-moving 20 000 (every object moves every frame, mostly
  // past the skin): 11.0 ms a call on the index, 1.3 ms afresh. Where the
  // cells are crowded (the study's scenes at 6 400: calls afresh 1.2 to 1.5
  // times the index's between builds), the index is built as before.
  if (outran || (rebuild && im.afresh_left > 0)) {
    detail::SphereCells cells;
    if (cells.build(objects) && cells.crowd() <= kAfreshCrowd) {
      const std::uint32_t afresh_left = outran ? kAfreshCalls : im.afresh_left - 1;
      const ArrayOptions options = im.options;
      clear();
      im.afresh_left = afresh_left;
      stats = cell_pairs(cells, sink, options);
      stats.afresh = true;
      return stats;
    }
    im.afresh_left = 0;
  }
  // No index yet (a first call, a new count, movers mode left): a set that
  // movers mode may take is searched afresh, holding nothing, and the next
  // call that lists its changes partitions it straight away; a next call
  // that does not builds the index. The index's build (1.0-1.2 s at
  // scaled-even 1 024 000, three one-shot calls' worth) is then not paid
  // by a caller that lists its changes.
  // The pairs are kept, with the cells: the next call enters movers mode
  // by sorting the quiet objects into cells of their own and dropping the
  // listed objects' pairs, without finding the quiet pairs again
  // (scaled-even 1 024 000, that call 410 -> 324 ms on one core).
  if (rebuild && !im.pending) {
    detail::SphereCells cells;
    if (cells.build(objects) && cells.crowd() <= kMoversCrowd) {
      const ArrayOptions options = im.options;
      const std::uint32_t quiet_after = im.quiet_after;
      clear();
      std::vector<IndexPair> all;
      stats = cell_pairs(cells, sink, options, &all);
      im.quiet_after = quiet_after;
      im.pending = true;
      im.count = objects.count;
      if (!stats.stopped) {  // (a sink that stopped early saw only some)
        all.shrink_to_fit();
        im.quiet_hits = std::move(all);
        im.quiet_cells = std::move(cells);
      }
      stats.afresh = true;
      return stats;
    }
  }
  // Objects that did not change in this call while their candidates are
  // still scanned become quiet, when they are many (a pass over the rows).
  if (changes.all) {
    im.listed_calls = 0;
    if (im.quiet_count > 0) im.quiet_after = std::min<std::uint32_t>(im.quiet_after * 4, 1u << 20);
  } else {
    ++im.listed_calls;
  }
  const bool bits_hold = im.built && !im.fresh && !changes.all && im.listed_calls >= im.quiet_after;
  auto partition_pays = [&] {
    return bits_hold && (n - im.quiet_count) - (changed_count - quiet_changed) > n / 8;
  };
  if (rebuild) {
    im.rebuild(objects);
    stats.rebuilt = true;
  } else {
    const bool partition_now = partition_pays();  // before renewals change the quiet count
    // Movers mode, at a partition or, while objects are quiet, as soon as
    // the set suits it (a box among the spheres may have gone).
    if ((partition_now || (bits_hold && im.quiet_count > 0 && !im.movers_refused)) &&
        im.enter_movers(objects, changed)) {
      stats = im.movers_call(objects, changed, sink);
      stats.compacted = true;
      return stats;
    }
    if (!renew.empty()) {
      im.renew(renew);
      stats.renewed = left;
      stats.woken = quiet_changed;
    }
    if (partition_now || (!renew.empty() && im.wants_compaction())) {
      im.compact(objects, bits_hold ? &changed : nullptr);
      stats.compacted = true;
    }
  }
  const bool test_all = changes.all || im.fresh;
  auto is_changed = [&](std::uint32_t k) { return test_all || test_bit(changed, k); };
  // Until every row is done (a sink may stop early or throw), the bits are
  // not to be trusted.
  im.fresh = true;

  const std::size_t rows = im.offset.size() - 1;
  const bool any_renewed = !im.renewed_list.empty();
  Emitter emit(sink, im.options.sorted, stats);
  const unsigned threads = thread_count(im.options.threads);
  // The scan over the rows, then over the renewed objects' candidates in
  // the order they were found, with shapes from `rd`.
  auto scan = [&](const auto& rd) {
    const bool go_on = run_in_order<PairChunk>(
        rows, threads,
        [&](std::size_t begin, std::size_t end, PairChunk& out) {
          out.pairs.clear();
          out.tests = 0;
          for (std::size_t k = begin; k < end; ++k) {
            if (k + kPrefetchRows < rows)
              for (std::uint32_t p = im.offset[k + kPrefetchRows];
                   p < im.offset[k + kPrefetchRows + 1]; ++p)
                rd.prefetch(im.partner[p] & kIndexMask);
            const std::uint32_t s = im.offset[k], e = im.offset[k + 1];
            if (s == e) continue;
            const std::uint32_t i = im.grid.probe_object(k);
            if (any_renewed && im.is_renewed(i)) continue;  // its pairs are loose
            const bool i_changed = is_changed(i);
            for (std::uint32_t p = s; p < e; ++p) {
              std::uint32_t& entry = im.partner[p];
              const std::uint32_t q = entry & kIndexMask;
              const std::uint32_t j = im.grid.probe_object(q);
              if (any_renewed && im.is_renewed(j)) continue;
              bool hit;
              if (i_changed || is_changed(j)) {
                ++out.tests;
                hit = overlaps(rd.row(k, i), rd.row(q, j));
                entry = q | (hit ? kOverlapBit : 0);
              } else {
                hit = (entry & kOverlapBit) != 0;
              }
              if (hit) out.pairs.push_back(ordered(i, j));
            }
          }
        },
        [&](PairChunk& c) { return emit.deliver(c); });
    if (go_on)
      run_in_order<PairChunk>(
          im.loose.size(), threads,
          [&](std::size_t begin, std::size_t end, PairChunk& out) {
            out.pairs.clear();
            out.tests = 0;
            for (std::size_t p = begin; p < end; ++p) {
              LoosePair& lp = im.loose[p];
              const std::uint32_t ka = lp.a, kb = lp.b & kIndexMask;
              const std::uint32_t i = im.grid.probe_object(ka), j = im.grid.probe_object(kb);
              bool hit;
              if (is_changed(i) || is_changed(j)) {
                ++out.tests;
                hit = overlaps(rd.row(ka, i), rd.row(kb, j));
                lp.b = kb | (hit ? kOverlapBit : 0);
              } else {
                hit = (lp.b & kOverlapBit) != 0;
              }
              if (hit) out.pairs.push_back(ordered(i, j));
            }
          },
          [&](PairChunk& c) { return emit.deliver(c); });
    if (!go_on || emit.stopped()) return;
    if (!any_renewed) {
      emit.deliver_slices(im.quiet_hits);  // as they stand
      return;
    }
    run_in_order<PairChunk>(
        im.quiet_hits.size(), threads,
        [&](std::size_t begin, std::size_t end, PairChunk& out) {
          out.pairs.clear();
          out.tests = 0;
          for (std::size_t p = begin; p < end; ++p) {
            const IndexPair q = im.quiet_hits[p];
            if (!im.is_renewed(q.i) && !im.is_renewed(q.j)) out.pairs.push_back(q);
          }
        },
        [&](PairChunk& c) { return emit.deliver(c); });
  };
  // When many objects changed, most objects take part in a test, and the
  // tests' reads of the caller's columns (one cache miss a column, in the
  // caller's order) dominate the call: the shapes are first copied, in one
  // sequential pass over the columns, into the rows' order, where a row's
  // partners lie near it (docs/arrays.md). With few changes, the tests
  // read the columns directly.
  if ((test_all ? n : changed_count) * kGatherShare >= objects.count) {
    detail::BigVector<Shape> now(rows);
    for (std::uint32_t i = 0; i < n; ++i) now[im.place[i]] = read_shape(objects, i);
    struct Gathered {
      const Shape* now;
      // Object i's shape, at place k.
      const Shape& row(std::size_t k, std::uint32_t) const { return now[k]; }
      void prefetch(std::uint32_t q) const { __builtin_prefetch(now + q); }
    };
    scan(Gathered{now.data()});
  } else {
    struct Direct {
      const Objects& o;
      Shape row(std::size_t, std::uint32_t i) const { return read_shape(o, i); }
      void prefetch(std::uint32_t) const {}
    };
    scan(Direct{objects});
  }
  emit.finish();
  im.fresh = stats.stopped;
  stats.quiet = im.quiet_count;
  return stats;
}

ArrayCallStats PairTracker::find_pairs(const Objects& objects, std::vector<IndexPair>& out,
                                       const Changes& changes) {
  return find_pairs(objects, append_to(out), changes);
}

std::size_t PairTracker::memory_bytes() const {
  const Impl& im = *impl_;
  return sizeof(Impl) + im.fat.capacity() * sizeof(AabbF) + im.grid.memory_bytes() +
         im.quiet.capacity() * sizeof(std::uint64_t) +
         im.quiet_hits.capacity() * sizeof(IndexPair) + im.grid.slim_bytes() +
         (im.place.capacity() + im.offset.capacity() + im.partner.capacity() +
          im.renewed_list.capacity()) *
             sizeof(std::uint32_t) +
         im.renewed.capacity() * sizeof(std::uint64_t) + im.loose.capacity() * sizeof(LoosePair) +
         im.quiet_cells.memory_bytes() +
         (im.active.capacity() + im.woken.capacity()) * sizeof(std::uint32_t);
}

void PairTracker::clear() {
  const ArrayOptions options = impl_->options;
  *impl_ = Impl{};
  impl_->options = options;
}

// The movers mode's invariants (see PairTracker::Impl::movers).
void PairTracker::Impl::check_movers(const Objects& objects) const {
  const Impl& im = *this;
  auto fail = [](const std::string& why) { throw std::logic_error("PairTracker: " + why); };
  const std::size_t n = im.count;
  if (im.quiet.size() != (n + 63) / 64) fail("one quiet bit per object");
  // Every object is exactly one of quiet, active (increasing) and woken.
  enum : char { kNone, kQuiet, kActive, kWoken };
  std::vector<char> role(n, kNone);
  std::size_t quiet = 0;
  for (std::uint32_t i = 0; i < n; ++i)
    if (im.is_quiet(i)) {
      role[i] = kQuiet;
      ++quiet;
    }
  if (quiet != im.quiet_count) fail("quiet bits and count disagree");
  for (std::size_t k = 0; k < im.active.size(); ++k) {
    const std::uint32_t i = im.active[k];
    if (i >= n || role[i] != kNone || (k > 0 && im.active[k - 1] >= i))
      fail("active object " + std::to_string(i) + " out of range, order or also quiet");
    role[i] = kActive;
  }
  for (std::uint32_t i : im.woken) {
    if (i >= n || role[i] != kNone) fail("woken object " + std::to_string(i) + " listed wrongly");
    role[i] = kWoken;
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    if (role[i] == kNone) fail("object " + std::to_string(i) + " is neither quiet nor a mover");
    if (!objects.is_sphere(i)) fail("object " + std::to_string(i) + " is not a sphere");
  }
  // The quiet cells hold every quiet and woken object once, and no other,
  // the quiet ones exactly as they are now.
  std::vector<char> held(n, 0);
  im.quiet_cells.for_each([&](std::uint32_t i, double x, double y, double z, double r) {
    if (i >= n || held[i] || role[i] == kActive)
      fail("quiet cells hold " + std::to_string(i) + " wrongly or twice");
    held[i] = 1;
    if (role[i] == kQuiet && (x != objects.x.at(i) || y != objects.y.at(i) ||
                              z != objects.z.at(i) || r != objects.radius.at(i)))
      fail("quiet object " + std::to_string(i) + " changed without being listed");
  });
  for (std::uint32_t i = 0; i < n; ++i)
    if (role[i] != kActive && !held[i])
      fail("quiet object " + std::to_string(i) + " is not in the quiet cells");
  // The quiet pairs: each once, i < j, of two objects quiet at the
  // partition, overlapping while both still are; all of them on small sets.
  std::unordered_set<std::uint64_t> seen;
  for (const IndexPair& q : im.quiet_hits) {
    const std::string name =
        "quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) + ")";
    if (q.i >= q.j || q.j >= n) fail(name + " out of order or range");
    if (role[q.i] == kActive || role[q.j] == kActive) fail(name + " has a mover");
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second) fail(name + " listed twice");
    if (role[q.i] == kQuiet && role[q.j] == kQuiet &&
        !overlaps(objects.shape(q.i), objects.shape(q.j)))
      fail(name + " does not overlap");
  }
  if (n <= 3000)
    for (std::uint32_t i = 0; i < n; ++i)
      for (std::uint32_t j = i + 1; j < n; ++j)
        if (role[i] == kQuiet && role[j] == kQuiet &&
            overlaps(objects.shape(i), objects.shape(j)) &&
            !seen.count((std::uint64_t(i) << 32) | j))
          fail("overlapping quiet objects " + std::to_string(i) + " and " + std::to_string(j) +
               " are not a quiet pair");
}

void PairTracker::validate(const Objects& objects) const {
  const Impl& im = *impl_;
  auto fail = [](const std::string& why) { throw std::logic_error("PairTracker: " + why); };
  if (!im.built) return;
  if (im.count != objects.count) fail("count differs from the last call's objects");
  const std::size_t n = im.count;
  if (im.movers) {
    im.check_movers(objects);
    return;
  }
  if (im.fat.size() != n || im.place.size() != n) fail("one fat box and place per object");
  const std::size_t rows = im.grid.probe_count();
  if (rows != n) fail("one candidate row per object");
  if (im.offset.size() != rows + 1 || im.offset[0] != 0 || im.offset[rows] != im.partner.size())
    fail("candidate offsets do not span the partner list");
  if (im.renewed.size() != (n + 63) / 64) fail("one renewed bit per object");
  // The renewed list and bits agree, without repeats.
  std::size_t marked = 0;
  for (std::uint32_t i = 0; i < n; ++i) marked += im.is_renewed(i) ? 1 : 0;
  if (marked != im.renewed_list.size()) fail("renewed bits and list disagree");
  {
    std::vector<char> listed(n, 0);
    for (std::uint32_t i : im.renewed_list) {
      if (i >= n || !im.is_renewed(i) || listed[i])
        fail("renewed list holds " + std::to_string(i) + " wrongly or twice");
      listed[i] = 1;
    }
  }
  if (!im.quiet.empty() && im.quiet.size() != (n + 63) / 64) fail("one quiet bit per object");
  {
    std::size_t quiet = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      quiet += im.is_quiet(i) ? 1 : 0;
      if (im.is_quiet(i) && im.is_renewed(i))
        fail("object " + std::to_string(i) + " is both quiet and renewed");
    }
    if (quiet != im.quiet_count) fail("quiet bits and count disagree");
  }
  std::vector<char> has_row(n, 0);
  std::unordered_set<std::uint64_t> seen;
  auto check_pair = [&](std::uint32_t i, std::uint32_t entry) {
    const std::uint32_t j = entry & kIndexMask;
    if (j >= n || j == i) fail("candidate partner out of range at " + std::to_string(i));
    const IndexPair q = ordered(i, j);
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second)
      fail("candidate pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") listed twice");
    if (!im.fat_of(i).overlaps(im.fat_of(j)))
      fail("candidate pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") has fat boxes apart");
    if (!im.fresh && ((entry & kOverlapBit) != 0) != overlaps(objects.shape(i), objects.shape(j)))
      fail("the overlap bit of (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") is stale");
  };
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t i = im.grid.probe_object(k);
    if (i >= n || has_row[i]) fail("row " + std::to_string(k) + " has a bad or repeated owner");
    if (im.place[i] != k) fail("object " + std::to_string(i) + " is not at its row's place");
    has_row[i] = 1;
    if (im.offset[k] > im.offset[k + 1]) fail("candidate offsets decrease at " + std::to_string(k));
    if (!im.contained(objects, i))
      fail("object " + std::to_string(i) + " lies outside its fat box");
    if (im.is_renewed(i)) continue;  // dead row
    for (std::uint32_t p = im.offset[k]; p < im.offset[k + 1]; ++p) {
      if ((im.partner[p] & kIndexMask) >= rows)
        fail("candidate place out of range at " + std::to_string(k));
      const std::uint32_t j = im.partner_object(im.partner[p]);
      if (im.is_renewed(j)) continue;  // dead entry
      if (im.is_quiet(i) && im.is_quiet(j))
        fail("candidate pair of quiet " + std::to_string(i) + " and " + std::to_string(j) +
             " left in the rows");
      check_pair(i, j | (im.partner[p] & kOverlapBit));
    }
  }
  for (const LoosePair& lp : im.loose) {
    const std::uint32_t kb = lp.b & kIndexMask;
    if (lp.a >= kb || kb >= rows)
      fail("loose pair at places (" + std::to_string(lp.a) + ", " + std::to_string(kb) +
           ") out of order or range");
    const std::uint32_t i = im.grid.probe_object(lp.a), j = im.grid.probe_object(kb);
    if (!im.is_renewed(i) && !im.is_renewed(j))
      fail("loose pair (" + std::to_string(i) + ", " + std::to_string(j) +
           ") has no renewed object");
    check_pair(i, j | (lp.b & kOverlapBit));
  }
  for (const IndexPair& q : im.quiet_hits) {
    if (q.i >= q.j || q.j >= n)
      fail("quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") out of order or range");
    if (im.is_renewed(q.i) || im.is_renewed(q.j)) continue;  // dead
    const std::string name =
        "quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) + ")";
    if (!im.is_quiet(q.i) || !im.is_quiet(q.j)) fail(name + " has an object that is not quiet");
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second) fail(name + " listed twice");
    if (!overlaps(objects.shape(q.i), objects.shape(q.j))) fail(name + " does not overlap");
  }
  // Completeness: every pair of overlapping fat boxes is a candidate
  // (quadratic, so checked only on small sets).
  if (n <= 3000)
    for (std::uint32_t i = 0; i < n; ++i)
      for (std::uint32_t j = i + 1; j < n; ++j)
        if (im.fat_of(i).overlaps(im.fat_of(j)) && !seen.count((std::uint64_t(i) << 32) | j) &&
            !(im.is_quiet(i) && im.is_quiet(j) && !overlaps(objects.shape(i), objects.shape(j))))
          fail("overlapping fat boxes of " + std::to_string(i) + " and " + std::to_string(j) +
               " are not candidates");
}

}  // namespace broadphase
