// The kernel for spheres (find_pairs on a single set of spheres, and the
// tracker's calls afresh): a few dense grids of cells, each a hair wider
// than the largest diameter on it, the spheres counting-sorted into them as
// records of doubles, and each sphere tested exactly, by the contract's
// predicate, against the spheres after it on its own grid (the rest of its
// cell and 13 neighbours: 5 runs of consecutive cells) and against every
// sphere within reach on the coarser grids (2 or 3 cells a side).
//
// The grids: the smallest remaining spheres, and all others up to twice
// their size or up to the narrowest cell that the budget of cells allows
// (kMaxCellsPerObject a sphere, each grid over the box of all centres), go
// to one grid; the rest to the next. Spheres of one size take one grid;
// radii over three decades three.
//
// Why beside ArrayGrid: ArrayGrid's power-of-two levels (one per octave)
// and float boxes cost a box test on about 30 partners a sphere before the
// exact test for spheres of one size, and a probe of every coarser octave
// for spheres of many sizes; here the cells are the diameters themselves,
// the levels few, and the exact test reads one record. Measured on one
// core (docs/arrays.md, point 5): 1 000 000 spheres of radius 0.00565 in
// the unit cube 135-150 ms against 310-420; 100 000 over three decades of
// radii 19-20 ms against 125.
#pragma once

#include <broadphase/arrays.hpp>
#include <cstdint>
#include <vector>

#include "big_vector.hpp"

namespace broadphase::detail {

class SphereCells {
 public:
  /// Sorts the spheres of `o` into grids. False, with nothing kept, when
  /// the kernel does not suit them: a box among them, fewer than
  /// `kMinObjects`, a grid that cannot be dense (under 2^26 cells along an
  /// axis), or spheres crowded into few cells (the sum of a grid's squared
  /// cell counts over `kMaxCrowd` times its spheres), or a value that
  /// check_objects refuses (a centre or radius not finite, a negative
  /// radius; the caller's check then names it). Missing columns: false.
  bool build(const Objects& o);

  static constexpr std::size_t kMinObjects = 64;
  static constexpr std::size_t kMaxCellsPerObject = 4;
  static constexpr std::size_t kMaxCrowd = 16;
  static constexpr std::size_t kMaxLevels = 8;

  /// Cells of all grids, each with one empty layer around the centres' box.
  std::size_t cell_count() const { return cells_; }
  /// The grids.
  std::size_t level_count() const { return levels_.size(); }
  /// The largest over the grids of the mean, over their spheres, of the
  /// spheres in a sphere's cell (itself included): 1 when none shares.
  double crowd() const { return crowd_; }
  /// Appends the overlapping pairs found from the spheres of cells
  /// [c0, c1) to `out` (caller's indices, i < j), each pair of the set
  /// exactly once over all cells; returns the number of exact tests.
  std::uint64_t pairs(std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const;

 private:
  struct Level {
    double h = 0, inv = 0;
    double rmax = 0;  // the largest radius on the grid
    std::size_t dims[3] = {0, 0, 0};
    std::size_t nx = 0, nxy = 0;
    std::size_t first = 0;  // its first cell in the cells of all grids
    std::size_t cells = 0;
    // The cell along axis `ax` of a coordinate anywhere (the empty outer
    // layer outside the centres' box).
    std::size_t index(int ax, double lo, double v) const {
      const double t = (v - lo) * inv;
      if (!(t >= 0)) return 0;
      if (t >= static_cast<double>(dims[ax] - 2)) return dims[ax] - 1;
      return static_cast<std::size_t>(t) + 1;
    }
    // The global cell of a point (inside the centres' box).
    std::size_t cell_of(const double* lo, double x, double y, double z) const {
      return first +
             ((static_cast<std::size_t>((z - lo[2]) * inv) + 1) * dims[1] +
              static_cast<std::size_t>((y - lo[1]) * inv) + 1) *
                 dims[0] +
             static_cast<std::size_t>((x - lo[0]) * inv) + 1;
    }
  };
  void release();
  bool fail();  // release(), false

  double lo_[3] = {0, 0, 0};
  std::vector<Level> levels_;
  std::size_t cells_ = 0;
  double crowd_ = 0;
  BigVector<std::uint32_t> start_;  // per cell, then one past the end
  // A sphere in cell order, with its index: one record, so that the
  // counting sort's scatter writes one line per sphere (five columns were
  // five cache misses a sphere).
  struct Placed {
    double x, y, z, r;
    std::uint32_t id;
  };
  BigVector<Placed> placed_;
};

}  // namespace broadphase::detail
