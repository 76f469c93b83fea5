// Pairs i < j of a set of n objects, kept by their lower index: the start of
// each object's partners (n + 1 counts), then the partners, in increasing i.
// 4 bytes a pair and 4 an object, against 8 a pair as IndexPair: the
// tracker's quiet pairs, which at scaled-uneven 1 024 000 (10.7 million of
// them) were 83 of its 125 bytes per object. Nothing is kept when there is
// no pair.
#pragma once

#include <algorithm>
#include <broadphase/arrays.hpp>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

#include "big_vector.hpp"

namespace broadphase::detail {

class PairsByFirst {
 public:
  /// Takes pairs i < j < n, each once, in any order (kept in the order given
  /// within each i).
  void assign(std::span<const IndexPair> pairs, std::size_t n) {
    clear();
    if (pairs.empty()) return;
    if (pairs.size() > std::numeric_limits<std::uint32_t>::max() ||
        n >= std::numeric_limits<std::uint32_t>::max())
      throw std::length_error("PairsByFirst: more than 2^32 - 1 pairs or objects");
    start_.assign(n + 1, 0);
    for (const IndexPair& p : pairs) ++start_[p.i + 1];
    for (std::size_t i = 0; i < n; ++i) start_[i + 1] += start_[i];
    partner_.resize(pairs.size());
    for (const IndexPair& p : pairs) partner_[start_[p.i]++] = p.j;
    for (std::size_t i = n; i > 0; --i) start_[i] = start_[i - 1];
    start_[0] = 0;
  }
  void clear() {
    free_vector(start_);
    free_vector(partner_);
  }
  std::size_t size() const { return partner_.size(); }
  std::size_t memory_bytes() const {
    return (start_.capacity() + partner_.capacity()) * sizeof(std::uint32_t);
  }
  /// Appends to `out` the pairs at positions [begin, end) of the list (in
  /// increasing i) for which keep(pair) holds.
  template <class Keep>
  void expand(std::size_t begin, std::size_t end, std::vector<IndexPair>& out, Keep&& keep) const {
    if (begin >= end) return;
    auto i = static_cast<std::uint32_t>(
        std::upper_bound(start_.begin(), start_.end(), static_cast<std::uint32_t>(begin)) -
        start_.begin() - 1);
    const std::size_t base = out.size();
    out.resize(base + (end - begin));
    IndexPair* w = out.data() + base;
    for (std::size_t p = begin; p < end; ++i) {
      const std::size_t stop = std::min<std::size_t>(end, start_[i + 1]);
      for (; p < stop; ++p) {
        *w = {i, partner_[p]};
        w += keep(*w) ? 1 : 0;
      }
    }
    out.resize(static_cast<std::size_t>(w - out.data()));
  }
  /// Calls f(pair) for every pair, in increasing i.
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t i = 0; i + 1 < start_.size(); ++i)
      for (std::uint32_t p = start_[i]; p < start_[i + 1]; ++p)
        f(IndexPair{static_cast<std::uint32_t>(i), partner_[p]});
  }
  /// Drops the pairs for which drop(pair) holds, keeping the others' order.
  template <class Drop>
  void erase_if(Drop&& drop) {
    std::uint32_t w = 0;
    for (std::size_t i = 0; i + 1 < start_.size(); ++i) {
      const std::uint32_t b = start_[i], e = start_[i + 1];
      start_[i] = w;
      for (std::uint32_t p = b; p < e; ++p)
        if (!drop(IndexPair{static_cast<std::uint32_t>(i), partner_[p]}))
          partner_[w++] = partner_[p];
    }
    if (w == 0) {
      clear();
      return;
    }
    start_.back() = w;
    partner_.resize(w);
    partner_.shrink_to_fit();
  }

 private:
  std::vector<std::uint32_t> start_;    // n + 1, or none
  std::vector<std::uint32_t> partner_;  // the j of each pair, by i
};

}  // namespace broadphase::detail
