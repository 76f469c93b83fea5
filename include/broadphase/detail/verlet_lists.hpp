/// \file verlet_lists.hpp
/// The moving objects of grid-verlet (grid_verlet.hpp): each mover's fat
/// box and its candidate lists, kept by VerletLists. The lists hold, like a
/// Verlet neighbour list in molecular dynamics, every object near a box
/// grown by a margin, so that while an object stays inside its box a frame
/// tests its lists alone. VerletLists renews the boxes that their movers
/// left, renews those movers' lists from the grids, and keeps the list
/// pools (compacted in place, never shrunk); the structure reads the lists
/// in its frames.
#pragma once

#include <algorithm>
#include <bit>
#include <broadphase/detail/level_grid.hpp>
#include <broadphase/detail/work_shares.hpp>
#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace broadphase::detail {

/// Per moving-grid entry (in the same order): its bounds now, the "fat"
/// box its lists cover (which is also its grid entry's box), where its
/// lists are, and its last displacement. Lists stay valid while the
/// bounds stay inside the fat box; then the box and lists are renewed.
struct VerletMover {
  AabbF cur;
  AabbF fat;
  std::uint32_t list_begin = 0, list_count = 0;  // fixed candidates, in the list pool
  std::uint32_t near_begin = 0, near_count = 0;  // moving neighbours (slots), in the near pool
  std::uint32_t epoch = 0;                       // fixed-grid epoch of the lists; 0: renewal due
  std::uint32_t stamp = 0;                       // the rebuild that last renewed them
  float speed = 0;
  bool fast = false;    // too fast for a margin: probes the moving grid each frame
  bool guessed = true;  // the fat box was made before the speed was known
};

/// One fixed object in a candidate list: a copy of its sphere (so that a
/// frame reads lists front to back, never the fixed grid) and its handle.
/// A box has a NaN radius whose payload is its entry in the fixed grid
/// (`box_entry`): its shape is read from the grid's copy at once, without
/// the slot lookup (the lists are renewed whenever the grid is rebuilt).
struct VerletCandidate {
  double c[3];
  double r;
  Handle handle;
  /// The radius of a box at entry `k` of the fixed grid: a quiet NaN
  /// carrying `k`.
  static double box_radius(std::uint32_t k) {
    return std::bit_cast<double>(0x7ff8000000000000ull | k);
  }
  bool is_box() const { return r != r; }
  /// A box's entry in the fixed grid (the payload of its NaN radius).
  std::uint32_t box_entry() const {
    return static_cast<std::uint32_t>(std::bit_cast<std::uint64_t>(r));
  }
};
static_assert(sizeof(VerletCandidate) == 40, "candidates are packed for the list scans");

/// The largest move of a bound along any axis: the displacement that sets
/// a mover's margin.
inline float displacement(const AabbF& from, const AabbF& to) {
  float d = 0;
  for (int a = 0; a < 3; ++a)
    d = std::max(d, std::max(std::fabs(to.lo[a] - from.lo[a]), std::fabs(to.hi[a] - from.hi[a])));
  return d;
}

/// Releases a scratch vector that holds more than twice what it last held
/// plus 64 KiB, after use (a wave of renewals, a scene streamed in).
template <class T>
void release_if_oversized(std::vector<T>& v) {
  constexpr std::size_t kKeepScratchBytes = 64 * 1024;
  if (v.capacity() * sizeof(T) > 2 * v.size() * sizeof(T) + kKeepScratchBytes)
    std::vector<T>().swap(v);
}

/// The movers' records, in the moving grid's entry order, and their
/// candidate lists. A mover's fixed list holds the fixed objects whose
/// bounds overlap its fat box; its near list holds the movers whose fat
/// boxes overlapped its own when it was renewed. A pair of movers is tested
/// from the list of the one renewed last (by the lower slot when both were
/// renewed by the same rebuild): that list was made against the other's
/// current fat box, so it holds the pair whenever the two objects can
/// touch. A frame thus reads lists front to back and probes grids only for
/// the movers that left their fat boxes. A list that stays valid stays
/// where it is; renewed lists are appended, and when they would not fit in
/// a pool's memory the lists that stay are first moved to its front in
/// place (the pools never shrink, so a steady frame allocates nothing).
/// Every list is renewed when the fixed grid is rebuilt.
class VerletLists {
 public:
  using Mover = VerletMover;
  using Candidate = VerletCandidate;
  /// List lengths of the movers whose lists stay and of those whose lists
  /// are renewed (by their present lengths), fixed and near.
  struct Totals {
    std::size_t kept = 0, renewing = 0, near_kept = 0, near_renewing = 0;
  };
  /// Candidate pools larger than this are taken to be out of cache (a
  /// typical second-level cache).
  static constexpr std::size_t kCachedListBytes = std::size_t{2} << 20;

  // --- What frames read ---------------------------------------------------

  /// The records, parallel to the moving grid's entries.
  const std::vector<Mover>& movers() const { return movers_; }
  /// The fixed-candidate pool (a list is [list_begin, + list_count)).
  const Candidate* list_data() const { return list_pool_.data(); }
  /// The near pool of moving neighbours' slots.
  const std::uint32_t* near_data() const { return near_pool_.data(); }
  /// True when the candidate pool is larger than a typical cache.
  bool lists_out_of_cache() const {
    return list_pool_.size() * sizeof(Candidate) > kCachedListBytes;
  }
  /// Movers that are not fast on level `l` of the moving grid.
  std::uint32_t slow_on_level(std::size_t l) const { return slow_per_level_[l]; }
  /// True while the movers keep no lists (set_direct).
  bool direct() const { return direct_; }
  /// The share of the live movers whose lists a frame would renew, as
  /// their last displacements predict: a fast mover every frame, one whose
  /// margin holds F frames of its displacement once in F frames. The same
  /// with or without lists (it reads bounds and displacements only), and
  /// the same for every thread count. O(movers).
  double renewal_share(const LevelGrid& moving) const;
  /// How often a mover with bounds `cur` and last displacement `speed`
  /// would renew its lists, a share of frames in [0, 1] (renewal_share's
  /// term).
  double renewal_rate(const AabbF& cur, float speed) const;

  // --- Changes --------------------------------------------------------------

  /// Mover k's bounds are `b` and its last displacement `speed`, as kept
  /// elsewhere while the movers had no lists.
  void place(std::size_t k, const AabbF& b, float speed) {
    movers_[k].cur = b;
    movers_[k].speed = speed;
  }
  /// Mover k's bounds are now `b` (its last displacement is remembered);
  /// its box and lists stay until the next rebuild renews them if needed.
  void move(std::size_t k, const AabbF& b);
  /// The box a mover's lists cover: its bounds grown by a margin that
  /// covers several frames of `speed` (its last displacement), within
  /// limits; `fast` tells whether the mover is too fast for a useful one.
  AabbF fat_box(const AabbF& cur, float speed, bool& fast) const;
  /// Without lists (`on`): from the next rebuild every mover's box is its
  /// bounds, every mover is fast, and no list is kept (the owner finds the
  /// movers' pairs without them). Back with lists: the next rebuild gives
  /// every mover a new fat box and new lists.
  void set_direct(bool on);
  /// The fixed grid was rebuilt: every list is renewed at the next renew(),
  /// and margins follow the new grid's finest cell.
  void fixed_grid_rebuilt(const LevelGrid& fixed);
  /// Starts a rebuild of the moving grid: gives a new fat box (and a
  /// renewal) to every live mover whose bounds left its box or whose box
  /// was made before its speed was known, writes it into its grid entry,
  /// and returns the lengths of the lists that stay and of those to be
  /// renewed. When `items` is not empty (no entry is dead), also copies
  /// each entry k to items[k] and k to src[k], in the same pass.
  Totals refresh_boxes(LevelGrid& moving, std::span<GridEntry> items, std::span<std::uint32_t> src,
                       const WorkShares& shares);
  /// Before the moving grid is rebuilt with n entries: the records are set
  /// aside; keep() and start() then place each entry's record.
  void reorder(std::size_t n) {
    old_movers_.swap(movers_);
    movers_.resize(n);
  }
  /// Entry k's record is the one of entry `old` before the rebuild.
  void keep(std::uint32_t k, std::uint32_t old) { movers_[k] = old_movers_[old]; }
  /// Entry k is a new mover with bounds `cur`, last displacement `speed`
  /// (0: unknown) and fat box `fat` (without lists: `cur`, and no list due).
  void start(std::uint32_t k, const AabbF& cur, float speed, const AabbF& fat) {
    Mover& mv = movers_[k];
    mv = Mover{};
    mv.cur = cur;
    mv.speed = speed;
    mv.guessed = !direct_ && !(speed > 0);
    mv.fat = direct_ ? cur : fat;
    mv.fast = direct_;
    if (direct_) mv.epoch = epoch_;
  }
  /// After the moving grid is rebuilt: counts the slow movers per level,
  /// and renews the lists of the movers whose boxes are new (all of them
  /// after a fixed-grid rebuild) from the two grids, `totals` being what
  /// refresh_boxes returned. The pools are the same for every thread count.
  /// With `filters` (by slot; empty: none) a list leaves out the candidates
  /// whose group/mask bits fail against its mover's: such lists hold until
  /// a filter changes (the owner then renews them all, fixed_grid_rebuilt).
  void renew(const LevelGrid& fixed, const LevelGrid& moving, const Totals& totals,
             const WorkShares& shares, std::span<const Filter> filters = {});

  /// Bytes held by the records, pools and scratch.
  std::size_t memory_bytes() const;
  /// Checks the lists against the grids; `fixed_entry(slot)` is the fixed
  /// grid's entry of a slot's object when it is there. Throws
  /// std::logic_error naming what is wrong.
  /// `filters` as renew() was given them; with `current` false (a filter
  /// changed since), only the lists' layout is checked, not that they are
  /// complete.
  void validate(const LevelGrid& fixed, const LevelGrid& moving, std::size_t slot_count,
                const std::function<std::optional<std::uint32_t>(std::uint32_t)>& fixed_entry,
                std::span<const Filter> filters = {}, bool current = true) const;

 private:
  struct alignas(64) ShareTotals {  // on lines of its own: each share writes its own
    std::uint32_t count[LevelGrid::kLevelSlots] = {};  // per level: movers that are not fast
    Totals lists;                                      // list lengths, before renewals
  };
  /// Counts, per level of the moving grid, the movers that are not fast.
  void count_slow(const LevelGrid& moving, const WorkShares& shares);
  /// Before renewals: when the lists about to be renewed would not fit in
  /// a pool, moves the lists that stay to its front, in place.
  void make_room(const LevelGrid& moving, const Totals& totals);
  /// Renews the lists of the movers of entries [begin, end) that need it,
  /// into `part` and `near` (offsets relative to them), noting each in
  /// `renewed`.
  void renew_range(const LevelGrid& fixed, const LevelGrid& moving, std::size_t begin,
                   std::size_t end, std::vector<Candidate>& part, std::vector<std::uint32_t>& near,
                   std::vector<std::uint32_t>& renewed, std::span<const Filter> filters);
  /// The filter rule over slots, `filters` by slot (missing: the default).
  static bool bits_pass(std::span<const Filter> filters, std::uint32_t a, std::uint32_t b) {
    if (filters.empty()) return true;
    const Filter fa = a < filters.size() ? filters[a] : Filter{};
    const Filter fb = b < filters.size() ? filters[b] : Filter{};
    return filters_pass(fa, fb);
  }

  std::vector<Mover> movers_;                           // parallel to the moving grid's entries
  std::vector<Mover> old_movers_;                       // the records before a rebuild
  std::vector<Candidate> list_pool_;                    // fixed candidates
  std::vector<std::uint32_t> near_pool_;                // moving neighbours (slots)
  std::vector<std::vector<Candidate>> list_parts_;      // per chunk, its renewed lists
  std::vector<std::vector<std::uint32_t>> near_parts_;  // per chunk, its renewed near lists
  std::vector<std::vector<std::uint32_t>> renewed_;     // per chunk, the movers it renewed
  std::vector<ShareTotals> share_totals_;
  std::vector<std::uint32_t> slow_per_level_;  // per moving-grid level: movers not fast
  std::uint32_t epoch_ = 1;                    // bumped at every fixed-grid rebuild
  std::uint32_t stamp_ = 0;                    // bumped at every rebuild
  double finest_cell_ = 0;                     // the fixed grid's finest cell side (0: none)
  bool direct_ = false;                        // no lists, boxes are bounds (set_direct)
  bool refit_ = false;                         // every mover gets a new fat box at the next refresh
};

}  // namespace broadphase::detail
