// FCL 0.7's broad-phase collision managers: DynamicAABBTreeCollisionManager,
// SaPCollisionManager and SpatialHashingCollisionManager, all in double.
// (IntervalTreeCollisionManager is not offered: docs/peers.md says why.)
//
// Every object is an fcl::CollisionObjectd holding an axis-aligned
// fcl::Boxd whose AABB, as FCL computes it (translation ± side/2), contains
// our conservative `bounds()`: see `place()`. FCL is used as its manuals
// show: register objects, setup(), then per step move the objects
// (setTranslation + computeAABB), update(moved objects) and collide(). The
// managers' collide() reports each candidate pair once; the adapter filters
// candidates exactly. SaP's incremental insert and removal are replaced by a
// bulk registration (see `stale_`).
#include <fcl/broadphase/broadphase_SaP.h>
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/broadphase/broadphase_spatialhash.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/narrowphase/collision_object.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "peer_common.hpp"

namespace broadphase::app::peers {

namespace {

enum class Kind { tree, sap, hash };

constexpr const char* name_of(Kind k) {
  switch (k) {
    case Kind::tree:
      return "fcl-dynamic-tree";
    case Kind::sap:
      return "fcl-sap";
    case Kind::hash:
      return "fcl-spatial-hash";
  }
  return "";
}

/// An FCL object and the box geometry it owns.
struct FclObject {
  std::shared_ptr<fcl::Boxd> box;
  fcl::CollisionObjectd object;

  FclObject() : box(std::make_shared<fcl::Boxd>(0, 0, 0)), object(box) {}

  /// Makes FCL's AABB of the object contain `b`. FCL computes the AABB of an
  /// unrotated box as translation ± side/2 in double; half-extents are nudged
  /// up until that rounding covers `b` on both sides.
  void place(const Aabb& b) {
    fcl::Vector3d centre, half;
    for (int a = 0; a < 3; ++a) {
      const double c = b.lo[a] + (b.hi[a] - b.lo[a]) * 0.5;
      double h = (b.hi[a] - b.lo[a]) * 0.5;
      while (c - h > b.lo[a] || c + h < b.hi[a])
        h = std::nextafter(h, std::numeric_limits<double>::infinity());
      centre[a] = c;
      half[a] = h;
    }
    box->side = half * 2;
    box->computeLocalAABB();
    object.setTranslation(centre);
    object.computeAABB();
  }
};

template <class F>
bool pair_callback(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
  return !(*static_cast<F*>(data))(slot_of(a->getUserData()), slot_of(b->getUserData()));
}

template <class F>
struct QueryContext {
  F& filter;
  const fcl::CollisionObjectd* query;
};

template <class F>
bool query_callback(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
  auto& ctx = *static_cast<QueryContext<F>*>(data);
  return !ctx.filter(slot_of((a == ctx.query ? b : a)->getUserData()));
}

/// One FCL manager behind the Structure interface.
/// insert/remove: registerObject/unregisterObject. update: re-place the box
/// and update(object). update(span): re-place every moved box, then one
/// update(moved objects), FCL's per-step refit. query: collide(object).
/// for_each_pair: collide() (self-collision). setup() runs before queries
/// when objects were registered since the last one, so queries mutate the
/// manager: not thread-safe.
template <Kind K>
class FclBroadPhase : public PeerBase<std::unique_ptr<FclObject>> {
 public:
  explicit FclBroadPhase(const Config& c) {
    OptionReader options(c, name_of(K));
    if constexpr (K == Kind::tree) {
      manager_ = std::make_unique<fcl::DynamicAABBTreeCollisionManagerd>();
    } else if constexpr (K == Kind::sap) {
      manager_ = std::make_unique<fcl::SaPCollisionManagerd>();
    } else {
      const Aabb& w = c.world;
      const double side = std::max({w.hi.x - w.lo.x, w.hi.y - w.lo.y, w.hi.z - w.lo.z});
      const double n = static_cast<double>(std::max<std::size_t>(c.expected_objects, 1));
      cell_ = options.number("cell", side / std::cbrt(n), 1e-300, 1e300);
      const double table = options.number("table", std::max(n, 1000.0), 1, 1e9);
      manager_ = std::make_unique<fcl::SpatialHashingCollisionManager<double>>(
          cell_, fcl::Vector3d(w.lo.x, w.lo.y, w.lo.z), fcl::Vector3d(w.hi.x, w.hi.y, w.hi.z),
          static_cast<unsigned>(table));
    }
    options.finish();
  }
  ~FclBroadPhase() { manager_->clear(); }
  FclBroadPhase(const FclBroadPhase&) = delete;
  FclBroadPhase& operator=(const FclBroadPhase&) = delete;

  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic) {
    Handle h;
    const std::uint32_t slot = add(s, user, h);
    auto o = std::make_unique<FclObject>();
    o->object.setUserData(tag_of(slot));
    o->place(fcl_bounds(s));
    if constexpr (K == Kind::sap) {
      stale_ = true;
    } else {
      manager_->registerObject(&o->object);
    }
    native_[slot] = std::move(o);
    return h;
  }
  void remove(Handle h) {
    const std::unique_ptr<FclObject> o = take(h);
    if constexpr (K == Kind::sap) {
      stale_ = true;
    } else {
      manager_->unregisterObject(&o->object);
    }
  }
  void update(Handle h, const Shape& s) {
    FclObject& o = *native_[store_.set_shape(h, s)];
    o.place(fcl_bounds(s));
    moved_.assign(1, &o.object);
    refit();
  }
  void update(std::span<const Move> moves) {
    check_moves(*this, moves);  // all-or-nothing, as the interface asks
    moved_.clear();
    for (const Move& m : moves) {
      FclObject& o = *native_[store_.set_shape(m.handle, m.shape)];
      o.place(fcl_bounds(m.shape));
      moved_.push_back(&o.object);
    }
    refit();
  }

  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    QueryFilter<V> filter(store_, q, visitor);
    query_.place(fcl_bounds(q));
    QueryContext<QueryFilter<V>> ctx{filter, &query_.object};
    prepare();
    manager_->collide(&query_.object, &ctx, &query_callback<QueryFilter<V>>);
    return filter.cost();
  }

  template <class V>
  QueryCost for_each_pair(V&& visitor) const {
    return this->with_filters(visitor, [this](auto& v) { return walk_pairs(v); });
  }
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    PairFilter<V> filter(store_, visitor);
    prepare();
    manager_->collide(&filter, &pair_callback<PairFilter<V>>);
    return filter.cost();
  }

  /// Our bookkeeping and the FCL objects we allocate; the manager's own
  /// index (tree nodes, end points, hash buckets) is not visible and not
  /// counted.
  std::size_t memory_bytes() const {
    return own_bytes() + (moved_.capacity() + all_.capacity()) * sizeof(void*) +
           store_.size() * (sizeof(FclObject) + sizeof(fcl::Boxd));
  }

  /// Checks the slots, FCL's object count, each object's tag, and that each
  /// object's FCL AABB contains the object's conservative bounds.
  void validate() const {
    validate_slots(name_of(K), stale_ ? store_.size() : manager_->size());
    for (std::uint32_t i = 0; i < native_.size(); ++i) {
      if (!native_[i]) continue;
      const fcl::CollisionObjectd& o = native_[i]->object;
      if (slot_of(o.getUserData()) != i)
        throw std::logic_error("fcl: an object carries the wrong slot");
      const Aabb b = fcl_bounds(store_.shape(i));
      for (int a = 0; a < 3; ++a)
        if (o.getAABB().min_[a] > b.lo[a] || o.getAABB().max_[a] < b.hi[a])
          throw std::logic_error("fcl: an object's AABB does not contain its bounds");
    }
  }

 private:
  /// `bounds()`; for the spatial hash also padded by 2^-20 cells, because
  /// FCL's hash covers cells [floor(lo/cell), ceil(hi/cell)), which is empty
  /// for a box whose sides are flat on a cell boundary (a point object).
  Aabb fcl_bounds(const Shape& s) const {
    Aabb b = bounds(s);
    if constexpr (K == Kind::hash) {
      const double pad = cell_ * 0x1p-20;
      b.lo = b.lo - Vec3{pad, pad, pad};
      b.hi = b.hi + Vec3{pad, pad, pad};
    }
    return b;
  }

  /// Brings the manager up to date before a query: FCL's setup(), and for
  /// SaP first the bulk registration of every object (see `stale_`).
  void prepare() const {
    if (stale_) {
      manager_->clear();
      all_.clear();
      for (const auto& o : native_)
        if (o) all_.push_back(&o->object);
      manager_->registerObjects(all_);
      stale_ = false;
    }
    manager_->setup();
  }

  /// Tells the manager that the objects of `moved_` moved.
  void refit() {
    prepare();
    manager_->update(moved_);
  }

  std::unique_ptr<fcl::BroadPhaseCollisionManagerd> manager_;
  mutable FclObject query_;
  std::vector<fcl::CollisionObjectd*> moved_;
  // SaP's registerObject finds the new object's pairs only among end points
  // inside its x interval, so it misses objects whose x interval contains
  // it, and its unregisterObject reads a list node after erasing it. The
  // adapter therefore never calls either: an insertion or removal marks the
  // manager stale, and the next use registers all objects at once with
  // registerObjects on an emptied manager, whose sorted build is complete.
  mutable bool stale_ = false;
  mutable std::vector<fcl::CollisionObjectd*> all_;
  double cell_ = 0;
};

}  // namespace

void register_fcl(Registry& r) {
  add_peer<FclBroadPhase<Kind::tree>>(
      r, "fcl-dynamic-tree",
      "FCL DynamicAABBTreeCollisionManager: dynamic AABB tree, refit per update "
      "(memory: objects only)");
  add_peer<FclBroadPhase<Kind::sap>>(
      r, "fcl-sap",
      "FCL SaPCollisionManager: sweep and prune with an incremental overlap-pair list "
      "(memory: objects only)");
  add_peer<FclBroadPhase<Kind::hash>>(
      r, "fcl-spatial-hash",
      "FCL SpatialHashingCollisionManager: hashed uniform grid over Config::world, options "
      "cell=, table= (memory: objects only)");
}

}  // namespace broadphase::app::peers
