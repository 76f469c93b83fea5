/// \file grid_common.hpp
/// What the uniform grids share: the monotone map from coordinates to cell
/// coordinates, cell keys and their hash, the "lowest shared cell" rule that
/// reports each pair once, the candidate test, and the automatic re-gridding
/// trigger. Internal: the public grid headers include it.
///
/// Why a monotone map is enough for exactness: every grid computes an
/// object's cell range from its conservative float bounds with the same
/// non-decreasing function (subtract, multiply by a positive constant,
/// clamp, floor: each rounds monotonically). When two boxes overlap on an
/// axis (a.lo <= b.hi and b.lo <= a.hi), applying a non-decreasing function
/// keeps both inequalities, so their cell ranges share a cell, however far
/// from the origin they are and however the clamp folds them into border
/// cells.
#pragma once

#include <algorithm>
#include <broadphase/cell_size.hpp>
#include <broadphase/detail/clamp_index.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/handle.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace broadphase::detail {

inline constexpr std::uint32_t kNone = 0xffffffffu;

/// Takes object `i` off an overflow list: `list` holds the objects in no
/// order, `where[o]` is o's position in it (kNone when absent). The last
/// object takes i's place; O(1). `i` must be on the list.
inline void leave_list(std::vector<std::uint32_t>& list, std::vector<std::uint32_t>& where,
                       std::uint32_t i) {
  const std::uint32_t p = where[i];
  list[p] = list.back();
  where[list[p]] = p;
  list.pop_back();
  where[i] = kNone;
}

/// Integer coordinates of one cell.
struct CellKey {
  std::int32_t c[3];
  friend bool operator==(const CellKey&, const CellKey&) = default;
};

/// A well-mixed 64-bit hash of a cell key (and a level, for hierarchies).
inline std::uint64_t hash_cell(const CellKey& k, std::uint32_t level = 0) {
  std::uint64_t h = static_cast<std::uint32_t>(k.c[0]) * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<std::uint32_t>(k.c[1]) * 0xC2B2AE3D27D4EB4Full;
  h ^= static_cast<std::uint32_t>(k.c[2]) * 0x165667B19E3779F9ull;
  h ^= level * 0xD6E8FEB86659FD93ull;
  h ^= h >> 32;
  h *= 0xD6E8FEB86659FD93ull;
  h ^= h >> 29;
  return h;
}

/// The closed range of cells an object's bounds cover.
struct CellRange {
  std::int32_t lo[3] = {0, 0, 0};
  std::int32_t hi[3] = {-1, -1, -1};

  std::int64_t span(int a) const { return std::int64_t{hi[a]} - lo[a] + 1; }
  /// Number of cells covered, saturating far above any real grid.
  double cells() const {
    return static_cast<double>(span(0)) * static_cast<double>(span(1)) *
           static_cast<double>(span(2));
  }
  bool contains(const CellKey& k) const {
    return lo[0] <= k.c[0] && k.c[0] <= hi[0] && lo[1] <= k.c[1] && k.c[1] <= hi[1] &&
           lo[2] <= k.c[2] && k.c[2] <= hi[2];
  }
  friend bool operator==(const CellRange&, const CellRange&) = default;
};

/// The axes on which cell `k` is not the first cell of range `r`, as bits.
/// Two ranges that both contain `k` report their pair in `k` only when
/// their masks share no bit: then `k` is the lowest corner of the ranges'
/// intersection, which exists exactly once per pair.
inline unsigned offset_mask(const CellRange& r, const CellKey& k) {
  return (k.c[0] != r.lo[0] ? 1u : 0u) | (k.c[1] != r.lo[1] ? 2u : 0u) |
         (k.c[2] != r.lo[2] ? 4u : 0u);
}

/// The cell of an object that spans at most two cells per axis, given the
/// object's range and which axes are at the second cell (bits of `k`).
inline CellKey key_of(const CellRange& r, unsigned k) {
  return {{r.lo[0] + static_cast<std::int32_t>(k & 1u),
           r.lo[1] + static_cast<std::int32_t>((k >> 1) & 1u),
           r.lo[2] + static_cast<std::int32_t>((k >> 2) & 1u)}};
}

/// The bits k (0..7) naming the cells of a range that spans at most two
/// cells per axis; 0 when it spans more (the object overflows).
inline unsigned link_mask(const CellRange& r) {
  if (r.span(0) > 2 || r.span(1) > 2 || r.span(2) > 2) return 0;
  unsigned m = 0;
  for (unsigned k = 0; k < 8; ++k)
    if (((k & 1u) == 0 || r.span(0) == 2) && ((k & 2u) == 0 || r.span(1) == 2) &&
        ((k & 4u) == 0 || r.span(2) == 2))
      m |= 1u << k;
  return m;
}

/// Maps world coordinates to cell coordinates with a non-decreasing
/// function. Unbounded maps clamp to +-2^30 cells (far objects share border
/// cells: slower, still exact); bounded maps clamp to [0, n-1] per axis.
///
/// Defined for every double, infinite float bounds included: the origin is
/// made finite and the inverse cell edge finite and positive (an infinite
/// cell, from an automatic size that overflowed, or a subnormal one whose
/// inverse is infinite, would give 0 * inf = NaN), so `(x - origin) * inv`
/// is never NaN and is clamped before it becomes an integer.
class CellMap {
 public:
  CellMap() = default;
  /// An unbounded grid of cells of edge `cell` with a corner at `origin`.
  CellMap(const Vec3& origin, double cell)
      : origin_(finite_origin(origin)), cell_(cell), inv_(safe_inverse(cell)) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = -0x1p30;
      hi_[a] = 0x1p30;
    }
  }
  /// A bounded grid of n[a] cells per axis starting at `origin`.
  CellMap(const Vec3& origin, double cell, const std::int32_t (&n)[3])
      : origin_(finite_origin(origin)), cell_(cell), inv_(safe_inverse(cell)) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = 0;
      hi_[a] = n[a] - 1;
    }
  }

  std::int32_t coord(double x, int a) const {
    return clamp_floor<std::int32_t>((x - origin_[a]) * inv_, lo_[a], hi_[a]);
  }
  /// 1 / cell, made finite and positive for every cell (NaN, zero, negative,
  /// subnormal or infinite ones included).
  static double safe_inverse(double cell) {
    const double inv = 1.0 / cell;
    if (!(inv > 0)) return std::numeric_limits<double>::denorm_min();
    if (!(inv <= std::numeric_limits<double>::max())) return std::numeric_limits<double>::max();
    return inv;
  }
  CellRange range(const AabbF& b) const {
    CellRange r;
    for (int a = 0; a < 3; ++a) {
      r.lo[a] = coord(b.lo[a], a);
      r.hi[a] = coord(b.hi[a], a);
    }
    return r;
  }
  double cell() const { return cell_; }
  /// The corner of cell (0, 0, 0), and the lowest and highest cell
  /// coordinate of axis `a` (the clamp), for the ray march.
  const Vec3& origin() const { return origin_; }
  double index_lo(int a) const { return lo_[a]; }
  double index_hi(int a) const { return hi_[a]; }
  /// The box of cell `k` (for pictures: border cells of a bounded map also
  /// hold what the clamp folds into them).
  Aabb box(const CellKey& k) const {
    Aabb b;
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = origin_[a] + k.c[a] * cell_;
      b.hi[a] = origin_[a] + (k.c[a] + 1.0) * cell_;
    }
    return b;
  }

 private:
  static Vec3 finite_origin(const Vec3& o) {
    return {std::isfinite(o.x) ? o.x : 0, std::isfinite(o.y) ? o.y : 0,
            std::isfinite(o.z) ? o.z : 0};
  }

  Vec3 origin_;
  double cell_ = 1;
  double inv_ = 1;
  double lo_[3] = {0, 0, 0};
  double hi_[3] = {0, 0, 0};
};

/// Tests one candidate pair: float boxes first, then the filters (admits,
/// structure_base.hpp), then the exact predicate. Returns false when the
/// visitor asked to stop.
template <class V>
inline bool test_pair(const ObjectStore& store, const AabbF* box, std::uint32_t a, std::uint32_t b,
                      QueryCost& cost, V& visitor) {
  if (!box[a].overlaps(box[b]) || !admits(visitor, a, b)) return true;
  ++cost.tests;
  if (!overlaps(store.shape(a), store.shape(b))) return true;
  if (visit(visitor, store.handle(a), store.handle(b))) return true;
  cost.stopped = true;
  return false;
}

/// Tests one candidate of a query shape. Returns false when the visitor
/// asked to stop.
template <class V>
inline bool test_query(const ObjectStore& store, const AabbF* box, const Shape& q,
                       const AabbF& qbox, std::uint32_t b, QueryCost& cost, V& visitor) {
  if (!qbox.overlaps(box[b])) return true;
  ++cost.tests;
  if (!overlaps(q, store.shape(b))) return true;
  if (visit(visitor, store.handle(b))) return true;
  cost.stopped = true;
  return false;
}

/// The automatic cell size of the objects now in `store` (boxes in `box`).
inline double auto_cell_size(const ObjectStore& store, const std::vector<AabbF>& box,
                             const CellSizeRule& rule = {}) {
  std::vector<double> extents;
  extents.reserve(store.size());
  Aabb centres{{1, 1, 1}, {0, 0, 0}};
  bool first = true;
  for (std::uint32_t i = 0; i < store.slot_count(); ++i) {
    if (!store.slots().alive(i)) continue;
    const AabbF& b = box[i];
    double e = 0;
    for (int a = 0; a < 3; ++a)
      e = std::max(e, static_cast<double>(b.hi[a]) - static_cast<double>(b.lo[a]));
    if (std::isfinite(e)) extents.push_back(e);
    const Vec3& c = store.shape(i).center;
    const Aabb p{c, c};
    centres = first ? p : centres.merged(p);
    first = false;
  }
  if (first) return 1.0;
  return choose_cell_size(extents, centres, rule);
}

/// When a grid with an automatic cell size re-grids: each time the
/// population doubles, or falls to a quarter, of what it was at the last
/// choice. Amortised O(1) per insert or remove.
struct RegridTrigger {
  bool forced = false;        ///< the user gave `cell=`: never re-grid
  std::size_t chosen_at = 0;  ///< object count at the last choice

  bool due(std::size_t n) const {
    if (forced) return false;
    return n >= std::max<std::size_t>(2 * chosen_at, chosen_at + 32) ||
           (chosen_at >= 128 && 4 * n <= chosen_at);
  }
};

/// The initial cell edge of an empty grid: the mean spacing of the expected
/// objects in the world box (64 objects when nothing is expected).
inline double initial_cell_size(const Config& c) {
  const Aabb& w = c.world;
  const double n = static_cast<double>(std::max<std::size_t>(c.expected_objects, 64));
  // Per axis first (the cube root of each width), so that a world whose
  // width or volume overflows a double still gets its mean spacing.
  double cell = 2 / std::cbrt(n);
  for (int a = 0; a < 3; ++a) cell *= std::cbrt(width_over(w.lo[a], w.hi[a], 2));
  return cell > 0 && std::isfinite(cell) ? cell : 1.0;
}

/// How many cells of edge `cell` cover [lo, hi], in [1, max]: never NaN
/// and never beyond `max`, whatever the width (it may overflow) or the cell
/// (it may be infinite or subnormal).
inline std::int32_t cells_across(double lo, double hi, double cell, double max) {
  const double width = hi - lo;
  const double want = std::ceil(std::isfinite(width) ? width / cell : hi / cell - lo / cell);
  return clamp_floor<std::int32_t>(want, 1, max);
}

}  // namespace broadphase::detail
