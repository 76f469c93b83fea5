// The one-shot kernel for spheres of about one size (find_pairs on a single
// set): one dense grid of cells a hair wider than the largest diameter, the
// spheres counting-sorted into it as columns of doubles, and each sphere
// tested exactly, by the contract's predicate, against the spheres after it
// in its cell and in the 13 cells of its half-neighbourhood (5 runs of
// consecutive cells).
//
// Why beside ArrayGrid: for spheres of one size, ArrayGrid's power-of-two
// levels and float boxes cost a box test on about 30 partners a sphere
// before the exact test (a quarter-octave base still leaves cells up to
// 1.19 times the diameter, 1.7 times the volume), and the candidates' boxes
// and shapes live in two arrays. Here a cell is the diameter itself, and
// the exact test reads four adjacent columns: measured at 1 000 000
// spheres of radius 0.00565 in the unit cube, see `build`'s caller.
#pragma once

#include <broadphase/arrays.hpp>
#include <cstdint>
#include <vector>

#include "big_vector.hpp"

namespace broadphase::detail {

class SphereCells {
 public:
  /// Sorts the spheres of `o` into cells. False, with nothing kept, when
  /// the kernel does not suit them: a box among them, fewer than
  /// `kMinObjects`, radii more than a factor `kMaxSpread` apart (when the
  /// largest sets the cell), a grid that cannot be dense (at most
  /// `kMaxCellsPerObject` cells an object, under 2^26 along an axis), or
  /// spheres crowded into few cells (the sum of the cells' squared counts
  /// over `kMaxCrowd` an object). `o` must have passed check_objects.
  bool build(const Objects& o);

  static constexpr std::size_t kMinObjects = 64;
  static constexpr double kMaxSpread = 2;
  static constexpr std::size_t kMaxCellsPerObject = 4;
  static constexpr std::size_t kMaxCrowd = 16;

  /// Cells, including one empty layer around the occupied box.
  std::size_t cell_count() const { return cells_; }
  /// Appends the overlapping pairs found from the spheres of cells
  /// [c0, c1) to `out` (caller's indices, i < j), each pair of the set
  /// exactly once over all cells; returns the number of exact tests.
  std::uint64_t pairs(std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const;

 private:
  void release();

  std::size_t cells_ = 0;
  std::size_t nx_ = 0, nxy_ = 0;
  BigVector<std::uint32_t> start_;   // per cell, then one past the end
  BigVector<double> x_, y_, z_, r_;  // in cell order
  BigVector<std::uint32_t> id_;
};

}  // namespace broadphase::detail
