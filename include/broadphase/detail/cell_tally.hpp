/// \file cell_tally.hpp
/// Objects counted per cell, for the `visit_cells` of structures that keep
/// their cells implicitly (hashed or linked grids, hierarchies of grids):
/// they do not store a count per cell, so a picture counts once, here.
/// Internal: a grid's visit_cells uses it. O(entries log cells), pictures only.
#pragma once

#include <array>
#include <broadphase/detail/grid_common.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <map>

namespace broadphase::detail {

/// Counts per (level, cell), reported in key order (deterministic pictures).
class CellTally {
 public:
  /// One object in cell `k` of `level`.
  void add(int level, const CellKey& k) { ++counts_[{level, k.c[0], k.c[1], k.c[2]}]; }
  /// One object in every cell of range `r` at `level`.
  void add(int level, const CellRange& r) {
    CellKey k;
    for (k.c[2] = r.lo[2]; k.c[2] <= r.hi[2]; ++k.c[2])
      for (k.c[1] = r.lo[1]; k.c[1] <= r.hi[1]; ++k.c[1])
        for (k.c[0] = r.lo[0]; k.c[0] <= r.hi[0]; ++k.c[0]) add(level, k);
  }
  /// Calls `visitor(box_of(level, key), level, count)` for every counted cell.
  template <class BoxOf>
  void report(BoxOf&& box_of, CellVisitor visitor) const {
    for (const auto& [key, n] : counts_)
      visitor(box_of(key[0], CellKey{{key[1], key[2], key[3]}}), key[0], n);
  }

 private:
  std::map<std::array<std::int32_t, 4>, std::size_t> counts_;
};

}  // namespace broadphase::detail
