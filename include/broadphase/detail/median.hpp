/// \file median.hpp
/// The median of a sample, as every measuring program of the project (the
/// CLI's run and sim, the lab's experiments and timing, the benchmarks,
/// tools/ab) reports it: the middle value, or the mean of the two middle
/// values of an even count; 0 for an empty sample.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace broadphase::detail {

inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  if (v.size() % 2) return v[m];
  const double upper = v[m];
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m));
  return 0.5 * (lower + upper);
}

}  // namespace broadphase::detail
