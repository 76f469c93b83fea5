// Shared helpers of the structure tests: a structure's pairs as sorted user
// data, and the brute-force pairs of a list of shapes.
#pragma once

#include <algorithm>
#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <cstdint>
#include <utility>
#include <vector>

namespace broadphase::testing {

/// Pairs of user data (or indices), each ordered, sorted.
using Pairs = std::vector<std::pair<std::uint64_t, std::uint64_t>>;

/// Every pair `s` reports, as its objects' user data.
template <class S>
Pairs pairs_of(const S& s) {
  Pairs out;
  s.for_each_pair([&](Handle a, Handle b) {
    const std::uint64_t x = s.user_data(a), y = s.user_data(b);
    out.emplace_back(std::min(x, y), std::max(x, y));
  });
  std::sort(out.begin(), out.end());
  return out;
}

/// Every overlapping pair of `shapes`, as indices.
inline Pairs brute(const std::vector<Shape>& shapes) {
  Pairs out;
  for (std::size_t i = 0; i < shapes.size(); ++i)
    for (std::size_t j = i + 1; j < shapes.size(); ++j)
      if (overlaps(shapes[i], shapes[j])) out.emplace_back(i, j);
  return out;
}

}  // namespace broadphase::testing
