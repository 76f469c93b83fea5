/// \file level_grid.hpp
/// The grid engine of grid-verlet (grid_verlet.hpp): a hierarchy of cell
/// grids in one flat array of 32-byte entries in cell order. Each level
/// holds the objects whose widest extent fits its reach; an object is in
/// exactly one cell of one level, the cell of its lower corner, and cells
/// along x are contiguous, so a box visits on each level one contiguous run
/// of entries per (y, z) row of cells. The grid builds itself from its
/// items (a counting sort, split over the structure's threads) and tells
/// its owner where each item went, so the owner can place what goes with
/// it (the shape copies, grid-verlet's mover records).
#pragma once

#include <algorithm>
#include <broadphase/detail/work_shares.hpp>
#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace broadphase::detail {

/// Prefetches the cache line at `p` (a hint; no effect where unsupported).
/// Callers compute `p` only inside an array they hold: an empty vector's
/// data() may be null, and arithmetic on it is undefined.
inline void prefetch(const void* p) {
#if defined(__GNUC__) || defined(__clang__)
  __builtin_prefetch(p);
#else
  (void)p;
#endif
}

/// The widest extent of a float box (infinite for unbounded objects).
inline double extent_of(const float lo[3], const float hi[3]) {
  double e = 0;
  for (int a = 0; a < 3; ++a)
    e = std::max(e, static_cast<double>(hi[a]) - static_cast<double>(lo[a]));
  return e;
}

/// One object in a grid: its float bounds, slot and generation. A dead
/// entry (its object left the grid) has NaN bounds: no comparison passes.
struct GridEntry {
  float lo[3];
  float hi[3];
  std::uint32_t slot;
  std::uint32_t gen;
  bool dead() const { return lo[0] != lo[0]; }
  Handle handle() const { return {slot, gen}; }
  /// All six comparisons, without a branch between them: in a scan about
  /// half the entries pass the first one, which a branch mispredicts.
  bool overlaps(const AabbF& q) const {
    return (lo[0] <= q.hi[0]) & (hi[0] >= q.lo[0]) & (lo[1] <= q.hi[1]) & (hi[1] >= q.lo[1]) &
           (lo[2] <= q.hi[2]) & (hi[2] >= q.lo[2]);
  }
  AabbF box() const { return {{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}}; }
};
static_assert(sizeof(GridEntry) == 32, "grid entries are packed for the cell scans");

/// One level of a grid: objects whose widest extent is at most
/// 0.98 * reach, in n[0] * n[1] * n[2] cells (side >= reach).
struct GridLevel {
  double reach = 0;
  double inv_cell = 0;  // 0: a single cell (infinite reach)
  double origin[3] = {0, 0, 0};
  std::uint32_t n[3] = {1, 1, 1};
  std::uint32_t first_cell = 0;
  /// The union of the level's entries' boxes when built (min of the lower
  /// corners, max of the upper).
  AabbF bound{{0, 0, 0}, {0, 0, 0}};

  std::uint32_t cell(double v, int a) const {
    const double t = (v - origin[a]) * inv_cell;
    if (!(t >= 0)) return 0;  // also NaN from an infinite reach
    if (t >= static_cast<double>(n[a] - 1)) return n[a] - 1;
    return static_cast<std::uint32_t>(t);
  }
  std::uint32_t cells() const { return n[0] * n[1] * n[2]; }
  /// The cell of a lower corner.
  std::uint32_t cell_of(const float lo[3]) const {
    return first_cell + (cell(lo[1], 1) * n[2] + cell(lo[2], 2)) * n[0] + cell(lo[0], 0);
  }
};

/// A grid's copy of a shape, padded to one cache line: most 56-byte
/// records would span two lines, and a scan that reads the shape of a hit
/// would then wait for two misses instead of one.
struct alignas(64) LineShape : Shape {
  LineShape() = default;
  LineShape(const Shape& s) : Shape(s) {}  // NOLINT(google-explicit-constructor)
};

/// What a grid's builds are made for: the world hint (cells cover the
/// objects inside it), a cell's side over its level's reach, and the cells
/// per object at most on each level.
struct LevelGridSpec {
  Aabb world;
  double cell_factor = 1;
  double cells_per_object = 2;
};

/// The levels, cell starts, entries and shape copies of one grid.
struct LevelGrid {
  /// A cell probe (two index loads) costs about as much as testing this many
  /// entries.
  static constexpr std::uint64_t kProbeCost = 2;
  /// "No lower bound on x" for scan's first level.
  static constexpr double kNoMinX = -std::numeric_limits<double>::infinity();
  /// Levels halve in reach from the largest finite extent down; twenty
  /// finite levels span six decades of sizes (smaller objects share the
  /// lowest level), and one more level of infinite reach takes objects
  /// whose float bounds are unbounded (centres beyond the float range).
  /// Factor 2 keeps an object's reach within twice its extent, so a scan
  /// window stays tight.
  static constexpr int kFiniteLevels = 20;
  static constexpr int kLevelSlots = kFiniteLevels + 1;
  /// An object goes to a level only when its widest extent is at most this
  /// fraction of the reach: the 2% margin absorbs the rounding of the cell
  /// arithmetic, so the cell bounds of a scan stay conservative.
  static constexpr double kFill = 0.98;
  /// A level holding less than 1/kSparseLevel of a grid's objects is
  /// merged into the next larger one.
  static constexpr std::size_t kSparseLevel = 4;

  /// One share's totals in a build, on cache lines of its own (each share
  /// writes its own).
  struct alignas(64) ShareTotals {
    double max_e = 0;
    std::uint32_t count[kLevelSlots] = {};
    float span_lo[kLevelSlots][3] = {}, span_hi[kLevelSlots][3] = {};
    float top[kLevelSlots][3] = {};  // upper corners' maxima
    std::uint32_t first_cell = 0;    // of the cells the share fills in the scatter
  };
  /// A build's scratch, kept by the caller between builds (one for grids
  /// rebuilt every frame, temporaries for grids rebuilt rarely).
  struct Scratch {
    std::vector<std::uint32_t> tag;  // per item: its level, then its cell
    std::vector<std::uint32_t> at;   // per item: its entry
    std::vector<ShareTotals> shares;
    std::size_t memory_bytes() const {
      return (tag.capacity() + at.capacity()) * 4 + shares.capacity() * sizeof(ShareTotals);
    }
  };

  std::vector<GridLevel> levels;
  /// True while every entry's box lies in its level's `bound` (build sets
  /// it): a scan then skips a level whose bound its query misses. A caller
  /// that writes an entry's box in place, not through a build, clears it.
  /// (A level's cells cover its lower corners, and the cell function clamps
  /// coordinates beyond them to the border cells: a query beyond a flat
  /// level, a flyer above a city's buildings, scanned that level's border
  /// row for every entry of its x-z window: grid-verlet's renewals on the
  /// city spent 18 µs each there.)
  bool bounded = false;
  std::vector<std::uint32_t> cell_start{0};  // per cell, into entries; one extra at the end
  std::vector<GridEntry> entries;
  // Per entry, a copy of its object's shape: the exact tests of a scan
  // read this array in the grid's spatial order instead of the slot array
  // in insertion order (a cache miss per test on large scenes).
  std::vector<LineShape> shapes;

  /// Refills the grid with `items` (their float boxes, slots and
  /// generations) in cell order: each goes to the level whose reach covers
  /// its widest extent, the cell of its lower corner; inside a cell the
  /// items keep their order (a stable counting sort), so the result
  /// depends on the items and `spec` alone, not on the thread count. The
  /// passes are split over `shares`. The shape copies are sized but not
  /// filled: returns, per item, the entry it went to (valid until the next
  /// build with `scratch`), for the caller to place its shape and whatever
  /// else goes with it.
  std::span<const std::uint32_t> build(std::span<const GridEntry> items, const LevelGridSpec& spec,
                                       const WorkShares& shares, Scratch& scratch);

  std::size_t level_end(std::size_t l) const {
    return cell_start[levels[l].first_cell + levels[l].cells()];
  }
  /// Calls f(entry index) for every entry whose float box overlaps `q`, on
  /// levels from `first_level` (on that level only in cells from the one
  /// of `first_min_x` along x); stops when f returns false.
  template <class F>
  bool scan(const AabbF& q, std::size_t first_level, double first_min_x, F&& f) const;
  /// The same on level `l` alone, in cells from the one of `min_x` along x.
  template <class F>
  bool scan_level(const AabbF& q, std::size_t l, double min_x, F&& f) const;
  std::size_t memory_bytes() const {
    return levels.capacity() * sizeof(GridLevel) + cell_start.capacity() * 4 +
           entries.capacity() * sizeof(GridEntry) + shapes.capacity() * sizeof(LineShape);
  }
};

template <class F>
bool LevelGrid::scan_level(const AabbF& q, std::size_t l, double min_x, F&& f) const {
  const GridLevel& lv = levels[l];
  if (bounded && !lv.bound.overlaps(q)) return true;
  const double lo_x = std::max(static_cast<double>(q.lo[0]) - lv.reach, min_x);
  const std::uint32_t x0 = lv.cell(lo_x, 0);
  const std::uint32_t x1 = lv.cell(q.hi[0], 0);
  const std::uint32_t y0 = lv.cell(static_cast<double>(q.lo[1]) - lv.reach, 1);
  const std::uint32_t y1 = lv.cell(q.hi[1], 1);
  const std::uint32_t z0 = lv.cell(static_cast<double>(q.lo[2]) - lv.reach, 2);
  const std::uint32_t z1 = lv.cell(q.hi[2], 2);
  const std::uint32_t level_begin = cell_start[lv.first_cell];
  const std::uint32_t level_end = cell_start[lv.first_cell + lv.cells()];
  if (static_cast<std::uint64_t>(y1 - y0 + 1) * (z1 - z0 + 1) * kProbeCost >
      level_end - level_begin) {
    // A query far larger than the level's cells: visiting its rows would
    // cost more than testing every entry of the level.
    for (std::uint32_t k = level_begin; k < level_end; ++k)
      if (entries[k].overlaps(q) && !f(k)) return false;
    return true;
  }
  // Rows are taken in batches: first every row's range (the loads do not
  // wait on each other) and a prefetch of its first entries, then the
  // scans, so that the rows' cache misses overlap instead of following one
  // another.
  constexpr unsigned kBatch = 16;
  std::uint32_t row_begin[kBatch], row_end[kBatch];
  unsigned rows = 0;
  auto scan_rows = [&] {
    for (unsigned r = 0; r < rows; ++r)
      for (std::uint32_t k = row_begin[r]; k < row_end[r]; ++k)
        if (entries[k].overlaps(q) && !f(k)) return false;
    rows = 0;
    return true;
  };
  for (std::uint32_t y = y0; y <= y1; ++y) {
    for (std::uint32_t z = z0; z <= z1; ++z) {
      const std::uint32_t base = lv.first_cell + (y * lv.n[2] + z) * lv.n[0];
      row_begin[rows] = cell_start[base + x0];
      row_end[rows] = cell_start[base + x1 + 1];
      prefetch(entries.data() + row_begin[rows]);
      if (++rows == kBatch && !scan_rows()) return false;
    }
  }
  return scan_rows();
}

template <class F>
bool LevelGrid::scan(const AabbF& q, std::size_t first_level, double first_min_x, F&& f) const {
  for (std::size_t l = first_level; l < levels.size(); ++l)
    if (!scan_level(q, l, l == first_level ? first_min_x : kNoMinX, f)) return false;
  return true;
}

}  // namespace broadphase::detail
