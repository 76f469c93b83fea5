/// \file grid_hashed.hpp
/// `grid-hashed`: the linked grid of grid-dense (detail/linked_grid.hpp) with no memory of its own:
/// cells hash into a table of buckets, so the world is unbounded and memory
/// is O(n) whatever the world's volume.
///
/// Exactness under bucket collisions: a bucket's list may hold links of
/// several cells. Every link's exact cell is recomputed from its object's
/// cell range and the link's number (no key needs storing), and only links
/// of the same cell are paired, so collisions cost time, never a wrong or
/// duplicated pair.
#pragma once

#include <broadphase/detail/linked_grid.hpp>

namespace broadphase {

/// The options of GridHashed (`grid-hashed:cell=E,buckets=N`).
struct GridHashedOptions {
  /// Cell edge in world units, in [1e-300, 1e300]; 0 (default): chosen from
  /// the world and the population, and re-chosen as it changes.
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
    detail::check_number("grid-hashed", "cell", cell, 1e-300, 1e300, true);
    detail::check_integer("grid-hashed", "buckets", buckets, 0, kMaxBuckets);
  }
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static GridHashedOptions from(const OptionText& text);
};

/// A hashed uniform grid. insert, remove, update: O(1) amortised (the table
/// doubles when it holds more than two links per bucket, unless `buckets=`
/// is given; the cell size is re-chosen when the population doubles or
/// quarters, unless `cell=` is given). query: O(cells covered +
/// candidates). for_each_pair: O(n + candidate pairs). Memory: O(n).
/// Options: `cell=` (edge length), `buckets=` (fixed table size, rounded up
/// to a power of two). Handles stay valid until their object is removed.
/// Const members may run concurrently; mutations need exclusive access.
class GridHashed : public detail::LinkedGrid<true> {
 public:
  using Options = GridHashedOptions;
  /// Reads the deprecated Config::options map into GridHashedOptions.
  /// Throws InvalidConfig.
  explicit GridHashed(const Config& c = {})
      : GridHashed(without_options(c), GridHashedOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o`.
  GridHashed(const Config& c, const GridHashedOptions& o)
      : LinkedGrid(c, "grid-hashed", (o.check(), o.cell), o.buckets) {}
};

}  // namespace broadphase
