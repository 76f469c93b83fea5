/// \file cell_size.hpp
/// The automatic cell size every uniform grid of the library uses, so that
/// all of them answer "how big is a cell?" the same way.
///
/// A uniform grid fails in three ways (see docs/grids.md and the lab's
/// cell-size sweep): cells much smaller than the objects (every object lands
/// in many cells, or overflows), cells much larger than the objects (each
/// cell holds objects that are far apart: many candidate tests per real
/// pair), and cells much larger than the spacing between objects (crowded
/// cells, quadratic work). The rule below sizes cells to hold most objects
/// whole, and never smaller than the mean spacing of the centres.
#pragma once

#include <algorithm>
#include <broadphase/geometry.hpp>
#include <cmath>
#include <cstddef>
#include <span>

namespace broadphase {

/// The knobs of the automatic cell size.
struct CellSizeRule {
  /// The cell edge is at least this quantile of the objects' extents (the
  /// largest side of each bounding box): that fraction of the objects spans
  /// at most two cells per axis.
  double quantile = 0.75;
  /// The cell edge is at least this multiple of the mean spacing of the
  /// centres, cbrt(volume / n), so that point-like objects do not scatter
  /// over many nearly empty cells.
  double spacing_factor = 0.5;
};

/// Chooses a cell edge from the objects' `extents` (reordered in place) and
/// the box `centres` that holds their centres. O(n). Always returns a
/// positive, finite size; 1 when there is nothing to go by.
inline double choose_cell_size(std::span<double> extents, const Aabb& centres,
                               const CellSizeRule& rule = {}) {
  const std::size_t n = extents.size();
  if (n == 0) return 1.0;
  const std::size_t k =
      std::min(n - 1, static_cast<std::size_t>(rule.quantile * static_cast<double>(n - 1) + 0.5));
  std::nth_element(extents.begin(), extents.begin() + static_cast<std::ptrdiff_t>(k),
                   extents.end());
  const double size_term = extents[k];
  // A flat or linear population has no volume: measure it with the largest
  // side so that the spacing stays a length.
  double side = 0;
  for (int a = 0; a < 3; ++a) side = std::max(side, centres.hi[a] - centres.lo[a]);
  double volume = 1;
  for (int a = 0; a < 3; ++a) volume *= std::max(centres.hi[a] - centres.lo[a], side * 1e-3);
  const double spacing = std::cbrt(volume / static_cast<double>(n));
  double cell = std::max(size_term, rule.spacing_factor * spacing);
  if (!(cell > 0) || !std::isfinite(cell)) cell = side > 0 && std::isfinite(side) ? side : 1.0;
  return cell;
}

}  // namespace broadphase
