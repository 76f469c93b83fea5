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
  /// Reads `cell=`, `buckets=`. Throws UnknownStructure for other keys.
  explicit GridHashed(const Config& c = {}) : LinkedGrid(c, "grid-hashed") {}
};

}  // namespace broadphase
