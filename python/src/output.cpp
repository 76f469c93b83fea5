/// \file output.cpp
/// Filling the module's int64 output arrays with pairs and ids, and sorting
/// pairs by (i, j).
#include "output.hpp"

#include <algorithm>
#include <numeric>

namespace broadphase_python {

void append_pairs(I64Vec& out, std::span<const bp::IndexPair> chunk) {
  const std::size_t k = out.size();
  if (out.capacity() < k + 2 * chunk.size())
    out.reserve(std::max(2 * out.capacity(), k + 2 * chunk.size()));
  out.resize(k + 2 * chunk.size());
  std::int64_t* p = out.data() + k;
  for (const bp::IndexPair& q : chunk) {
    *p++ = q.i;
    *p++ = q.j;
  }
}

void sort_pairs(PairVec& pairs, std::size_t n) {
  if (pairs.size() < 2) return;
  std::vector<std::uint32_t> start(n + 1, 0);
  for (const bp::IndexPair& p : pairs) ++start[p.i + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  PairVec out(pairs.size());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const bp::IndexPair& p : pairs) out[fill[p.i]++] = p;
  for (std::size_t i = 0; i < n; ++i)
    std::sort(out.begin() + start[i], out.begin() + start[i + 1],
              [](const bp::IndexPair& a, const bp::IndexPair& b) { return a.j < b.j; });
  pairs.swap(out);
}

IntArray to_int_array(std::span<const bp::IndexPair> pairs) {
  IntArray a;
  a.cols = 2;
  a.rows = pairs.size();
  append_pairs(a.data, pairs);
  return a;
}

IntArray ids_array(std::span<const std::uint32_t> ids) {
  IntArray a;
  a.rows = ids.size();
  a.data.assign(ids.begin(), ids.end());
  return a;
}

}  // namespace broadphase_python
