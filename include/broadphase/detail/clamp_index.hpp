/// \file clamp_index.hpp
/// Converting coordinates-derived doubles to integer indices safely. A cell
/// or level index computed from coordinates can be NaN (0 * inf, inf - inf,
/// inf / inf over worlds whose width overflows or cells that are infinite)
/// or far beyond any integer type; converting either to an integer is
/// undefined behaviour. Internal.
#pragma once

#include <cmath>

namespace broadphase::detail {

/// `v` clamped to [lo, hi] (finite, lo <= hi, both representable in Int)
/// and floored, as an Int. NaN gives `lo`. Non-decreasing in `v` for every
/// `v` but NaN, so the grids' monotone-map argument for exactness still
/// holds.
template <class Int>
inline Int clamp_floor(double v, double lo, double hi) {
  const double c = v >= lo ? (v <= hi ? v : hi) : lo;
  return static_cast<Int>(std::floor(c));
}

/// (hi - lo) / k without overflowing when hi - lo exceeds the largest
/// double (a world [-1e308, 1e308] has finite corners and an infinite
/// width): the quotient is taken first. k >= 1.
inline double width_over(double lo, double hi, double k) {
  const double w = hi - lo;
  return std::isfinite(w) ? w / k : hi / k - lo / k;
}

}  // namespace broadphase::detail
