/// \file sort_sweep.hpp
/// `sort-sweep`: the batch sweep-and-prune. Nothing is kept sorted between
/// frames; each all-pairs pass picks the axis along which the box centres
/// vary most, sorts the boxes by their lower end on it (radix sort of the
/// float keys) and sweeps.
#pragma once

#include <broadphase/config_error.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

/// SortSweep takes no options; the struct is where they would go.
struct SortSweepOptions {
  /// Nothing to check.
  void check() const {}
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static SortSweepOptions from(const OptionText& text);
};

/// Batch sort-and-sweep over float boxes rounded outwards from the
/// conservative bounds. No state but the boxes, so incoherent motion (an
/// explosion) costs the same as coherent motion.
///
/// Complexity: insert/remove/update: O(1). for_each_pair: O(n) radix sort
/// plus O(n + k) sweep, k the pairs overlapping on the sweep axis.
/// query: O(n). Handles stay valid until their object is removed.
/// Thread-safety: const members may run concurrently (the sort buffers are
/// per thread); a visitor must not start another all-pairs pass of a
/// sort-sweep on the same thread.
class SortSweep : public detail::StoreBase<SortSweep> {
 public:
  using Options = SortSweepOptions;
  /// Reads the deprecated Config::options (none accepted). Throws InvalidConfig.
  explicit SortSweep(const Config& c = {})
      : SortSweep(without_options(c), SortSweepOptions::from(c.options)) {}
  /// Checks `c` (check_config). Throws InvalidConfig.
  SortSweep(const Config& c, const SortSweepOptions& o);

  /// Adds an object. O(1). Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object. O(1). Throws InvalidHandle.
  void remove(Handle h);
  /// Replaces an object's shape. O(1). Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object overlapping `q` exactly (a linear scan of boxes).
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    const AabbF b = bounds_f(q);
    for (std::size_t d = 0; d < dense_.size(); ++d) {
      if (!box_[d].overlaps(b)) continue;
      ++cost.tests;
      if (overlaps(q, store_.shape(dense_[d])) && !visit(visitor, store_.handle(dense_[d]))) {
        cost.stopped = true;
        break;
      }
    }
    return cost;
  }

  /// Casts a ray (HasRayCast): a linear scan of the dense boxes, each
  /// culled by RayCull before the exact test. The sort is made per pass in
  /// a per-thread buffer, so there is no kept order to walk: sorting for one
  /// ray would cost more than the scan. O(n). Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    require_valid(r);
    detail::RayCast<std::remove_reference_t<V>> cast(store_, r, visitor);
    for (std::size_t d = 0; d < dense_.size(); ++d)
      if (!cast.test(dense_[d], box_[d])) break;
    return cast.cost;
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair once: sort, then sweep.
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    QueryCost cost;
    const std::vector<Item>& s = sorted();
    const std::size_t n = s.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Item& a = s[i];
      for (std::size_t j = i + 1; j < n && s[j].lo0 <= a.hi0; ++j) {
        const Item& b = s[j];
        if (a.lo1 > b.hi1 || b.lo1 > a.hi1 || a.lo2 > b.hi2 || b.lo2 > a.hi2) continue;
        if (!detail::admits(visitor, a.slot, b.slot)) continue;
        ++cost.tests;
        if (overlaps(store_.shape(a.slot), store_.shape(b.slot)) &&
            !visit(visitor, store_.handle(a.slot), store_.handle(b.slot))) {
          cost.stopped = true;
          return cost;
        }
      }
    }
    return cost;
  }

  /// Bytes held (capacities of every array and table).
  std::size_t memory_bytes() const;
  /// The axis the next pass would sweep along (largest variance of centres).
  int sweep_axis() const;
  /// Checks the dense arrays against the object store.
  void validate() const;

 private:
  // One box in sweep order: the sweep axis first, then the other two.
  struct Item {
    float lo0, hi0, lo1, hi1, lo2, hi2;
    std::uint32_t slot;
  };
  // The boxes sorted along sweep_axis(), in a per-thread buffer.
  const std::vector<Item>& sorted() const;

  std::vector<AabbF> box_;               // dense position -> float box
  std::vector<std::uint32_t> dense_;     // dense position -> slot
  std::vector<std::uint32_t> slot_pos_;  // slot -> dense position
};

}  // namespace broadphase
