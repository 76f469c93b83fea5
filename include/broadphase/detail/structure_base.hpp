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
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

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

 protected:
  /// The opening of every validate(): checks the store's own invariants and
  /// returns the thrower for the structure's further checks.
  InvariantFailure validate_store(std::string_view structure) const {
    store_.validate();
    return InvariantFailure(structure);
  }

  ObjectStore store_;
};

}  // namespace broadphase::detail
