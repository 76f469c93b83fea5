/// \file sap.hpp
/// `sap`: incremental three-axis sweep-and-prune. Every axis keeps a sorted
/// list of box endpoints; a move re-sorts only the moved object's endpoints
/// by insertion sort (temporal coherence: small moves cross few endpoints),
/// and every crossing of a lower and an upper endpoint adds or removes a pair
/// in a set kept up to date by the mutations themselves.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/pair_table.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <vector>

namespace broadphase {

/// Sap takes no options; the struct is where they would go.
struct SapOptions {
  /// Nothing to check.
  void check() const {}
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static SapOptions from(const OptionText& text);
};

/// Incremental sweep-and-prune over float endpoints (rounded outwards from
/// the conservative bounds), with an incrementally maintained set of pairs
/// whose boxes overlap on all three axes. `for_each_pair` runs the exact
/// predicate over that set only.
///
/// Complexity: update: O(log n + endpoints crossed) (coherent motion crosses
/// few; a bulk update falls back to a rebuild when crossings exceed a few per
/// endpoint); insert/remove: O(log n + k) search plus an O(n) memmove of 8-byte
/// endpoints per axis, where k is the number of objects whose lower endpoint
/// lies within the largest extent of the new box on the best axis;
/// for_each_pair: O(pairs of overlapping boxes); query: O(log n + k).
/// Handles stay valid until their object is removed. Const members may run
/// concurrently; mutations need exclusive access.
class Sap : public detail::StoreBase<Sap> {
 public:
  using Options = SapOptions;
  /// Reads the deprecated Config::options (none accepted). Throws InvalidConfig.
  explicit Sap(const Config& c = {}) : Sap(without_options(c), SapOptions::from(c.options)) {}
  /// Checks `c` (check_config). Throws InvalidConfig.
  Sap(const Config& c, const SapOptions& o);

  /// Adds an object and finds its overlapping boxes. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object and its pairs. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves an object: insertion sort of its six endpoints, pair set updated
  /// at every crossing. Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);
  /// Moves many objects, each as `update`; when the batch has crossed more
  /// than a few endpoints per object (incoherent motion), the rest of it is
  /// applied at once and the lists and pairs are rebuilt: O(n log n + k).
  /// All-or-nothing: the batch is checked before any move is applied
  /// (Throws InvalidHandle, InvalidShape); a repeated handle takes its last move.
  void update(std::span<const Move> moves);

  /// Visits every object overlapping `q` exactly.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    const AabbF b = normalized_bounds(q);
    scan(b, [&](std::uint32_t o) {
      ++cost.tests;
      if (overlaps(q, store_.shape(o)) && !visit(visitor, store_.handle(o))) {
        cost.stopped = true;
        return false;
      }
      return true;
    });
    return cost;
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): the exact predicate over the pairs whose boxes overlap on all
  /// three axes. The box-pair set holds candidates whatever their filters, so
  /// a changed filter invalidates nothing: the filters are tested here.
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    QueryCost cost;
    for (const detail::PairTable::Pair& p : pairs_.pairs()) {
      if (!detail::admits(visitor, p.a, p.b)) continue;
      ++cost.tests;
      if (overlaps(store_.shape(p.a), store_.shape(p.b)) &&
          !visit(visitor, store_.handle(p.a), store_.handle(p.b))) {
        cost.stopped = true;
        break;
      }
    }
    return cost;
  }

  /// Casts a ray (HasRayCast) along one sorted axis: the ray is cut where
  /// it leaves the box of every object (the lists' first and last
  /// endpoints), and the axis whose reach of what is left
  /// (detail::ray_axis_reach) holds the fewest endpoints is walked in the
  /// ray's direction, cut short as the visitor clips the ray. O(log n +
  /// objects whose interval on that axis meets the ray's).
  /// Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const;

  /// Bytes held (capacities of every array and table).
  std::size_t memory_bytes() const;
  /// Pairs of overlapping boxes currently in the set (candidates).
  std::size_t box_pairs() const { return pairs_.size(); }
  /// Endpoint crossings since construction (the incremental work done).
  std::uint64_t swaps() const { return swaps_; }
  /// Batches that switched to a full rebuild.
  std::uint64_t rebuilds() const { return rebuilds_; }

  /// Checks sorted lists, endpoint presence, and that the pair set is
  /// exactly the set of overlapping boxes (counted by a sweep).
  void validate() const;

  /// The conservative float box with -0 turned into +0, so that the order
  /// of the endpoint keys agrees with float comparison.
  static AabbF normalized_bounds(const Shape& s);

 private:
  // An endpoint is one 64-bit key: order-preserving float bits, then the
  // upper/lower flag (lower first, so touching boxes overlap), then the slot.
  static std::uint32_t ordered(float f) {
    const std::uint32_t u = std::bit_cast<std::uint32_t>(f);
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
  }
  // The float of an endpoint key (the inverse of `ordered`).
  static float value_of(std::uint64_t k) {
    const auto o = static_cast<std::uint32_t>(k >> 32);
    return std::bit_cast<float>((o & 0x80000000u) ? (o & 0x7fffffffu) : ~o);
  }
  static std::uint64_t key(float v, bool upper, std::uint32_t slot) {
    return (std::uint64_t(ordered(v)) << 32) | (std::uint64_t(upper) << 31) | slot;
  }
  static std::uint32_t slot_of(std::uint64_t k) {
    return static_cast<std::uint32_t>(k & 0x7fffffffu);
  }
  static bool is_upper(std::uint64_t k) { return (k >> 31) & 1u; }
  static bool boxes_overlap(const AabbF& a, const AabbF& b) { return a.overlaps(b); }

  // Moves one endpoint from key `from` to key `to`, handling each crossing.
  void move_endpoint(int axis, std::uint64_t from, std::uint64_t to);
  void rebuild(std::span<const Move> rest);
  // Crossings per endpoint after which a batch is cheaper to rebuild.
  static constexpr std::uint64_t kRebuildCrossings = 4;
  static constexpr std::uint64_t kRetryEvery = 8;
  void crossing(std::uint32_t self, bool begins, std::uint32_t other);
  void grow_extent(const AabbF& b);
  int scan_axis() const;

  // Calls f(o) for every object o whose box overlaps b (f returns false to stop).
  template <class F>
  void scan(const AabbF& b, F&& f) const {
    if (store_.size() == 0) return;
    const int a = scan_axis();
    const std::vector<std::uint64_t>& e = ep_[a];
    const float start = lower_limit(b.lo[a], max_extent_[a]);
    auto it = std::lower_bound(e.begin(), e.end(), key(start, false, 0));
    const std::uint64_t end = key(b.hi[a], false, 0x7fffffffu);
    for (; it != e.end() && *it <= end; ++it) {
      if (is_upper(*it)) continue;
      const std::uint32_t o = slot_of(*it);
      if (boxes_overlap(box_[o], b) && !f(o)) return;
    }
  }
  // A float at or below lo - extent (so every box reaching lo starts above it).
  static float lower_limit(float lo, float extent);

  std::vector<AabbF> box_;                        // slot -> normalized float box
  std::array<std::vector<std::uint64_t>, 3> ep_;  // sorted endpoint keys per axis
  std::array<float, 3> max_extent_{};             // upper bound of hi - lo per axis
  detail::PairTable pairs_;                       // slots whose boxes overlap
  std::vector<std::uint32_t> sweep_lows_;         // rebuild scratch: slots by lower end
  std::uint64_t swaps_ = 0;
  std::uint64_t rebuilds_ = 0;
  std::uint64_t incoherent_batches_ = 0;  // consecutive batches that rebuilt early
};

template <class V>
QueryCost Sap::cast_ray(const Ray& r, V&& visitor) const {
  require_valid(r);
  detail::RayCast<std::remove_reference_t<V>> cast(store_, r, visitor);
  if (store_.size() == 0) return cast.cost;
  // No object is hit where the ray is outside the box of them all: without
  // this cut a ray that leaves the world reaches half of every axis, and
  // the walk cost about as much as a test of every object (docs/rays.md).
  Aabb all;
  for (int a = 0; a < 3; ++a) {
    all.lo[a] = value_of(ep_[a].front());
    all.hi[a] = value_of(ep_[a].back());
  }
  double t_in, t_out;
  if (!detail::ray_span(cast.cull, all, r.tmax, t_in, t_out)) return cast.cost;
  using It = std::vector<std::uint64_t>::const_iterator;
  int axis = 0;
  It first, last;
  for (int a = 0; a < 3; ++a) {
    double lo, hi;
    detail::ray_axis_reach(r, t_out, a, lo, hi);
    const std::vector<std::uint64_t>& e = ep_[a];
    const It f = std::lower_bound(
        e.begin(), e.end(), key(lower_limit(detail::float_below(lo), max_extent_[a]), false, 0));
    const It l = std::upper_bound(f, e.end(), key(detail::float_above(hi), false, 0x7fffffffu));
    if (a == 0 || l - f < last - first) {
      axis = a;
      first = f;
      last = l;
    }
  }
  const int a = axis;
  double lo_live, hi_live, at = t_out;
  detail::ray_axis_reach(r, at, a, lo_live, hi_live);
  float stop = lower_limit(detail::float_below(lo_live), max_extent_[a]);
  if (r.dir[a] >= 0) {
    // Lower ends upwards, until one lies beyond the reach of the live tmax.
    for (It it = first; it != last; ++it) {
      if (is_upper(*it)) continue;
      const std::uint32_t o = slot_of(*it);
      if (std::min(cast.tmax, t_out) != at) {
        at = std::min(cast.tmax, t_out);
        detail::ray_axis_reach(r, at, a, lo_live, hi_live);
      }
      if (static_cast<double>(box_[o].lo[a]) > hi_live) break;
      if (!cast.test(o, box_[o])) break;
    }
  } else {
    // Lower ends downwards, until one lies so low that its box, at most
    // the largest extent long, ends below the reach of the live tmax.
    for (It it = last; it != first;) {
      --it;
      if (is_upper(*it)) continue;
      const std::uint32_t o = slot_of(*it);
      if (std::min(cast.tmax, t_out) != at) {
        at = std::min(cast.tmax, t_out);
        detail::ray_axis_reach(r, at, a, lo_live, hi_live);
        stop = lower_limit(detail::float_below(lo_live), max_extent_[a]);
      }
      if (box_[o].lo[a] < stop) break;
      if (!cast.test(o, box_[o])) break;
    }
  }
  return cast.cost;
}

}  // namespace broadphase
