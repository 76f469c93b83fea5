/// \file hgrid.hpp
/// `hgrid`: the lecture notes' hierarchical grid (not the study's
/// hgrid-paper). Level k has cells of edge 2^k; an object lives in exactly
/// one cell of exactly one level, the finest whose cell is at least its
/// extent (largest side of its bounds), in the cell holding the centre
/// of its bounds. All levels share one hash table keyed by (level,
/// cell); a per-level object count lets queries skip empty levels. There is
/// no world box and no size limit: levels are powers of two of the whole
/// double range, so objects from 1e-3 to 1e4 (or beyond) share one
/// structure without re-gridding.
///
/// Pairs: each object looks at its own level and the coarser ones only, so
/// a pair of different levels is found once, by its finer object; a pair on
/// one level is kept only when the lower slot looks at the higher one.
///
/// Exactness: an object b at level L with cell edge c has extent <= c, so
/// when b overlaps a, b's centre lies in [a.lo - c/2, a.hi + c/2]; a scans
/// the cells of that box at level L (widened by a margin larger than the
/// rounding of the centre and of the additions): at most 3 x 3 x 3 cells at
/// its own level, 2 x 2 x 2 on coarser ones. A level is never finer
/// than 2^-20 of the object's distance from the origin, so cell coordinates
/// stay far inside int32 (at 1e7 from the origin cells are >= 2^4).
/// Objects whose bounds are not finite in float go to an overflow list
/// tested against everything.
#pragma once

#include <broadphase/config_error.hpp>
#include <broadphase/detail/grid_common.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstdint>
#include <vector>

namespace broadphase {

/// HGrid takes no options; the struct is where they would go.
struct HGridOptions {
  /// Nothing to check.
  void check() const {}
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static HGridOptions from(const OptionText& text);
};

/// A hierarchical grid of power-of-two levels in one hash table.
/// insert, remove, update: O(1) expected (a hash insert or erase; update is
/// free when the object keeps its cell and level). query: O(occupied levels
/// x cells scanned per level + candidates). for_each_pair: O(n x occupied
/// coarser levels + candidates). Memory: O(n). No options. Handles stay
/// valid until their object is removed. Const members may run concurrently;
/// mutations need exclusive access.
class HGrid : public detail::StoreBase<HGrid> {
 public:
  using Options = HGridOptions;
  /// Reads the deprecated Config::options (none accepted). Throws InvalidConfig.
  explicit HGrid(const Config& c = {}) : HGrid(without_options(c), HGridOptions::from(c.options)) {}
  /// Checks `c` (check_config). Throws InvalidConfig.
  HGrid(const Config& c, const HGridOptions& o);

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves or resizes an object. Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object overlapping `q`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    const AabbF qb = bounds_f(q);
    for (int level : levels_) {
      const bool go = scan_level(qb, level, [&](std::uint32_t b) {
        return detail::test_query(store_, box_.data(), q, qb, b, cost, visitor);
      });
      if (!go) return cost;
    }
    for (std::uint32_t b : overflow_)
      if (!detail::test_query(store_, box_.data(), q, qb, b, cost, visitor)) return cost;
    return cost;
  }

  /// Casts a ray (HasRayCast): the overflowing objects, then each occupied
  /// level coarse to fine: a march through the level's blocks (cells of
  /// 8 x 8 x 8 of its own), and within each block that holds an object of
  /// the level a march through the level's cells where the ray crosses the
  /// block (detail/ray_walk.hpp), grown by the half edge by which a level's
  /// objects may reach beyond the cell of their centre; each object tested
  /// once. Per level O(blocks passed + cells passed in occupied blocks +
  /// candidates), and never more than about a scan of the objects.
  /// Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    auto box_of = [&](std::uint32_t b) -> const AabbF& { return box_[b]; };
    return detail::ray_grid_cast(store_, r, visitor, overflow_, box_of,
                                 [&](auto& cast, detail::RaySlots& tested) {
                                   for (auto it = levels_.rbegin(); it != levels_.rend(); ++it)
                                     if (!cast_level(cast, tested, *it)) return;
                                 });
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair once.
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    QueryCost cost;
    const AabbF* box = box_.data();
    const std::uint32_t slots = store_.slot_count();
    for (std::uint32_t a = 0; a < slots; ++a) {
      if (!store_.slots().alive(a) || where_[a] != detail::kNone) continue;
      const int own = level_[a];
      for (auto it = std::lower_bound(levels_.begin(), levels_.end(), own); it != levels_.end();
           ++it) {
        const bool same = *it == own;
        const bool go = scan_level(box[a], *it, [&](std::uint32_t b) {
          if (same && b <= a) return true;
          return detail::test_pair(store_, box, a, b, cost, visitor);
        });
        if (!go) return cost;
      }
    }
    for (std::size_t p = 0; p < overflow_.size(); ++p) {
      const std::uint32_t o = overflow_[p];
      for (std::uint32_t b = 0; b < slots; ++b) {
        if (!store_.slots().alive(b) || (where_[b] != detail::kNone && where_[b] <= p)) continue;
        if (!detail::test_pair(store_, box, o, b, cost, visitor)) return cost;
      }
    }
    return cost;
  }

  /// Bytes held: store, per-object arrays, the cell table, the level list.
  std::size_t memory_bytes() const;
  /// The occupied levels (cell edge 2^level), finest first.
  const std::vector<int>& levels() const { return levels_; }
  /// The level of a live object, or a value above 1023 for an overflowing one.
  int level_of(Handle h) const;

  /// Checks levels, cells, the hash table, the lists and the counts.
  void validate() const;
  /// Reports every occupied cell: its box, its level k (edge 2^k), the objects
  /// whose centre it holds (an object may reach half an edge beyond). Overflow
  /// objects are in no cell. O(cells).
  void visit_cells(CellVisitor visitor) const;

  /// The finest level (cells of 2^-100).
  static constexpr int kMinLevel = -100;
  /// The coarsest level; larger or non-finite objects overflow.
  static constexpr int kMaxLevel = 1000;

 private:
  struct Cell {
    std::int32_t level;
    detail::CellKey key;
    std::uint32_t head;  // first object, kNone for an empty slot of the table
  };

  static double edge(int level) { return std::ldexp(1.0, level); }
  static std::int32_t coord(double x, int level) {
    return detail::clamp_floor<std::int32_t>(std::ldexp(x, -level), -0x1p30, 0x1p30);
  }
  std::size_t find(int level, const detail::CellKey& k) const {
    const std::size_t mask = table_.size() - 1;
    for (std::size_t p = detail::hash_cell(k, static_cast<std::uint32_t>(level)) & mask;;
         p = (p + 1) & mask) {
      const Cell& c = table_[p];
      if (c.head == detail::kNone || (c.level == level && c.key == k)) return p;
    }
  }

  // Calls f(b) for every object b at `level` whose centre lies in the box a
  // level-`level` object overlapping `qb` must have it in.
  template <class F>
  bool scan_level(const AabbF& qb, int level, F&& f) const {
    const double c = edge(level);
    detail::CellRange r;
    for (int a = 0; a < 3; ++a) {
      const double lo = qb.lo[a], hi = qb.hi[a];
      const double slack = c * (0.5 + 0x1p-20);
      r.lo[a] = coord(lo - (slack + std::fabs(lo) * 0x1p-50), level);
      r.hi[a] = coord(hi + (slack + std::fabs(hi) * 0x1p-50), level);
    }
    if (r.cells() > 4.0 * static_cast<double>(occupancy(level)) + 8) {
      // Scanning more cells than the level has objects: walk the objects.
      for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
        if (store_.slots().alive(b) && where_[b] == detail::kNone && level_[b] == level &&
            r.contains(cell_[b]) && !f(b))
          return false;
      return true;
    }
    detail::CellKey k;
    for (k.c[2] = r.lo[2]; k.c[2] <= r.hi[2]; ++k.c[2])
      for (k.c[1] = r.lo[1]; k.c[1] <= r.hi[1]; ++k.c[1])
        for (k.c[0] = r.lo[0]; k.c[0] <= r.hi[0]; ++k.c[0]) {
          const Cell& cell = table_[find(level, k)];
          for (std::uint32_t b = cell.head; b != detail::kNone; b = next_[b])
            if (!f(b)) return false;
        }
    return true;
  }

  // A level's blocks: cubes of 2^kBlockShift cells per axis (block_of),
  // kept in the cell table under the level + kBlockTag with their object
  // count in `head`. Why: a random ray at 10^5 spheres of radius 0.5-5
  // (scaled-even) passes thousands of a fine level's cells, nearly all
  // empty, and the march through them (its hash probes) was nearly all of
  // the cast's time (perf). Measured in one lab run (2-core VM, shared):
  // 940 rays/s marching every level's cells; 15 400 marching the blocks
  // and a level's cells only inside occupied blocks, levels coarse to fine
  // (kept); 2 500 fine to coarse (the coarse levels' large objects clip the
  // ray early, so the fine levels march a short ray); 12 700 all levels at
  // once, front to back in stretches of a coarse block.
  static constexpr int kBlockShift = 3;
  static constexpr int kBlockTag = 4096;

  // One level of a cast (see cast_ray); false when the cast stopped.
  template <class Cast>
  bool cast_level(Cast& cast, detail::RaySlots& tested, int level) const {
    // A level's scan reads every slot (there is no list per level), so the
    // march may cost as much before it gives up.
    const double budget = 2.0 * static_cast<double>(store_.size()) + 64;
    double probes = 0;  // cells and blocks visited
    bool over = false;  // out of budget inside a block
    auto test = [&](std::uint32_t b) { return !tested.insert(b) || cast.test(b, box_[b]); };
    const double scale = std::ldexp(1.0, -level);
    const double reach = edge(level) * (0.5 + 0x1p-20);  // as scan_level's slack
    const detail::RayGridLevel cells = ray_level_of(level, reach, 0x1p30);
    const detail::RayGridLevel blocks = ray_level_of(level + kBlockShift, reach, 0x1p27);
    const detail::RayGridMarch inner(
        cells, [&](double x, int) { return coord_scaled(x, scale); },
        [&](const detail::CellKey& k) {
          probes += 1;
          for (std::uint32_t b = table_[find(level, k)].head; b != detail::kNone; b = next_[b])
            if (!test(b)) return false;
          return true;
        });
    using Outcome = detail::RayMarchOutcome;
    const detail::RayGridMarch outer(
        blocks, [&](double x, int) { return block_of(coord_scaled(x, scale)); },
        [&](const detail::CellKey& k) {
          probes += 1;
          if (table_[find(level + kBlockTag, k)].head == detail::kNone) return true;
          // The centres of the block's objects lie in its cells: the objects
          // within reach of them, and one cell more against the rounding of
          // the cell coordinate near zero.
          const double e = edge(level + kBlockShift);
          const double grow = reach + edge(level);
          Aabb within;
          for (int a = 0; a < 3; ++a) {
            within.lo[a] = k.c[a] * e - grow;
            within.hi[a] = (k.c[a] + 1.0) * e + grow;
          }
          switch (inner.march_within(cast, budget - probes, &within)) {
            case Outcome::finished:
              return true;
            case Outcome::stopped:
              return false;
            case Outcome::scan:
              over = true;
              return false;
          }
          return false;
        });
    switch (outer.march(cast, budget, &occupied_)) {
      case Outcome::finished:
        return true;
      case Outcome::stopped:
        if (!over) return false;
        break;
      case Outcome::scan:
        break;
    }
    for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
      if (store_.slots().alive(b) && where_[b] == detail::kNone && level_[b] == level &&
          !tested.contains(b) && !cast.test(b, box_[b]))
        return false;
    return true;
  }
  // The block of a cell coordinate: floor division by 2^kBlockShift, so
  // that a block holds exactly the cells it covers, clamped or not.
  static std::int32_t block_of(std::int32_t cell) { return cell >> kBlockShift; }
  static detail::CellKey block_of(const detail::CellKey& k) {
    return {{block_of(k.c[0]), block_of(k.c[1]), block_of(k.c[2])}};
  }
  static detail::RayGridLevel ray_level_of(int level, double reach, double limit) {
    detail::RayGridLevel l;
    l.origin = {0, 0, 0};
    l.cell = edge(level);
    for (int a = 0; a < 3; ++a) {
      l.index_lo[a] = -limit;
      l.index_hi[a] = limit;
    }
    l.reach = reach;
    return l;
  }
  // coord(x, level) with scale = 2^-level: the product is exact wherever
  // ldexp is (both round once), without ldexp's call in the march.
  static std::int32_t coord_scaled(double x, double scale) {
    return detail::clamp_floor<std::int32_t>(x * scale, -0x1p30, 0x1p30);
  }

  std::uint32_t occupancy(int level) const { return count_[level - kMinLevel]; }
  void place(std::uint32_t i);
  void lift(std::uint32_t i);
  // Counts object i in its block (+1 or -1), adding or erasing the block.
  void count_in_block(std::uint32_t i, int change);
  void erase_cell(std::size_t p);
  void grow_table();
  static int level_for(const AabbF& b);
  // The cell of an object's bounds' centre at `level`.
  static detail::CellKey cell_for(const AabbF& b, int level) {
    detail::CellKey k;
    for (int a = 0; a < 3; ++a)
      k.c[a] = coord(0.5 * (static_cast<double>(b.lo[a]) + static_cast<double>(b.hi[a])), level);
    return k;
  }

  std::vector<AabbF> box_;
  std::vector<std::int32_t> level_;
  std::vector<detail::CellKey> cell_;
  std::vector<std::uint32_t> next_, prev_;
  std::vector<std::uint32_t> where_;  // position in overflow_, or kNone
  std::vector<std::uint32_t> overflow_;
  detail::OccupiedBox occupied_;  // holds every box placed (rays)
  std::vector<Cell> table_;       // open addressing, linear probing; cells and blocks
  std::size_t cells_used_ = 0;
  std::vector<std::uint32_t> count_;  // objects per level
  std::vector<int> levels_;           // occupied levels, ascending
};

}  // namespace broadphase
