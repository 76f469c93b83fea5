/// \file fast_grid.hpp
/// `fast-grid`: the performance-tuned structure. A hierarchy of row grids
/// (cells in y and z, each row a list sorted along x) rebuilt in bulk, with
/// fixed and moving objects kept apart and the pairs among fixed objects
/// cached, so that a frame of the study retests only what moved.
///
/// Layout. Objects live in slot-indexed arrays (shape, user data,
/// generation, where the object is). Each of the two grids (fixed objects,
/// moving objects) is a flat array of 28-byte entries (float bounds rounded
/// outwards plus the slot) sorted by (level, row, lower x), with one row
/// index array per level. An object goes into exactly one row of one level:
/// the level whose reach (4^k times a base) covers its widest extent, the
/// row of its lower corner. A query box visits on each level the rows whose
/// lower corner could still reach it and, inside a row, the x range
/// [q.lo.x - reach, q.hi.x] found by binary search, so every object is met
/// at most once and every pair is reported once by construction.
///
/// Mutations. A bulk `update(span)` rebuilds the moving grid in one sort
/// (and the fixed grid with its pair cache when the fixed set changed).
/// A single insert or update puts the object on a short unsorted "loose"
/// list that every query and frame scans; a removal takes the object out at
/// once (loose objects leave their list, grid objects are masked and their
/// slot is held back until the next rebuild so that no stale grid entry can
/// name a new object). When the loose and held-back objects exceed
/// max(64, size/8), the mutation that crossed the line rebuilds: amortised
/// O(log n) per insert, and no work is ever left for the next query.
///
/// Threads. `find_pairs` splits the moving objects over `threads` threads
/// (option `threads=N`, default 1, 0 = hardware concurrency); each writes
/// its own buffer and the buffers are joined in order, so the pair order
/// and hash never depend on the thread count.
#pragma once

#include <algorithm>
#include <broadphase/broad_phase.hpp>
#include <broadphase/registry.hpp>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <mutex>
#include <span>
#include <utility>
#include <vector>

namespace broadphase {

/// Hierarchical row grid with a fixed/moving split and cached fixed pairs.
/// insert, remove, update: amortised O(log n) (O(1) unless a rebuild is
/// due); bulk update of m objects: O(m log m) plus a rebuild of the fixed
/// grid, O(f log f + pairs), only when the fixed set changed. Handles stay
/// valid until their object is removed. Const members may run concurrently;
/// mutations need exclusive access.
class FastGrid {
 public:
  /// Options: `threads=N` (0..64; 0 = hardware concurrency; default 1);
  /// `cell=F` (1..64, default 2): a row's cell in y and z over its level's
  /// reach (larger: fewer row probes, more candidates per row).
  explicit FastGrid(const Config& c = {});

  /// Adds an object (to the loose list). Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object; its handle becomes stale. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves one object (to the loose list). Throws InvalidHandle, InvalidShape.
  /// A fixed object that is updated is treated as moving from then on.
  void update(Handle h, const Shape& s);
  /// Moves many objects and rebuilds the moving grid once. Throws like
  /// update(h, s), before changing anything when a handle or shape is bad.
  void update(std::span<const Move> moves);

  /// Visits every object whose shape overlaps `q` exactly.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const;
  /// Visits every overlapping pair once, in a deterministic order.
  template <class V>
  QueryCost for_each_pair(V&& visitor) const;
  /// Appends every overlapping pair once to `out`, using the configured
  /// threads; the order equals for_each_pair's whatever the thread count.
  QueryCost find_pairs(std::vector<HandlePair>& out) const;

  /// The number of live objects. O(1).
  std::size_t size() const { return live_; }
  /// Bytes held: the capacity of every container, pair buffers included.
  std::size_t memory_bytes() const;
  /// True when `h` names a live object of this structure. O(1).
  bool contains(Handle h) const {
    return h.index < gen_.size() && gen_[h.index] == h.generation && (h.generation & 1u) != 0;
  }
  /// The object's shape. Throws InvalidHandle. The reference lives until
  /// the next mutation.
  const Shape& shape(Handle h) const { return shapes_[index_of(h)]; }
  /// The user data given at insertion. Throws InvalidHandle.
  std::uint64_t user_data(Handle h) const { return user_[index_of(h)]; }
  /// The number of threads find_pairs uses.
  unsigned threads() const { return threads_; }
  /// Checks slots, lists, grid order and the pair cache; throws std::logic_error.
  void validate() const;

 private:
  /// Where a slot's object is: which list or grid holds its live entry.
  enum class Home : std::uint8_t { free, held, fixed_grid, moving_grid, loose };

  /// One object in a grid: its float bounds and its slot.
  struct Entry {
    float lo[3];
    float hi[3];
    std::uint32_t slot;
  };
  static_assert(sizeof(Entry) == 28, "grid entries are packed for the row scans");

  /// One level of a grid: objects whose widest extent is at most
  /// 0.98 * reach, in ny * nz rows of `cell` (>= reach) in y and z.
  struct Level {
    double reach = 0;
    double inv_cell = 0;
    double origin_y = 0, origin_z = 0;
    std::uint32_t ny = 1, nz = 1;
    std::uint32_t first_row = 0;

    std::uint32_t cell(double v, double origin, std::uint32_t n) const {
      const double t = (v - origin) * inv_cell;
      if (!(t >= 0)) return 0;  // also NaN from an infinite reach
      if (t >= static_cast<double>(n - 1)) return n - 1;
      return static_cast<std::uint32_t>(t);
    }
  };

  struct Grid {
    std::vector<Level> levels;
    std::vector<std::uint32_t> row_start{0};  // per row, into entries; one extra at the end
    std::vector<Entry> entries;
    std::vector<std::uint32_t> entry_row;  // per entry, its row (for split ranges)
    // Per entry, a copy of its object's shape: the exact tests of a scan
    // read this array in the grid's spatial order instead of the slot array
    // in insertion order (a cache miss per test on large scenes).
    std::vector<Shape> shapes;

    /// The shape copy of an entry met by scan().
    const Shape& shape_of(const Entry& e) const {
      return shapes[static_cast<std::size_t>(&e - entries.data())];
    }

    /// Calls f(entry) for every entry whose float box overlaps `q`, on
    /// levels from `first_level` (on that level only entries whose lower x
    /// is at least `first_min_x`); stops when f returns false.
    template <class F>
    bool scan(const AabbF& q, std::size_t first_level, double first_min_x, F&& f) const;
    std::size_t memory_bytes() const {
      return levels.capacity() * sizeof(Level) + row_start.capacity() * 4 +
             entries.capacity() * sizeof(Entry) + entry_row.capacity() * 4 +
             shapes.capacity() * sizeof(Shape);
    }
  };

  // A row probe (index lookup and binary search) costs about as much as
  // testing this many entries.
  static constexpr std::uint64_t kProbeCost = 8;
  static constexpr double kNoMinX = -std::numeric_limits<double>::infinity();

  std::uint32_t index_of(Handle h) const {
    if (!contains(h)) throw InvalidHandle(h);
    return h.index;
  }
  Handle handle_of(std::uint32_t s) const { return {s, gen_[s]}; }
  std::uint32_t allocate_slot();
  void free_slot(std::uint32_t s);
  void add_loose(std::uint32_t s);
  void drop_loose(std::uint32_t s);
  void leave_grid(std::uint32_t s);
  void maybe_rebuild();
  void rebuild(bool fixed_too);
  void build_candidate_lists();
  void build_lists(std::size_t begin, std::size_t end, std::vector<std::uint32_t>& pool);
  void build_grid(Grid& g, std::vector<Entry>& items) const;
  static bool entry_before(const Entry& x, const Entry& y);
  static void sort_row(Entry* b, Entry* e);
  void build_fixed_cache();

  /// Pairs of moving-grid entries [begin, end) with the fixed grid and with
  /// later moving entries. emit(slot, slot) returns false to stop.
  template <class E>
  bool moving_pairs(std::size_t begin, std::size_t end, E& emit, std::uint64_t& tests) const;
  template <class E>
  bool list_pairs(std::size_t begin, std::size_t end, E& emit, std::uint64_t& tests) const;
  /// Pairs among entries of one grid (each pair once), for the fixed cache.
  template <class E>
  bool grid_pairs(const Grid& g, Home home, std::size_t begin, std::size_t end, E& emit,
                  std::uint64_t& tests) const;
  /// Pairs of loose objects with both grids and with later loose objects.
  template <class E>
  bool loose_pairs(E& emit, std::uint64_t& tests) const;
  template <class E>
  bool all_pairs(E& emit, std::uint64_t& tests) const;

  Aabb world_;
  unsigned threads_ = 1;
  double cell_factor_ = 2;  // row cell size over reach

  std::vector<Shape> shapes_;
  std::vector<std::uint64_t> user_;  // for a free slot: the next free slot
  std::vector<std::uint32_t> gen_;   // odd while alive
  std::vector<Home> home_;
  std::vector<Motion> motion_;
  std::vector<std::uint32_t> loose_pos_;  // for a loose object: its index in loose_
  std::uint32_t free_head_ = Handle::kNullIndex;
  std::size_t live_ = 0;

  std::vector<std::uint32_t> loose_;  // loose slots
  std::vector<AabbF> loose_bounds_;   // parallel to loose_
  std::vector<std::uint32_t> held_;   // removed grid objects whose slots wait for a rebuild
  bool fixed_dirty_ = false;          // the fixed set changed since the fixed grid was built
  std::size_t fixed_count_ = 0;       // objects of the fixed grid still in it
  std::size_t moving_count_ = 0;      // objects of the moving grid still in it

  Grid fixed_;
  Grid moving_;
  // Overlapping pairs within the fixed grid, stored as the handles find_pairs
  // reports: while no fixed object has left the grid since the cache was
  // built, a frame appends the whole cache as one block copy.
  std::vector<HandlePair> fixed_pairs_;
  std::vector<Entry> scratch_items_;  // rebuild input, kept to avoid reallocation

  // Candidate lists of moving objects against the fixed grid. A list holds
  // the fixed entries whose bounds overlap a "fat" box (the object's bounds
  // grown by a margin); it stays complete while the object's bounds remain
  // inside the fat box, so a slowly moving object is tested against its
  // list instead of probing the fixed grid every frame. Lists live in one
  // pool in moving-grid order, rebuilt (mostly copied) by every rebuild,
  // and are all dropped when the fixed grid is rebuilt.
  std::vector<std::uint32_t> list_pool_;                // fixed entry indices
  std::vector<std::uint32_t> list_pool_next_;           // the pool being built
  std::vector<std::vector<std::uint32_t>> list_parts_;  // per thread, its share of the new pool
  std::vector<std::uint32_t> list_begin_;               // per slot, into list_pool_
  std::vector<std::uint32_t> list_count_;               // per slot
  std::vector<std::uint32_t> list_epoch_;               // per slot: fixed-grid epoch of its list
  std::vector<AabbF> fat_;                              // per slot: the box its list covers
  std::vector<float> speed_;  // per slot: bounds displacement of the last move
  std::uint32_t epoch_ = 1;   // bumped at every fixed-grid rebuild

  /// Per-thread pair buffers of find_pairs, reused between frames.
  mutable std::mutex buffers_mutex_;
  mutable std::vector<std::vector<HandlePair>> buffers_;
};

// ---------------------------------------------------------------------------

template <class F>
bool FastGrid::Grid::scan(const AabbF& q, std::size_t first_level, double first_min_x,
                          F&& f) const {
  for (std::size_t l = first_level; l < levels.size(); ++l) {
    const Level& lv = levels[l];
    double lo_x = static_cast<double>(q.lo[0]) - lv.reach;
    if (l == first_level) lo_x = std::max(lo_x, first_min_x);
    const std::uint32_t y0 = lv.cell(static_cast<double>(q.lo[1]) - lv.reach, lv.origin_y, lv.ny);
    const std::uint32_t y1 = lv.cell(q.hi[1], lv.origin_y, lv.ny);
    const std::uint32_t z0 = lv.cell(static_cast<double>(q.lo[2]) - lv.reach, lv.origin_z, lv.nz);
    const std::uint32_t z1 = lv.cell(q.hi[2], lv.origin_z, lv.nz);
    const std::uint32_t level_begin = row_start[lv.first_row];
    const std::uint32_t level_end = row_start[lv.first_row + lv.ny * lv.nz];
    if (static_cast<std::uint64_t>(y1 - y0 + 1) * (z1 - z0 + 1) * kProbeCost >
        level_end - level_begin) {
      // A query far larger than the level's cells: probing its rows would
      // cost more than testing every entry of the level.
      for (std::uint32_t k = level_begin; k < level_end; ++k) {
        const Entry& en = entries[k];
        if (en.lo[0] <= q.hi[0] && static_cast<double>(en.lo[0]) >= lo_x && en.hi[0] >= q.lo[0] &&
            en.lo[1] <= q.hi[1] && en.hi[1] >= q.lo[1] && en.lo[2] <= q.hi[2] &&
            en.hi[2] >= q.lo[2] && !f(en))
          return false;
      }
      continue;
    }
    for (std::uint32_t y = y0; y <= y1; ++y) {
      const std::uint32_t base = lv.first_row + y * lv.nz;
      for (std::uint32_t z = z0; z <= z1; ++z) {
        const Entry* b = entries.data() + row_start[base + z];
        const Entry* e = entries.data() + row_start[base + z + 1];
        if (b == e) continue;
        const Entry* it = std::partition_point(
            b, e, [lo_x](const Entry& en) { return static_cast<double>(en.lo[0]) < lo_x; });
        for (; it != e && it->lo[0] <= q.hi[0]; ++it) {
          if (it->hi[0] >= q.lo[0] && it->lo[1] <= q.hi[1] && it->hi[1] >= q.lo[1] &&
              it->lo[2] <= q.hi[2] && it->hi[2] >= q.lo[2]) {
            if (!f(*it)) return false;
          }
        }
      }
    }
  }
  return true;
}

template <class V>
QueryCost FastGrid::query(const Shape& q, V&& visitor) const {
  QueryCost cost;
  const AabbF b = bounds_f(q);
  auto test = [&](std::uint32_t s, const Shape& shape) {
    ++cost.tests;
    if (overlaps(q, shape) && !visit(visitor, handle_of(s))) {
      cost.stopped = true;
      return false;
    }
    return true;
  };
  if (!fixed_.scan(b, 0, kNoMinX, [&](const Entry& e) {
        return home_[e.slot] != Home::fixed_grid || test(e.slot, fixed_.shape_of(e));
      }))
    return cost;
  if (!moving_.scan(b, 0, kNoMinX, [&](const Entry& e) {
        return home_[e.slot] != Home::moving_grid || test(e.slot, moving_.shape_of(e));
      }))
    return cost;
  for (std::size_t i = 0; i < loose_.size(); ++i)
    if (loose_bounds_[i].overlaps(b) && !test(loose_[i], shapes_[loose_[i]])) return cost;
  return cost;
}

template <class E>
bool FastGrid::grid_pairs(const Grid& g, Home home, std::size_t begin, std::size_t end, E& emit,
                          std::uint64_t& tests) const {
  // Each pair is reported by the entry that comes first in the order
  // (level, lower x, entry index): entries on higher levels are scanned in
  // full, entries on the same level only from the lower x onwards.
  std::size_t level = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const Entry& me = g.entries[i];
    if (home_[me.slot] != home) continue;
    const std::uint32_t row = g.entry_row[i];
    while (level + 1 < g.levels.size() && g.levels[level + 1].first_row <= row) ++level;
    const Shape& sm = g.shapes[i];
    const AabbF q{{me.lo[0], me.lo[1], me.lo[2]}, {me.hi[0], me.hi[1], me.hi[2]}};
    auto test = [&](const Entry& o) {
      if (home_[o.slot] != home) return true;
      ++tests;
      return !overlaps(sm, g.shape_of(o)) || emit(me.slot, o.slot);
    };
    const std::size_t level_end =
        level + 1 < g.levels.size() ? g.row_start[g.levels[level + 1].first_row] : g.entries.size();
    const bool go = g.scan(q, level, me.lo[0], [&](const Entry& o) {
      const std::size_t j = static_cast<std::size_t>(&o - g.entries.data());
      if (j < level_end && (o.lo[0] < me.lo[0] || (o.lo[0] == me.lo[0] && j <= i))) return true;
      return test(o);
    });
    if (!go) return false;
  }
  return true;
}

template <class E>
bool FastGrid::moving_pairs(std::size_t begin, std::size_t end, E& emit,
                            std::uint64_t& tests) const {
  return list_pairs(begin, end, emit, tests) &&
         grid_pairs(moving_, Home::moving_grid, begin, end, emit, tests);
}

template <class E>
bool FastGrid::list_pairs(std::size_t begin, std::size_t end, E& emit, std::uint64_t& tests) const {
  for (std::size_t i = begin; i < end; ++i) {
    const Entry& me = moving_.entries[i];
    if (home_[me.slot] != Home::moving_grid) continue;
    const Shape& sm = moving_.shapes[i];
    const std::uint32_t* c = list_pool_.data() + list_begin_[me.slot];
    const std::uint32_t* c_end = c + list_count_[me.slot];
    for (; c != c_end; ++c) {
      const Entry& o = fixed_.entries[*c];
      if (o.lo[0] <= me.hi[0] && o.hi[0] >= me.lo[0] && o.lo[1] <= me.hi[1] &&
          o.hi[1] >= me.lo[1] && o.lo[2] <= me.hi[2] && o.hi[2] >= me.lo[2] &&
          home_[o.slot] == Home::fixed_grid) {
        ++tests;
        if (overlaps(sm, fixed_.shapes[*c]) && !emit(me.slot, o.slot)) return false;
      }
    }
  }
  return true;
}

template <class E>
bool FastGrid::loose_pairs(E& emit, std::uint64_t& tests) const {
  for (std::size_t i = 0; i < loose_.size(); ++i) {
    const std::uint32_t s = loose_[i];
    const Shape& sh = shapes_[s];
    const AabbF& q = loose_bounds_[i];
    auto test_in = [&](const Grid& g, Home home) {
      return [&, home](const Entry& o) {
        if (home_[o.slot] != home) return true;
        ++tests;
        return !overlaps(sh, g.shape_of(o)) || emit(s, o.slot);
      };
    };
    if (!fixed_.scan(q, 0, kNoMinX, test_in(fixed_, Home::fixed_grid))) return false;
    if (!moving_.scan(q, 0, kNoMinX, test_in(moving_, Home::moving_grid))) return false;
    for (std::size_t j = i + 1; j < loose_.size(); ++j) {
      if (!loose_bounds_[j].overlaps(q)) continue;
      ++tests;
      if (overlaps(sh, shapes_[loose_[j]]) && !emit(s, loose_[j])) return false;
    }
  }
  return true;
}

template <class E>
bool FastGrid::all_pairs(E& emit, std::uint64_t& tests) const {
  for (const HandlePair& p : fixed_pairs_)
    if (home_[p.a.index] == Home::fixed_grid && home_[p.b.index] == Home::fixed_grid &&
        !emit(p.a.index, p.b.index))
      return false;
  return moving_pairs(0, moving_.entries.size(), emit, tests) && loose_pairs(emit, tests);
}

template <class V>
QueryCost FastGrid::for_each_pair(V&& visitor) const {
  QueryCost cost;
  auto emit = [&](std::uint32_t a, std::uint32_t b) {
    return visit(visitor, handle_of(a), handle_of(b));
  };
  cost.stopped = !all_pairs(emit, cost.tests);
  return cost;
}

}  // namespace broadphase
