/// \file naive.hpp
/// `naive`: tests every pair, the study's base case and the oracle every
/// other structure is checked against.
#pragma once

#include <broadphase/config_error.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <vector>

namespace broadphase {

/// Naive takes no options; the struct is where they would go.
struct NaiveOptions {
  /// Nothing to check.
  void check() const {}
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static NaiveOptions from(const OptionText& text);
};

/// Keeps objects in a dense array and tests every pair.
/// insert, remove, update: O(1). query: O(n). for_each_pair: O(n²).
/// Handles stay valid until their object is removed.
class Naive : public detail::StoreBase<Naive> {
 public:
  using Options = NaiveOptions;
  /// Reads the deprecated Config::options (none accepted). Throws InvalidConfig.
  explicit Naive(const Config& c = {}) : Naive(without_options(c), NaiveOptions::from(c.options)) {}
  /// Checks `c` (check_config). Throws InvalidConfig.
  Naive(const Config& c, const NaiveOptions& o) {
    check_config(c, "naive");
    o.check();
  }

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic) {
    const Handle h = store_.insert(s, user);
    if (h.index >= slot_pos_.size()) slot_pos_.resize(h.index + 1);
    slot_pos_[h.index] = static_cast<std::uint32_t>(dense_.size());
    dense_.push_back(h.index);
    return h;
  }
  /// Removes an object (swap with the last of the dense array). Throws InvalidHandle.
  void remove(Handle h) {
    const std::uint32_t i = store_.erase(h);
    const std::uint32_t pos = slot_pos_[i];
    dense_[pos] = dense_.back();
    slot_pos_[dense_[pos]] = pos;
    dense_.pop_back();
  }
  /// Replaces an object's shape. Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s) { store_.set_shape(h, s); }

  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    for (std::uint32_t i : dense_) {
      ++cost.tests;
      if (overlaps(q, store_.shape(i)) && !visit(visitor, store_.handle(i))) {
        cost.stopped = true;
        break;
      }
    }
    return cost;
  }

  /// The pair walk behind for_each_pair (StoreBase): every pair of the
  /// dense array, the filter test (detail::admits) before the exact one.
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    QueryCost cost;
    const std::size_t n = dense_.size();
    for (std::size_t a = 0; a < n; ++a) {
      const Shape& sa = store_.shape(dense_[a]);
      for (std::size_t b = a + 1; b < n; ++b) {
        if (!detail::admits(visitor, dense_[a], dense_[b])) continue;
        ++cost.tests;
        if (overlaps(sa, store_.shape(dense_[b])) &&
            !visit(visitor, store_.handle(dense_[a]), store_.handle(dense_[b]))) {
          cost.stopped = true;
          return cost;
        }
      }
    }
    return cost;
  }

  std::size_t memory_bytes() const {
    return store_.memory_bytes() +
           (dense_.capacity() + slot_pos_.capacity()) * sizeof(std::uint32_t);
  }

  /// Checks that the dense array lists exactly the live slots.
  void validate() const {
    const auto fail = validate_store("naive");
    if (dense_.size() != store_.size()) fail("dense array size");
    for (std::size_t p = 0; p < dense_.size(); ++p) {
      if (!store_.slots().alive(dense_[p]) || slot_pos_[dense_[p]] != p)
        fail("dense array and slot positions disagree");
    }
  }

 private:
  std::vector<std::uint32_t> dense_;     // live slot indices
  std::vector<std::uint32_t> slot_pos_;  // slot index -> position in dense_
};

}  // namespace broadphase
