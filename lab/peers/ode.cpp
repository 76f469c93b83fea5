// ODE's collision spaces: dHashSpace (a multi-resolution hashed grid, cell
// sizes 2^minlevel .. 2^maxlevel, larger geoms tested against all) and
// dSweepAndPruneSpace (sort and sweep on one axis, rebuilt every collide).
//
// Objects are geoms of a custom geom class whose AABB callback returns the
// bounds the adapter stores in the geom's class data, so ODE sees exactly
// our conservative box. ODE is driven as a simulation loop drives it: a moved
// geom is marked dirty (dGeomSetPosition to its centre), and dSpaceCollide
// recomputes dirty AABBs, rebuilds the space's index and calls back for each
// pair whose AABBs overlap, once per pair. The adapter filters exactly.
#include <ode/ode.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>

#include "peer_common.hpp"

namespace broadphase::app::peers {

namespace {

/// ODE's AABB layout: min x, max x, min y, max y, min z, max z.
struct GeomBounds {
  dReal aabb[6];
};

void bounds_callback(dGeomID g, dReal aabb[6]) {
  std::copy_n(static_cast<const GeomBounds*>(dGeomGetClassData(g))->aabb, 6, aabb);
}

// Never called: the adapter only runs ODE's broad phase, never dCollide.
dColliderFn* no_collider(int) { return nullptr; }

/// Initialises ODE once and registers the geom class; returns its number.
int geom_class() {
  static const int number = [] {
    dInitODE2(0);
    dGeomClass c{};
    c.bytes = sizeof(GeomBounds);
    c.collider = &no_collider;
    c.aabb = &bounds_callback;
    return dCreateGeomClass(&c);
  }();
  dAllocateODEDataForThread(dAllocateMaskAll);
  return number;
}

enum class Kind { hash, sap };

template <class F>
void pair_callback(void* data, dGeomID a, dGeomID b) {
  (*static_cast<F*>(data))(slot_of(dGeomGetData(a)), slot_of(dGeomGetData(b)));
}

template <class F>
struct QueryContext {
  F& filter;
  dGeomID query;
};

template <class F>
void query_callback(void* data, dGeomID a, dGeomID b) {
  auto& ctx = *static_cast<QueryContext<F>*>(data);
  ctx.filter(slot_of(dGeomGetData(a == ctx.query ? b : a)));
}

/// One ODE space behind the Structure interface.
/// insert: a geom added to the space; remove: dGeomDestroy; update: new
/// bounds, geom marked dirty (O(1)). for_each_pair: dSpaceCollide, which
/// does ODE's per-step work (AABBs, hash table or sort) and cannot stop
/// early: after a stop the remaining candidates are ignored. query:
/// dSpaceCollide2 of a query geom with the space (ODE tests it against every
/// geom). Queries mutate ODE's state: not thread-safe.
template <Kind K>
class OdeBroadPhase : public PeerBase<dGeomID> {
 public:
  explicit OdeBroadPhase(const Config& c) : class_(geom_class()) {
    OptionReader options(c, K == Kind::hash ? "ode-hash" : "ode-sap");
    if constexpr (K == Kind::hash) {
      const Aabb& w = c.world;
      const double side = std::max({w.hi.x - w.lo.x, w.hi.y - w.lo.y, w.hi.z - w.lo.z});
      const int top = static_cast<int>(std::ceil(std::log2(side)));
      const int maxlevel = static_cast<int>(options.number("maxlevel", top, -60, 60));
      const int minlevel =
          static_cast<int>(options.number("minlevel", maxlevel - 12, -60, maxlevel));
      space_ = dHashSpaceCreate(nullptr);
      dHashSpaceSetLevels(space_, minlevel, maxlevel);
    } else {
      space_ = dSweepAndPruneSpaceCreate(nullptr, dSAP_AXES_XYZ);
    }
    options.finish();
    query_ = dCreateGeom(class_);
  }
  ~OdeBroadPhase() {
    dGeomDestroy(query_);
    dSpaceDestroy(space_);  // destroys the geoms it holds
  }
  OdeBroadPhase(const OdeBroadPhase&) = delete;
  OdeBroadPhase& operator=(const OdeBroadPhase&) = delete;

  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic) {
    Handle h;
    const std::uint32_t slot = add(s, user, h);
    const dGeomID g = dCreateGeom(class_);
    dGeomSetData(g, tag_of(slot));
    place(g, s);
    dSpaceAdd(space_, g);
    native_[slot] = g;
    return h;
  }
  void remove(Handle h) { dGeomDestroy(take(h)); }
  void update(Handle h, const Shape& s) { place(native_[store_.set_shape(h, s)], s); }
  void update(std::span<const Move> moves) {
    check_moves(*this, moves);  // all-or-nothing, as the interface asks
    for (const Move& m : moves) place(native_[store_.set_shape(m.handle, m.shape)], m.shape);
  }

  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    QueryFilter<V> filter(store_, q, visitor);
    place(query_, q);
    QueryContext<QueryFilter<V>> ctx{filter, query_};
    dSpaceCollide2(query_, reinterpret_cast<dGeomID>(space_), &ctx,
                   &query_callback<QueryFilter<V>>);
    return filter.cost();
  }

  template <class V>
  QueryCost for_each_pair(V&& visitor) const {
    return this->with_filters(visitor, [this](auto& v) { return walk_pairs(v); });
  }
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    PairFilter<V> filter(store_, visitor);
    dSpaceCollide(space_, &filter, &pair_callback<PairFilter<V>>);
    return filter.cost();
  }

  /// Our bookkeeping only: ODE's allocations (geoms, hash tables) are not
  /// visible through its API and are not counted.
  std::size_t memory_bytes() const { return own_bytes(); }

  /// Checks the slots, the space's geom count, each geom's tag and bounds.
  void validate() const {
    validate_slots(K == Kind::hash ? "ode-hash" : "ode-sap",
                   static_cast<std::size_t>(dSpaceGetNumGeoms(space_)));
    for (std::uint32_t i = 0; i < native_.size(); ++i) {
      if (native_[i] == nullptr) continue;
      if (slot_of(dGeomGetData(native_[i])) != i || dGeomGetSpace(native_[i]) != space_)
        throw std::logic_error("ode: a geom carries the wrong slot or space");
      const Aabb b = bounds(store_.shape(i));
      const dReal* a = static_cast<const GeomBounds*>(dGeomGetClassData(native_[i]))->aabb;
      for (int k = 0; k < 3; ++k)
        if (a[2 * k] > b.lo[k] || a[2 * k + 1] < b.hi[k])
          throw std::logic_error("ode: a geom's AABB does not contain its bounds");
    }
  }

 private:
  /// Stores the shape's bounds as the geom's AABB and marks the geom dirty.
  /// The sweep-and-prune space sorts AABB minima converted to float: it gets
  /// `bounds_f()` (already floats, converted exactly), the hash space the
  /// double `bounds()`.
  static void place(dGeomID g, const Shape& s) {
    dReal* a = static_cast<GeomBounds*>(dGeomGetClassData(g))->aabb;
    if constexpr (K == Kind::sap) {
      const AabbF b = bounds_f(s);
      for (int k = 0; k < 3; ++k) {
        a[2 * k] = b.lo[k];
        a[2 * k + 1] = b.hi[k];
      }
    } else {
      const Aabb b = bounds(s);
      for (int k = 0; k < 3; ++k) {
        a[2 * k] = b.lo[k];
        a[2 * k + 1] = b.hi[k];
      }
    }
    dGeomSetPosition(g, s.center.x, s.center.y, s.center.z);
  }

  int class_;
  dSpaceID space_ = nullptr;
  dGeomID query_ = nullptr;
};

}  // namespace

void register_ode(Registry& r) {
  add_peer<OdeBroadPhase<Kind::hash>>(
      r, "ode-hash",
      "ODE dHashSpace: multi-resolution hashed grid rebuilt by dSpaceCollide, options "
      "minlevel=, maxlevel= (memory: adapter only)");
  add_peer<OdeBroadPhase<Kind::sap>>(
      r, "ode-sap",
      "ODE dSweepAndPruneSpace: sort and sweep on x rebuilt by dSpaceCollide "
      "(memory: adapter only)");
}

}  // namespace broadphase::app::peers
