// Pairs i < j of a set of n objects (the tracker's quiet pairs). Where they
// are at least kByFirstShare a object (many), and as IndexPairs would take
// more than the bytes the caller spares, they are kept by their lower index:
// the start of each object's partners (n + 1 counts), then the partners, in
// increasing i: 4 bytes a pair and 4 an object, against 8 a pair as
// IndexPair (at scaled-uneven 1 024 000, 10.7 million quiet pairs were 83
// of the tracker's 125 bytes per object). Fewer are kept as IndexPairs, in
// the order given, and handed over as they stand: expanding them cost a
// walk over every object (0.7 ms of a 7 ms call at 100 000 spheres with
// 190 000 quiet pairs). Nothing is kept when there is no pair.
#pragma once

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

#include "big_vector.hpp"

namespace broadphase::arrays::detail {

class PairsByFirst {
 public:
  static constexpr std::size_t kByFirstShare = 2;

  /// Takes pairs i < j < n, each once, in any order (kept in the order given,
  /// within each i where they are kept by it); as IndexPairs where they are
  /// few or take at most `spare_bytes`.
  void assign(std::span<const IndexPair> pairs, std::size_t n, std::size_t spare_bytes = 0) {
    clear();
    if (pairs.empty()) return;
    if (pairs.size() < kByFirstShare * n || pairs.size() * sizeof(IndexPair) <= spare_bytes) {
      plain_.assign(pairs.begin(), pairs.end());
      return;
    }
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
    free_vector(plain_);
    free_vector(start_);
    free_vector(partner_);
  }
  std::size_t size() const { return plain_.size() + partner_.size(); }
  std::size_t memory_bytes() const {
    return plain_.capacity() * sizeof(IndexPair) +
           (start_.capacity() + partner_.capacity()) * sizeof(std::uint32_t);
  }
  /// Kept as IndexPairs (then `pairs()` holds them all), not by lower index.
  bool plain() const { return start_.empty(); }
  /// At least kByFirstShare pairs an object of n, whatever their form.
  bool many(std::size_t n) const { return size() >= kByFirstShare * n; }
  std::span<const IndexPair> pairs() const { return plain_; }
  /// Appends to `out` the pairs at positions [begin, end) of the list (in
  /// increasing i) for which keep(pair) holds.
  template <class Keep>
  void expand(std::size_t begin, std::size_t end, std::vector<IndexPair>& out, Keep&& keep) const {
    if (begin >= end) return;
    if (plain()) {
      for (std::size_t p = begin; p < end; ++p)
        if (keep(plain_[p])) out.push_back(plain_[p]);
      return;
    }
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
  /// Calls f(pair) for every pair, in the order kept.
  template <class F>
  void for_each(F&& f) const {
    for (const IndexPair& q : plain_) f(q);
    for (std::size_t i = 0; i + 1 < start_.size(); ++i)
      for (std::uint32_t p = start_[i]; p < start_[i + 1]; ++p)
        f(IndexPair{static_cast<std::uint32_t>(i), partner_[p]});
  }
  /// Drops the pairs for which drop(pair) holds, keeping the others' order
  /// (those left kept as IndexPairs when they are then few).
  template <class Drop>
  void erase_if(Drop&& drop) {
    if (plain()) {
      std::erase_if(plain_, drop);
      plain_.shrink_to_fit();
      return;
    }
    // Without a branch a pair: where a fifth of the objects move, a third
    // of the pairs go, a coin toss for a branch (the pass over 2.58
    // million pairs at scaled-even 1 024 000: 16 ms with one, 10 without).
    std::uint32_t w = 0;
    for (std::size_t i = 0; i + 1 < start_.size(); ++i) {
      const std::uint32_t b = start_[i], e = start_[i + 1];
      start_[i] = w;
      for (std::uint32_t p = b; p < e; ++p) {
        const std::uint32_t j = partner_[p];
        partner_[w] = j;
        w += drop(IndexPair{static_cast<std::uint32_t>(i), j}) ? 0 : 1;
      }
    }
    if (w == 0) {
      clear();
      return;
    }
    start_.back() = w;
    partner_.resize(w);
    if (w < kByFirstShare * (start_.size() - 1)) {  // now few: as IndexPairs
      std::vector<IndexPair> few;
      few.reserve(w);
      expand(0, w, few, [](const IndexPair&) { return true; });
      clear();
      plain_ = std::move(few);
      return;
    }
    partner_.shrink_to_fit();
  }

 private:
  std::vector<IndexPair> plain_;        // few, or within the bytes spared
  std::vector<std::uint32_t> start_;    // n + 1, or none
  std::vector<std::uint32_t> partner_;  // the j of each pair, by i
};

}  // namespace broadphase::arrays::detail
