/// \file structure_base.hpp
/// What every structure answers the same way, written once: the members of
/// the Structure concept that do not depend on how a structure indexes its
/// objects, and the opening of `validate()`.
///
/// `StructureBase<S>` is the root of every structure (CRTP: `S` is the
/// structure itself); `StoreBase<S>` adds the ObjectStore most structures
/// keep their objects in, and answers `size`, `contains`, `shape` and
/// `user_data` from it. A member every structure should gain goes here (and
/// into AnyBroadPhase / Erased in structure.hpp), not into each header.
///
/// Neither base has a virtual function or data of its own beyond the store:
/// each call is resolved at compile time and inlined, and the hot paths
/// (`query`, `for_each_pair`) stay templates in the concrete structure.
///
/// Every structure also follows the same pattern for its options, which the
/// bases cannot hold (constructors are not inherited) and are documented
/// here once:
///
///   - `S::Options`, an aggregate with a default for every field;
///     `Options::check()` throws InvalidConfig for a value out of its
///     documented range (NaN, infinite and subnormal values included);
///     `Options::from(const OptionText&)` reads options given as text
///     (`key=value`, from a registry spec or the deprecated Config::options)
///     into the fields, throwing InvalidConfig for an unknown key or a value
///     that is not a number or not one of the choices; ranges are left to
///     check(). `from` is defined with the registry (src/registry/), the
///     only place option text is parsed.
///   - `S(const Config& c, const Options& o)`, the typed constructor: throws
///     InvalidConfig for a bad `c` (check_config) or `o` (Options::check).
///   - `explicit S(const Config& c = {})`, reading the deprecated
///     Config::options map once into Options and passing on the Config
///     without it; throws InvalidConfig.
#pragma once

#include <broadphase/handle.hpp>
#include <broadphase/ray.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

namespace broadphase::detail {

/// Throws std::logic_error naming the structure and the invariant that
/// failed: `fail("stale bounds")` in a validate().
class InvariantFailure {
 public:
  explicit InvariantFailure(std::string_view structure) : structure_(structure) {}
  [[noreturn]] void operator()(std::string_view what) const {
    throw std::logic_error(std::string(structure_) + ": " + std::string(what));
  }

 private:
  std::string_view structure_;
};

/// A pair visitor carrying the filter test of a filtered world: the pair
/// walks call `admits(visitor, i, j)` on each candidate after its box test
/// and before the exact test, so a filtered-out pair costs neither the exact
/// test nor a report. A walk over a plain visitor (an unfiltered world) finds
/// `admits` a constant `true`: the walk is instantiated twice, and the
/// unfiltered one has no filter code in its loops at all. Any visitor that
/// names a `PairGate` type and has `may_pair(i, j)` is tested the same way
/// (GridVerlet's emitters).
template <class V>
class FilteredVisitor {
 public:
  using PairGate = void;
  FilteredVisitor(V& visitor, const ObjectStore& store, const PairFilter& pair_filter)
      : visitor_(visitor), store_(store), pair_filter_(pair_filter) {}
  bool operator()(Handle a, Handle b) { return visit(visitor_, a, b); }
  /// The rule: the bits first, then the pair filter (structure.hpp).
  bool may_pair(std::uint32_t i, std::uint32_t j) const {
    return store_.may_pair(i, j) &&
           (!pair_filter_ || pair_filter_(store_.handle(i), store_.handle(j)));
  }

 private:
  V& visitor_;
  const ObjectStore& store_;
  const PairFilter& pair_filter_;
};

/// True when the candidate pair of slots `i`, `j` may be reported: by the
/// filter rule for a visitor with a PairGate, always (compiled away) for
/// any other.
template <class V>
inline bool admits(const V& v, std::uint32_t i, std::uint32_t j) {
  if constexpr (requires { typename V::PairGate; }) {
    return v.may_pair(i, j);
  } else {
    (void)v, (void)i, (void)j;
    return true;
  }
}

/// The root of every structure (`S` is the structure).
template <class S>
class StructureBase {
 public:
  /// Commits a batch of updates (Structure, structure.hpp). A no-op here:
  /// mutations are complete when they return; a structure that defers work
  /// (GridVerlet) hides this with its own.
  void settle() {}

 protected:
  const S& self() const { return static_cast<const S&>(*this); }
  S& self() { return static_cast<S&>(*this); }
};

/// A structure keeping its objects in an ObjectStore.
template <class S>
class StoreBase : public StructureBase<S> {
 public:
  /// Objects held. O(1).
  std::size_t size() const { return store_.size(); }
  /// True when `h` names a live object of this structure. O(1).
  bool contains(Handle h) const { return store_.contains(h); }
  /// The object's current shape. Throws InvalidHandle. O(1).
  const Shape& shape(Handle h) const { return store_.shape_of(h); }
  /// The user data given at insertion. Throws InvalidHandle. O(1).
  std::uint64_t user_data(Handle h) const { return store_.user_data(h); }

  /// Changes an object's collision filter (HasFilters). Throws
  /// InvalidHandle. A structure that caches pairs or keeps filters in its
  /// own nodes hides this with its own.
  void set_filter(Handle h, Filter f) { store_.set_filter(h, f); }
  /// An object's collision filter. Throws InvalidHandle. O(1).
  Filter filter(Handle h) const { return store_.filter_of(h); }
  /// Installs the pair filter (structure.hpp's PairFilter); empty removes it.
  void set_pair_filter(PairFilter pf) { pair_filter_ = std::move(pf); }
  /// True when objects `a` and `b` may pair by the filters and the pair
  /// filter. Throws InvalidHandle. O(1) plus the pair filter.
  bool pair_passes(Handle a, Handle b) const {
    return may_pair(store_.index_of(a), store_.index_of(b));
  }

  /// Visits every overlapping pair that passes the filters once
  /// (Structure). `query(shape)` is not filtered: its shape is no object and
  /// has no filter of its own. The walk itself is the structure's
  /// `walk_pairs(visitor)`, instantiated once for a plain visitor (a world
  /// without filters: no filter test anywhere in its loops) and once with the
  /// filter test attached (FilteredVisitor, tested through `admits`).
  template <class V>
  QueryCost for_each_pair(V&& visitor) const {
    if (unfiltered()) return this->self().walk_pairs(visitor);
    FilteredVisitor<std::remove_reference_t<V>> f(visitor, store_, pair_filter_);
    return this->self().walk_pairs(f);
  }

  /// Casts a ray by testing every object (HasRayCast): the fallback of a
  /// structure without a walk of its own, and the oracle the walks are
  /// checked against. O(n).
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    require_valid(r);
    QueryCost cost;
    double tmax = r.tmax;
    const std::uint32_t slots = store_.slot_count();
    for (std::uint32_t i = 0; i < slots; ++i) {
      if (!store_.slots().alive(i) || !store_.sees(r.mask, i)) continue;
      ++cost.tests;
      double t;
      if (!ray_hit(r.origin, r.dir, tmax, store_.shape(i), t)) continue;
      tmax = visit_hit(visitor, store_.handle(i), t, tmax);
      if (tmax < 0) {
        cost.stopped = true;
        break;
      }
    }
    return cost;
  }

 protected:
  /// True when slots `i` and `j` may pair: their filters pass and so does
  /// the pair filter. Every pair a structure reports or caches passes this.
  bool may_pair(std::uint32_t i, std::uint32_t j) const {
    return store_.may_pair(i, j) &&
           (!pair_filter_ || pair_filter_(store_.handle(i), store_.handle(j)));
  }
  /// True when no filter or pair filter is set: every pair passes.
  bool unfiltered() const { return !store_.filtered() && !pair_filter_; }

  /// The opening of every validate(): checks the store's own invariants and
  /// returns the thrower for the structure's further checks.
  InvariantFailure validate_store(std::string_view structure) const {
    store_.validate();
    return InvariantFailure(structure);
  }

  ObjectStore store_;
  PairFilter pair_filter_;
};

}  // namespace broadphase::detail
