// Bullet's broad phases: btDbvtBroadphase (two dynamic AABB trees, a fixed
// and a dynamic set) and bt32BitAxisSweep3 (incremental sweep and prune on
// quantised 32-bit end points). Both keep a persistent overlapping-pair cache
// that is updated as proxies are created and moved; the adapter reads that
// cache and filters it exactly.
//
// Bullet stores bounds in float: the adapter passes `bounds_f()` (rounded
// outwards). The axis sweep quantises positions inside a fixed world box; it
// is given Config::world enlarged by half its largest side on every side, and
// every bound is clamped into a box strictly inside it (see `clamp_`): end
// points outside the world would otherwise land on the sweep's sentinel
// position and corrupt its edge arrays when removed. Clamping is monotone, so
// an overlapping pair still overlaps after clamping (objects far outside just
// become extra candidates, rejected by the exact test).
#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "peer_common.hpp"

namespace broadphase::app::peers {

namespace {

btVector3 to_bt(const float v[3]) { return {v[0], v[1], v[2]}; }

/// Calls a filter for every proxy an AABB query reports.
template <class F>
struct AabbVisitor final : btBroadphaseAabbCallback {
  explicit AabbVisitor(F& f) : filter(f) {}
  bool process(const btBroadphaseProxy* proxy) override {
    return filter(slot_of(proxy->m_clientObject));
  }
  F& filter;
};

enum class Kind { dbvt, sweep };

/// One Bullet broad phase behind the Structure interface.
/// insert, remove, update: Bullet's createProxy, destroyProxy, setAabb (each
/// updates the pair cache at once). update(span): setAabb for every move,
/// then calculateOverlappingPairs, as btCollisionWorld does once per step.
/// for_each_pair: reads the pair cache, O(cached pairs). query: aabbTest.
/// Not thread-safe (queries go through the library's non-const interface).
template <Kind K>
class BulletBroadPhase : public PeerBase<btBroadphaseProxy*> {
 public:
  explicit BulletBroadPhase(const Config& c) {
    OptionReader options(c, K == Kind::dbvt ? "bullet-dbvt" : "bullet-sweep32");
    if constexpr (K == Kind::sweep) {
      accelerator_ = options.choice("accelerator", "on", {"on", "off"}) == "on";
      const Aabb& w = c.world;
      const double grow = 0.5 * std::max({w.hi.x - w.lo.x, w.hi.y - w.lo.y, w.hi.z - w.lo.z});
      for (int a = 0; a < 3; ++a) {
        clamp_lo_[a] = round_down(w.lo[a] - grow);
        clamp_hi_[a] = round_up(w.hi[a] + grow);
        // The sweep's own box leaves a margin of 1/64 of its size around the
        // clamp box, so clamped end points never quantise to 0 or the sentinel.
        const float margin = (clamp_hi_[a] - clamp_lo_[a]) / 64;
        world_lo_[a] = clamp_lo_[a] - margin;
        world_hi_[a] = clamp_hi_[a] + margin;
      }
      capacity_ = static_cast<unsigned>(
          std::clamp<std::size_t>(c.expected_objects + c.expected_objects / 4, 1024, kMaxHandles));
    }
    options.finish();
    bp_ = make_broadphase();
  }
  ~BulletBroadPhase() { release_all(); }
  BulletBroadPhase(const BulletBroadPhase&) = delete;
  BulletBroadPhase& operator=(const BulletBroadPhase&) = delete;

  /// Creates a proxy. O(log n) for the tree, O(n) worst case for the sweep
  /// (edges move along the axes); may rebuild the sweep with twice the handles.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic) {
    if constexpr (K == Kind::sweep) {
      if (store_.size() >= capacity_) grow();
    }
    Handle h;
    const std::uint32_t slot = add(s, user, h);
    native_[slot] = create_proxy(slot, s);
    return h;
  }
  /// Destroys the proxy (and its cached pairs).
  void remove(Handle h) { bp_->destroyProxy(take(h), nullptr); }
  /// Moves the proxy with setAabb.
  void update(Handle h, const Shape& s) {
    const std::uint32_t i = store_.set_shape(h, s);
    set_aabb(i, s);
  }
  /// setAabb for every move, then Bullet's per-step calculateOverlappingPairs.
  void update(std::span<const Move> moves) {
    check_moves(*this, moves);  // all-or-nothing, as the interface asks
    for (const Move& m : moves) set_aabb(store_.set_shape(m.handle, m.shape), m.shape);
    bp_->calculateOverlappingPairs(nullptr);
  }

  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    QueryFilter<V> filter(store_, q, visitor);
    AabbVisitor<QueryFilter<V>> callback(filter);
    btVector3 lo, hi;
    bt_bounds(q, lo, hi);
    bp_->aabbTest(lo, hi, callback);
    return filter.cost();
  }

  /// Walks Bullet's overlapping-pair cache. The cache holds each pair once
  /// (a hash set of proxy pairs); the tree also keeps pairs whose fattened
  /// leaves still touch, which the exact test rejects.
  template <class V>
  QueryCost for_each_pair(V&& visitor) const {
    PairFilter<V> filter(store_, visitor);
    btBroadphasePairArray& pairs = bp_->getOverlappingPairCache()->getOverlappingPairArray();
    for (int k = 0; k < pairs.size(); ++k) {
      if (!filter(slot_of(pairs[k].m_pProxy0->m_clientObject),
                  slot_of(pairs[k].m_pProxy1->m_clientObject)))
        break;
    }
    return filter.cost();
  }

  /// Our bookkeeping plus an estimate of Bullet's: its allocations are not
  /// visible, so proxies, tree nodes, sweep edges and the pair array are
  /// counted from their sizes.
  std::size_t memory_bytes() const {
    const std::size_t pairs =
        static_cast<std::size_t>(
            bp_->getOverlappingPairCache()->getOverlappingPairArray().capacity()) *
        (sizeof(btBroadphasePair) + 2 * sizeof(int));
    const std::size_t tree = store_.size() * (sizeof(btDbvtProxy) + 2 * sizeof(btDbvtNode));
    if constexpr (K == Kind::dbvt) {
      return own_bytes() + pairs + tree;
    } else {
      using Sweep = btAxisSweep3Internal<unsigned>;
      const std::size_t sweep =
          (std::size_t{capacity_} + 1) * (sizeof(Sweep::Handle) + 3 * 2 * sizeof(Sweep::Edge));
      return own_bytes() + pairs + sweep + (accelerator_ ? tree : 0);
    }
  }

  /// Checks that every live slot has a proxy tagged with that slot and that
  /// Bullet holds as many proxies as we have objects.
  void validate() const {
    std::size_t count = 0;
    if constexpr (K == Kind::dbvt) {
      const auto& dbvt = static_cast<const btDbvtBroadphase&>(*bp_);
      count = static_cast<std::size_t>(dbvt.m_sets[0].m_leaves + dbvt.m_sets[1].m_leaves);
    } else {
      count = static_cast<const bt32BitAxisSweep3&>(*bp_).getNumHandles();
    }
    validate_slots(K == Kind::dbvt ? "bullet-dbvt" : "bullet-sweep32", count);
    for (std::uint32_t i = 0; i < native_.size(); ++i)
      if (native_[i] != nullptr && slot_of(native_[i]->m_clientObject) != i)
        throw std::logic_error("bullet: a proxy carries the wrong slot");
  }

 private:
  // Leaves room for the sweep's sentinel handle and its doubled edge count.
  static constexpr std::size_t kMaxHandles = 0x3ffffffe;

  std::unique_ptr<btBroadphaseInterface> make_broadphase() const {
    if constexpr (K == Kind::dbvt) {
      return std::make_unique<btDbvtBroadphase>();
    } else {
      return std::make_unique<bt32BitAxisSweep3>(to_bt(world_lo_), to_bt(world_hi_), capacity_,
                                                 nullptr, !accelerator_);
    }
  }

  void bt_bounds(const Shape& s, btVector3& lo, btVector3& hi) const {
    AabbF b = bounds_f(s);
    if constexpr (K == Kind::sweep) {
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::clamp(b.lo[a], clamp_lo_[a], clamp_hi_[a]);
        b.hi[a] = std::clamp(b.hi[a], clamp_lo_[a], clamp_hi_[a]);
      }
    }
    lo = to_bt(b.lo);
    hi = to_bt(b.hi);
  }

  btBroadphaseProxy* create_proxy(std::uint32_t slot, const Shape& s) {
    btVector3 lo, hi;
    bt_bounds(s, lo, hi);
    // Every object collides with every other: one filter group, all masks.
    return bp_->createProxy(lo, hi, BOX_SHAPE_PROXYTYPE, tag_of(slot),
                            btBroadphaseProxy::DefaultFilter, btBroadphaseProxy::AllFilter,
                            nullptr);
  }

  void set_aabb(std::uint32_t slot, const Shape& s) {
    btVector3 lo, hi;
    bt_bounds(s, lo, hi);
    bp_->setAabb(native_[slot], lo, hi, nullptr);
  }

  void release_all() {
    for (btBroadphaseProxy*& p : native_) {
      if (p != nullptr) bp_->destroyProxy(p, nullptr);
      p = nullptr;
    }
  }

  /// The sweep allocates its handles up front and cannot grow: a full sweep
  /// is replaced by one with twice the handles, every proxy created again.
  void grow() {
    if (capacity_ >= kMaxHandles) throw std::length_error("bullet-sweep32: too many objects");
    release_all();
    capacity_ =
        static_cast<unsigned>(std::min<std::size_t>(std::size_t{capacity_} * 2, kMaxHandles));
    bp_ = make_broadphase();
    for (std::uint32_t i = 0; i < native_.size(); ++i)
      if (store_.slots().alive(i)) native_[i] = create_proxy(i, store_.shape(i));
  }

  std::unique_ptr<btBroadphaseInterface> bp_;
  bool accelerator_ = true;
  unsigned capacity_ = 0;
  float clamp_lo_[3] = {}, clamp_hi_[3] = {};
  float world_lo_[3] = {}, world_hi_[3] = {};
};

}  // namespace

void register_bullet(Registry& r) {
  add_peer<BulletBroadPhase<Kind::dbvt>>(
      r, "bullet-dbvt",
      "Bullet btDbvtBroadphase: two dynamic AABB trees and a persistent pair cache "
      "(float bounds; memory is an estimate)");
  add_peer<BulletBroadPhase<Kind::sweep>>(
      r, "bullet-sweep32",
      "Bullet bt32BitAxisSweep3: incremental sweep and prune on quantised end points in a "
      "fixed world box, option accelerator=on|off (its ray/AABB-query tree; memory is an "
      "estimate)");
}

}  // namespace broadphase::app::peers
