// CGAL's box_intersection_d: a batch algorithm (streamed segment tree) that
// reports the intersecting pairs of a sequence of boxes. It keeps no state
// between calls, so the adapter stores the shapes and builds the box
// sequence from `bounds()` on every all-pairs pass, as a CGAL user would.
// box_self_intersection_d with CLOSED boxes reports each intersecting pair
// once; the adapter filters candidates exactly.
#include <CGAL/box_intersection_d.h>

#include <cstdint>
#include <span>
#include <vector>

#include "peer_common.hpp"

namespace broadphase::app::peers {

namespace {

/// The box concept box_intersection_d expects: coordinates and a unique id
/// (our slot index).
struct CgalBox {
  using NT = double;
  using ID = std::size_t;

  static int dimension() { return 3; }
  ID id() const { return slot; }
  NT min_coord(int d) const { return lo[d]; }
  NT max_coord(int d) const { return hi[d]; }

  double lo[3];
  double hi[3];
  std::uint32_t slot;
};

CgalBox box_of(const Shape& s, std::uint32_t slot) {
  const Aabb b = bounds(s);
  return {{b.lo.x, b.lo.y, b.lo.z}, {b.hi.x, b.hi.y, b.hi.z}, slot};
}

/// Thrown out of CGAL's callback to stop a traversal the visitor ended;
/// CGAL's algorithm holds only vectors, so unwinding through it is safe.
struct Stop {};

/// Stores the objects; every query or all-pairs pass runs CGAL from scratch.
/// insert, remove, update: O(1). for_each_pair: O(n log^3 n + pairs) in
/// CGAL's bound. query: box_intersection_d of the query box with all boxes.
/// Queries reuse a scratch box vector: not thread-safe.
class CgalBoxIntersection : public detail::StoreBase<CgalBoxIntersection> {
 public:
  explicit CgalBoxIntersection(const Config& c) {
    OptionReader(c, "cgal-box").finish();
    scratch_.reserve(c.expected_objects);
  }

  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic) {
    return store_.insert(s, user);
  }
  void remove(Handle h) { store_.erase(h); }
  void update(Handle h, const Shape& s) { store_.set_shape(h, s); }

  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    QueryFilter<V> filter(store_, q, visitor);
    fill_scratch();
    // CGAL reorders both sequences, so the query is a one-box array of its own.
    CgalBox query_box[1] = {box_of(q, kQuerySlot)};
    try {
      CGAL::box_intersection_d(scratch_.begin(), scratch_.end(), query_box, query_box + 1,
                               [&](const CgalBox& a, const CgalBox& b) {
                                 if (!filter(a.slot == kQuerySlot ? b.slot : a.slot)) throw Stop{};
                               });
    } catch (const Stop&) {
    }
    return filter.cost();
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters, tested in PairFilter).
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    PairFilter<V> filter(store_, visitor);
    fill_scratch();
    try {
      CGAL::box_self_intersection_d(scratch_.begin(), scratch_.end(),
                                    [&](const CgalBox& a, const CgalBox& b) {
                                      if (!filter(a.slot, b.slot)) throw Stop{};
                                    });
    } catch (const Stop&) {
    }
    return filter.cost();
  }

  /// The stored objects and the box sequence CGAL runs on. CGAL's internal
  /// copy (box_self_intersection_d copies the sequence once per call) is
  /// temporary and not counted.
  std::size_t memory_bytes() const {
    return store_.memory_bytes() + scratch_.capacity() * sizeof(CgalBox);
  }
  void validate() const { store_.validate(); }

 private:
  // Larger than any slot, so the query box never shares an id with an object.
  static constexpr std::uint32_t kQuerySlot = 0xffffffffu;

  void fill_scratch() const {
    scratch_.clear();
    for (std::uint32_t i = 0; i < store_.slot_count(); ++i)
      if (store_.slots().alive(i)) scratch_.push_back(box_of(store_.shape(i), i));
  }

  mutable std::vector<CgalBox> scratch_;
};

}  // namespace

void register_cgal(Registry& r) {
  add_peer<CgalBoxIntersection>(
      r, "cgal-box",
      "CGAL box_self_intersection_d: streamed segment tree over all boxes, run from scratch "
      "on each pass (memory: adapter and its box vector)");
}

}  // namespace broadphase::app::peers
