/// \file grid_dense.hpp
/// `grid-dense`: a dense 3D array of cells over Config::world, each cell the
/// head of a doubly linked list whose links live in per-object arrays
/// (eight links per object, one per cell it may touch). Also the shared
/// engine of `grid-hashed` (grid_hashed.hpp) and `grid-hybrid`: the engine, `detail::LinkedGrid`,
/// is in detail/linked_grid.hpp.
///
/// Placement: an object is entered into every cell its bounds overlap, and
/// the cell size is chosen so that most objects span at most two cells per
/// axis (eight links). Centre cells with a neighbourhood search would need
/// cells as large as the largest object; this way the cell follows a size
/// quantile instead (docs/grids.md). An object spanning more goes to an overflow list that
/// is tested against the grid by a range query. Each pair is reported once,
/// from the lowest corner of the intersection of the two objects' cell
/// ranges (detail::offset_mask): no hash set, no sorting.
///
/// World: cells cover Config::world; their number is capped at
/// clamp(16 n, 4096, 2^22) (n: objects at the last re-grid), and the cell
/// edge grows until the world fits under the cap. Objects outside the world
/// are clamped into the border cells (exact, slower when many are outside).
#pragma once

#include <broadphase/detail/linked_grid.hpp>

namespace broadphase {

/// The options of GridDense (`grid-dense:cell=E`).
struct GridDenseOptions {
  /// Cell edge in world units, in [1e-300, 1e300]; 0 (default): chosen from
  /// the world and the population, and re-chosen as it changes.
  double cell = 0;
  /// Throws InvalidConfig for a value out of range (detail/structure_base.hpp).
  void check() const { detail::check_number("grid-dense", "cell", cell, 1e-300, 1e300, true); }
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static GridDenseOptions from(const OptionText& text);
};

/// A dense array of cells over Config::world with linked lists of objects.
/// insert, remove, update: O(1) (amortised: re-grids when the population
/// doubles or quarters, unless `cell=` is given). query: O(cells covered +
/// candidates). for_each_pair: O(n + candidate pairs). Memory: O(n + cells),
/// cells capped at clamp(16 n, 4096, 2^22). Options: `cell=` (edge length).
/// Handles stay valid until their object is removed. Const members may run
/// concurrently; mutations need exclusive access.
class GridDense : public detail::LinkedGrid<false> {
 public:
  using Options = GridDenseOptions;
  /// Reads the deprecated Config::options map into GridDenseOptions.
  /// Throws InvalidConfig.
  explicit GridDense(const Config& c = {})
      : GridDense(without_options(c), GridDenseOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o`.
  GridDense(const Config& c, const GridDenseOptions& o)
      : LinkedGrid(c, "grid-dense", (o.check(), o.cell), 0) {}
};

}  // namespace broadphase
