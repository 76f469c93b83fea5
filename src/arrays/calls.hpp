// Helpers shared by the lean path's one-shot calls (src/arrays/one_shot.cpp) and its
// tracker (src/arrays/pair_tracker.cpp): reading an object, the chunks of pairs
// and their hand-over to the caller's sink, the sphere kernel's calls.
#pragma once

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/detail/in_order.hpp>
#include <span>
#include <vector>

#include "sphere_kernel.hpp"

namespace broadphase::arrays::detail {

// The library's in-order joiner (include/broadphase/detail/in_order.hpp).
using broadphase::detail::kChunkItems;
using broadphase::detail::run_in_order;
using broadphase::detail::thread_count;

// Object i as a Shape, always inlined: perf showed GCC calling
// Objects::shape out of line from the tracker's scan once the scan grew
// (32% of a steady call told everything at scaled-even 1 024 000).
[[gnu::always_inline]] inline Shape read_shape(const Objects& o, std::uint32_t i) {
  const Vec3 c{o.x.at(i), o.y.at(i), o.z.at(i)};
  if (o.is_sphere(i)) return Shape::sphere(c, o.radius.at(i));
  return Shape::box(c, {o.half_x.at(i), o.half_y.at(i), o.half_z.at(i)});
}

// check_objects on the columns and on the objects whose bits `listed` sets,
// in increasing index: for a call that reads no other value (a movers call
// of the tracker; 3% of one at scaled-even 1 024 000 went on checking the
// quiet objects, which it does not read).
void check_listed(const Objects& o, const std::vector<std::uint64_t>& listed);

// The caller's filter columns over the pairs a call hands over: pair (i, j)
// reads i's group and mask from the first set, j's from the second (the
// same set in a one-set call). Empty: no filters.
struct PairFilterColumns {
  std::span<const std::uint32_t> gi, mi, gj, mj;
  bool active() const { return !gi.empty(); }
  bool pass(const IndexPair& p) const {
    return (gi[p.i] & mj[p.j]) != 0 && (gj[p.j] & mi[p.i]) != 0;
  }
  static PairFilterColumns of(const Objects& o) { return {o.groups, o.masks, o.groups, o.masks}; }
};

// Throws InvalidObjects unless the filter columns are both empty or both
// hold one value an object.
void check_filter_columns(const Objects& o, const char* what);

struct PairChunk {
  std::vector<IndexPair> pairs;
  std::uint64_t tests = 0;
};

// Hands the chunks to the sink (sorted at the end if asked), counting.
// With filter columns, the pairs that fail them are dropped here, the one
// place every pair of a call passes before the caller sees it: pairs a
// tracker keeps between calls (its quiet pairs, its cells' pairs) are kept
// whatever the filters, so a mask the caller changes needs no renewal. A
// call without filters pays one test a chunk.
class Emitter {
 public:
  Emitter(const PairSink& sink, bool sorted, ArrayCallStats& stats, PairFilterColumns filters = {})
      : sink_(sink), sorted_(sorted), stats_(stats), filters_(filters) {}

  bool deliver(PairChunk& c) {
    stats_.tests += c.tests;
    return deliver(std::span<const IndexPair>(c.pairs));
  }
  // Pairs the caller keeps valid until the sink returns (no copy).
  bool deliver(std::span<const IndexPair> pairs) {
    if (filters_.active()) {
      passed_.clear();
      for (const IndexPair& p : pairs)
        if (filters_.pass(p)) passed_.push_back(p);
      pairs = passed_;
    }
    stats_.pairs += pairs.size();
    if (sorted_) {
      all_.insert(all_.end(), pairs.begin(), pairs.end());
      return true;
    }
    return hand(pairs);
  }
  // The same, handed over in slices.
  bool deliver_slices(std::span<const IndexPair> pairs) {
    return in_slices(pairs, [&](std::span<const IndexPair> s) { return deliver(s); });
  }
  bool stopped() const { return stats_.stopped; }
  void finish() {
    if (!sorted_ || stats_.stopped) return;
    std::sort(all_.begin(), all_.end(), [](const IndexPair& p, const IndexPair& q) {
      return p.i != q.i ? p.i < q.i : p.j < q.j;
    });
    in_slices(all_, [&](std::span<const IndexPair> s) { return hand(s); });
  }

 private:
  template <class Take>
  static bool in_slices(std::span<const IndexPair> pairs, Take&& take) {
    constexpr std::size_t kSlice = 1 << 16;
    for (std::size_t s = 0; s < pairs.size(); s += kSlice)
      if (!take(pairs.subspan(s, std::min(kSlice, pairs.size() - s)))) return false;
    return true;
  }
  bool hand(std::span<const IndexPair> pairs) {
    if (pairs.empty()) return true;
    if (!sink_(pairs)) {
      stats_.stopped = true;
      return false;
    }
    return true;
  }
  const PairSink& sink_;
  bool sorted_;
  ArrayCallStats& stats_;
  PairFilterColumns filters_;
  std::vector<IndexPair> passed_;  // a filtered chunk, valid until the sink returns
  std::vector<IndexPair> all_;
};

inline PairSink append_to(std::vector<IndexPair>& out) {
  return [&out](std::span<const IndexPair> c) {
    out.insert(out.end(), c.begin(), c.end());
    return true;
  };
}

inline IndexPair ordered(std::uint32_t p, std::uint32_t q) {
  return p < q ? IndexPair{p, q} : IndexPair{q, p};
}

// The pairs of the spheres sorted into `cells`, handed over in order (and,
// with `keep`, appended to it as they are handed over).
// `keep` takes the pairs whatever the filters.
inline ArrayCallStats cell_pairs(const detail::SphereCells& cells, const PairSink& sink,
                                 const ArrayOptions& options,
                                 std::vector<IndexPair>* keep = nullptr,
                                 PairFilterColumns filters = {}) {
  ArrayCallStats stats;
  Emitter emit(sink, options.sorted, stats, filters);
  run_in_order<PairChunk>(
      cells.cell_count(), thread_count(options.threads),
      [&](std::size_t begin, std::size_t end, PairChunk& out) {
        out.pairs.clear();
        out.tests = cells.pairs(begin, end, out.pairs);
      },
      [&](PairChunk& c) {
        if (keep != nullptr) keep->insert(keep->end(), c.pairs.begin(), c.pairs.end());
        return emit.deliver(c);
      });
  emit.finish();
  return stats;
}

}  // namespace broadphase::arrays::detail
