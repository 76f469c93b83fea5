// What every peer adapter shares: the object store beside the library's own
// objects, the exact filter applied to the library's candidates, and the
// registration of an adapter as a `peer`.
//
// A peer library decides which pairs are *candidates*; only our exact
// `overlaps()` decides which are pairs. The library is fed the conservative
// `bounds()` (or `bounds_f()` for float libraries), so every overlapping pair
// is a candidate and the pair hash equals ours unless the library itself
// loses a candidate (docs/peers.md lists where that happens).
#pragma once

#include <broadphase/detail/structure_base.hpp>
#include <broadphase/handle.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace broadphase::app::peers {

/// Stores a slot index in a library's `void*` user pointer. Slot + 1, so that
/// no object is ever tagged with the null pointer some libraries reserve.
inline void* tag_of(std::uint32_t slot) {
  return reinterpret_cast<void*>(static_cast<std::uintptr_t>(slot) + 1);
}
/// The slot index a `tag_of` pointer carries.
inline std::uint32_t slot_of(const void* tag) {
  return static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(tag) - 1);
}

/// Filters a library's candidate pairs by the collision filters (when the
/// visitor carries them: PeerBase::with_filters) and the exact predicate, and
/// forwards the overlapping ones to a visitor. Counts every candidate tested
/// exactly as one test.
/// Once the visitor asks to stop, later candidates are ignored (for libraries
/// whose callbacks cannot stop a traversal).
template <class V>
class PairFilter {
 public:
  PairFilter(const ObjectStore& store, V& visitor) : store_(store), visitor_(visitor) {}

  /// Tests candidate (a, b); returns false once the visitor has asked to stop.
  bool operator()(std::uint32_t a, std::uint32_t b) {
    if (cost_.stopped) return false;
    if (!detail::admits(visitor_, a, b)) return true;
    ++cost_.tests;
    if (overlaps(store_.shape(a), store_.shape(b)) &&
        !visit(visitor_, store_.handle(a), store_.handle(b)))
      cost_.stopped = true;
    return !cost_.stopped;
  }
  const QueryCost& cost() const { return cost_; }

 private:
  const ObjectStore& store_;
  V& visitor_;
  QueryCost cost_;
};

/// The same for the candidates of one query shape.
template <class V>
class QueryFilter {
 public:
  QueryFilter(const ObjectStore& store, const Shape& query, V& visitor)
      : store_(store), query_(query), visitor_(visitor) {}

  /// Tests candidate `slot`; returns false once the visitor has asked to stop.
  bool operator()(std::uint32_t slot) {
    if (cost_.stopped) return false;
    ++cost_.tests;
    if (overlaps(query_, store_.shape(slot)) && !visit(visitor_, store_.handle(slot)))
      cost_.stopped = true;
    return !cost_.stopped;
  }
  const QueryCost& cost() const { return cost_; }

 private:
  const ObjectStore& store_;
  const Shape& query_;
  V& visitor_;
  QueryCost cost_;
};

/// The part of an adapter that does not depend on the library: our handles,
/// shapes and user data, and one library object per slot. `Native` is what
/// the library hands back for an object (a proxy pointer, a geom id, ...):
/// a pointer-like type, null while the slot is free.
/// (size, contains, shape and user_data are the structures' own, from
/// detail::StoreBase.)
template <class Native>
class PeerBase : public detail::StoreBase<PeerBase<Native>> {
 protected:
  using detail::StoreBase<PeerBase<Native>>::store_;

  /// Stores the object and returns its slot (the library object is set next).
  std::uint32_t add(const Shape& s, std::uint64_t user, Handle& h) {
    h = store_.insert(s, user);
    if (h.index >= native_.size()) native_.resize(h.index + 1);
    return h.index;
  }
  /// Runs an adapter's pair walk `walk(visitor)` with the collision filters
  /// attached to the visitor (detail::FilteredVisitor, tested by PairFilter
  /// in the library's pair callback), or on the plain visitor when no filter
  /// is set. The peers' own group/mask schemes (Bullet's, FCL's, ODE's
  /// category bits) are not used: a changed filter would need every proxy
  /// re-created for their pair caches to follow.
  template <class V, class Walk>
  QueryCost with_filters(V& visitor, Walk&& walk) const {
    if (this->unfiltered()) return walk(visitor);
    detail::FilteredVisitor<V> f(visitor, store_, this->pair_filter_);
    return walk(f);
  }
  /// Frees the slot and returns the library object it held.
  Native take(Handle h) {
    const std::uint32_t i = store_.erase(h);
    return std::exchange(native_[i], Native{});
  }
  /// Bytes held by our own bookkeeping (the library's memory is not included).
  std::size_t own_bytes() const {
    return store_.memory_bytes() + native_.capacity() * sizeof(Native);
  }
  /// Checks that exactly the live slots hold a library object; `library_count`
  /// is the number of objects the library says it holds.
  void validate_slots(const char* name, std::size_t library_count) const {
    store_.validate();
    std::size_t held = 0;
    for (std::uint32_t i = 0; i < native_.size(); ++i) {
      const bool has = native_[i] != nullptr;
      if (has != store_.slots().alive(i))
        throw std::logic_error(
            std::string(name) + ": slot " + std::to_string(i) +
            (has ? " is free but holds a library object" : " is live but holds no library object"));
      held += has;
    }
    if (held != store_.size() || library_count != store_.size())
      throw std::logic_error(std::string(name) + ": the library holds " +
                             std::to_string(library_count) + " objects, the adapter " +
                             std::to_string(store_.size()));
  }

  std::vector<Native> native_;
};

/// Registers adapter `S` (constructor taking a Config) as a peer.
template <class S>
void add_peer(Registry& r, std::string name, std::string description) {
  r.add({std::move(name), std::move(description), true,
         [](const Config& c) -> std::unique_ptr<AnyBroadPhase> {
           return std::make_unique<Erased<S>>(c);
         }});
}

// One registration function per library; peers/register.cpp calls those
// that were built.
void register_bullet(Registry& r);
void register_fcl(Registry& r);
void register_ode(Registry& r);
void register_cgal(Registry& r);

}  // namespace broadphase::app::peers
