/// \file grid_hybrid.hpp
/// `grid-hybrid`: the notes' hybrid for very uneven density (a city and an
/// empty sky): a coarse hashed grid whose occupied cells hold lists sorted
/// along x and swept, sort-and-sweep inside each cell.
///
/// Why it helps: a uniform grid is sized for one density. Sized for the
/// city, the sky costs nothing (hashed cells: no empty cell is stored or
/// visited) but large objects span many cells; sized for the sky, city cells
/// hold hundreds of objects and the grid tests all their pairs. Here cells
/// are four times the uniform grid's automatic size, so nearly every object
/// spans at most two cells per axis, and inside a crowded cell the sorted
/// list turns the all-pairs test into a sweep whose work follows the real
/// x overlaps, whatever the cell's density. The lists stay sorted under
/// motion by moving each link past the neighbours it overtook (insertion
/// sort, O(1) per move for coherent motion).
///
/// Exactness and pair uniqueness are those of grid-hashed (exact cell keys,
/// lowest shared cell); the sweep only skips links whose x interval starts
/// after the current one ends, which cannot overlap it.
#pragma once

#include <broadphase/detail/linked_grid.hpp>

namespace broadphase {

/// The options of GridHybrid (`grid-hybrid:cell=E,buckets=N`).
struct GridHybridOptions {
  /// Cell edge in world units, in [1e-300, 1e300]; 0 (default): kCoarseness
  /// times the size chosen from the world and the population, and re-chosen as it changes.
  double cell = 0;
  /// Bucket heads, rounded up to a power of two, in [1, kMaxBuckets]; 0
  /// (default): as many as objects, doubled as the population grows.
  std::size_t buckets = 0;
  /// The most buckets: 2^26 heads are 256 MB, far more than any population a
  /// handle can name needs (the automatic table holds about one bucket per
  /// object), and a larger table is a typo, not a tuning.
  static constexpr std::size_t kMaxBuckets = std::size_t{1} << 26;
  /// Throws InvalidConfig for a value out of range (detail/structure_base.hpp).
  void check() const {
    detail::check_number("grid-hybrid", "cell", cell, 1e-300, 1e300, true);
    detail::check_integer("grid-hybrid", "buckets", buckets, 0, kMaxBuckets);
  }
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static GridHybridOptions from(const OptionText& text);
};

/// A coarse hashed grid with x-sorted cell lists.
/// insert: O(length of the cell list) to find the sorted position.
/// remove: O(1). update: O(1) plus the links passed, or a re-insert when
/// the cells change. query: O(cells covered + candidates). for_each_pair:
/// O(links + x-overlapping link pairs in each cell). Memory: O(n).
/// Options: `cell=` (edge length), `buckets=`. Handles stay valid until
/// their object is removed. Const members may run concurrently; mutations
/// need exclusive access.
class GridHybrid : public detail::LinkedGrid<true, true> {
 public:
  /// Cells are this many times the uniform grids' automatic size.
  static constexpr double kCoarseness = 4;
  using Options = GridHybridOptions;
  /// Reads the deprecated Config::options map into GridHybridOptions.
  /// Throws InvalidConfig.
  explicit GridHybrid(const Config& c = {})
      : GridHybrid(without_options(c), GridHybridOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o`.
  GridHybrid(const Config& c, const GridHybridOptions& o)
      : LinkedGrid(c, "grid-hybrid", (o.check(), o.cell), o.buckets, kCoarseness) {}
};

}  // namespace broadphase
