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
//
// Rays: cast_ray walks Bullet's own tree with rayTest (the sweep's rayTest
// walks the dbvt it keeps beside its edges, the "accelerator"; without it
// Bullet hands over every proxy, so the sweep with accelerator=off casts by
// our store's test of every object instead). The callback runs our exact
// `ray_hit` on every proxy Bullet reaches and clips `m_lambda_max` to the
// closest hit; Bullet reads that clip only between its two trees (the walk
// of one tree takes lambda_max by value), which is Bullet's cost, measured
// as is. Filters: each proxy carries the object's group and mask, which is
// Bullet's own rule (btOverlappingPairCache::needsBroadphaseCollision), so
// the pair cache holds only pairs that pass.
#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <broadphase/ray.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "peer_common.hpp"
#include "ray_peers.hpp"

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

/// Hands every proxy Bullet's ray walk reaches to our exact test, and clips
/// the walk (m_lambda_max, in the ray's own parameter t) to the hits found.
template <class V>
struct RayVisitor final : btBroadphaseRayCallback {
  RayVisitor(const ObjectStore& s, const Ray& r, V& v) : store(s), ray(r), visitor(v) {}
  bool process(const btBroadphaseProxy* proxy) override {
    if (cost.stopped) return false;  // Bullet cannot stop its walk: the rest is ignored
    const std::uint32_t slot = slot_of(proxy->m_clientObject);
    if (!store.sees(ray.mask, slot)) return true;
    if (walking && slot < clamped.size() && clamped[slot]) return true;  // tested apart
    ++cost.tests;
    double t;
    if (!ray_hit(ray.origin, ray.dir, tmax, store.shape(slot), t)) return true;
    tmax = visit_hit(visitor, store.handle(slot), t, tmax);
    if (tmax < 0) {
      cost.stopped = true;
      m_lambda_max = -1;
      return false;
    }
    m_lambda_max = lambda_above(tmax);
    return true;
  }
  /// A float clip that keeps every hit at exactly `t` (ties go to the
  /// smaller id): `t` grown by 2^-16 and rounded up, far beyond the few
  /// float ulps by which Bullet's slab test rounds the entry parameter.
  static float lambda_above(double t) {
    const double grown = t * (1 + 0x1p-16);
    if (!(grown < std::numeric_limits<float>::max())) return std::numeric_limits<float>::infinity();
    return std::nextafter(static_cast<float>(grown), std::numeric_limits<float>::infinity());
  }
  const ObjectStore& store;
  const Ray& ray;
  V& visitor;
  double tmax = 0;
  QueryCost cost;
  std::span<const std::uint8_t> clamped;  // the sweep's clamped objects, tested after the walk
  bool walking = true;
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
  void remove(Handle h) {
    if constexpr (K == Kind::sweep) {
      if (h.index < clamped_.size() && store_.contains(h)) {
        clamped_count_ -= clamped_[h.index];
        clamped_[h.index] = 0;
      }
    }
    bp_->destroyProxy(take(h), nullptr);
  }
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

  /// Casts a ray with Bullet's rayTest (the dbvt's walk, or the sweep's
  /// accelerator tree; see the file comment), our exact test on every proxy
  /// it reaches. Bullet works in float: every node is grown by a margin of
  /// 2^-16 of the ray origin's and the world's largest coordinate (rayTest's
  /// aabbMin/aabbMax, meant for swept boxes), 256 float ulps of the
  /// distances its slab test subtracts, so no object our double test hits
  /// is culled. Rays Bullet cannot represent (a coordinate beyond float's
  /// range, a direction component below float's normal range) and the sweep
  /// without its tree are cast by testing every object. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    require_valid(r);
    if (!float_ray(r) || !has_ray_tree()) return Base::cast_ray(r, visitor);
    RayVisitor<V> cb(store_, r, visitor);
    cb.tmax = r.tmax;
    if (clamped_count_ > 0) cb.clamped = clamped_;
    const btVector3 from(static_cast<float>(r.origin.x), static_cast<float>(r.origin.y),
                         static_cast<float>(r.origin.z));
    for (int a = 0; a < 3; ++a) {
      const float d = static_cast<float>(r.dir[a]);
      cb.m_rayDirectionInverse[a] = d == 0 ? static_cast<btScalar>(BT_LARGE_FLOAT) : 1 / d;
      cb.m_signs[a] = cb.m_rayDirectionInverse[a] < 0;
    }
    cb.m_lambda_max = RayVisitor<V>::lambda_above(r.tmax);
    const double o_mag =
        std::max({std::fabs(r.origin.x), std::fabs(r.origin.y), std::fabs(r.origin.z)});
    const float m =
        static_cast<float>((o_mag + scale_) * 0x1p-16) + std::numeric_limits<float>::min();
    // rayTo is not read by either walk (btDbvt::rayTestInternal ignores it).
    bp_->rayTest(from, from, cb, btVector3(-m, -m, -m), btVector3(m, m, m));
    // Objects the sweep clamped into its box are not where the tree has them.
    cb.walking = false;
    for (std::uint32_t i = 0; clamped_count_ > 0 && i < clamped_.size() && !cb.cost.stopped; ++i)
      if (clamped_[i]) cb.process(native_[i]);
    return cb.cost;
  }

  /// Changes an object's group and mask (the proxy's own words). Bullet
  /// applies its rule when a pair is added, so this proxy's cached pairs are
  /// brought in line. The tree: every proxy whose bounds meet its own (an
  /// aabbTest) is added as a pair when the rule now passes, removed when it
  /// fails, both O(1) in the hashed pair cache. The sweep: its proxy is made
  /// again, O(cached pairs) (destroyProxy scans the whole cache), because
  /// pairs added to its cache that way went missing in the randomized
  /// comparison with the oracle (1 in 50 filter changes). for_each_pair
  /// applies the rule too, so no pair cached under an old rule is reported.
  void set_filter(Handle h, Filter f) {
    const std::uint32_t i = store_.set_filter(h, f);
    if constexpr (K == Kind::sweep) {
      bp_->destroyProxy(native_[i], nullptr);
      native_[i] = create_proxy(i, store_.shape(i));
    } else {
      btBroadphaseProxy* p = native_[i];
      p->m_collisionFilterGroup = static_cast<int>(f.group);
      p->m_collisionFilterMask = static_cast<int>(f.mask);
      btOverlappingPairCache* cache = bp_->getOverlappingPairCache();
      auto sync = [&](std::uint32_t j) {
        if (j == i) return true;
        if (filters_pass(f, store_.filter(j)))
          cache->addOverlappingPair(p, native_[j]);
        else
          cache->removeOverlappingPair(p, native_[j], nullptr);
        return true;
      };
      AabbVisitor<decltype(sync)> callback(sync);
      bp_->aabbTest(p->m_aabbMin, p->m_aabbMax, callback);
    }
  }

  /// Walks Bullet's overlapping-pair cache. The cache holds each pair once
  /// (a hash set of proxy pairs); the tree also keeps pairs whose fattened
  /// leaves still touch, which the exact test rejects.
  template <class V>
  QueryCost for_each_pair(V&& visitor) const {
    PairFilter<V> filter(store_, visitor);
    btBroadphasePairArray& pairs = bp_->getOverlappingPairCache()->getOverlappingPairArray();
    const bool unfiltered = this->unfiltered();
    for (int k = 0; k < pairs.size(); ++k) {
      const std::uint32_t a = slot_of(pairs[k].m_pProxy0->m_clientObject);
      const std::uint32_t b = slot_of(pairs[k].m_pProxy1->m_clientObject);
      // Bullet applied the group/mask when it cached the pair; the user's
      // pair filter, and a filter changed since, are applied here.
      if (!unfiltered && !may_pair(a, b)) continue;
      if (!filter(a, b)) break;
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
  using Base = PeerBase<btBroadphaseProxy*>;

  bool has_ray_tree() const { return K == Kind::dbvt || accelerator_; }

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

  /// The bounds Bullet gets; true when the sweep clamped them.
  bool bt_bounds(const Shape& s, btVector3& lo, btVector3& hi) const {
    AabbF b = bounds_f(s);
    bool clamped = false;
    if constexpr (K == Kind::sweep) {
      for (int a = 0; a < 3; ++a) {
        const float l = std::clamp(b.lo[a], clamp_lo_[a], clamp_hi_[a]);
        const float h = std::clamp(b.hi[a], clamp_lo_[a], clamp_hi_[a]);
        clamped = clamped || l != b.lo[a] || h != b.hi[a];
        b.lo[a] = l;
        b.hi[a] = h;
      }
    }
    lo = to_bt(b.lo);
    hi = to_bt(b.hi);
    return clamped;
  }

  /// Bounds of object `slot` for Bullet, keeping the rays' bookkeeping:
  /// the largest coordinate (the scale of cast_ray's margin) and the
  /// objects the sweep clamped.
  void proxy_bounds(std::uint32_t slot, const Shape& s, btVector3& lo, btVector3& hi) {
    const bool clamped = bt_bounds(s, lo, hi);
    for (int a = 0; a < 3; ++a)
      scale_ = std::max({scale_, double{std::fabs(lo[a])}, double{std::fabs(hi[a])}});
    if constexpr (K == Kind::sweep) {
      if (clamped_.size() <= slot) clamped_.resize(slot + 1, 0);
      clamped_count_ += static_cast<std::size_t>(clamped) - clamped_[slot];
      clamped_[slot] = clamped;
    }
  }

  btBroadphaseProxy* create_proxy(std::uint32_t slot, const Shape& s) {
    btVector3 lo, hi;
    proxy_bounds(slot, s, lo, hi);
    // Bullet's filter words are ints with the same bits (C++20 conversion).
    const Filter f = store_.filter(slot);
    return bp_->createProxy(lo, hi, BOX_SHAPE_PROXYTYPE, tag_of(slot), static_cast<int>(f.group),
                            static_cast<int>(f.mask), nullptr);
  }

  void set_aabb(std::uint32_t slot, const Shape& s) {
    btVector3 lo, hi;
    proxy_bounds(slot, s, lo, hi);
    bp_->setAabb(native_[slot], lo, hi, nullptr);
  }

  void release_all() {
    // The pairs first: destroyProxy scans the whole pair cache for the
    // proxy's pairs, O(n · pairs) for all (minutes at 10^5 objects), where
    // removing each pair by its two proxies is a hash look-up.
    btOverlappingPairCache* cache = bp_->getOverlappingPairCache();
    btBroadphasePairArray& pairs = cache->getOverlappingPairArray();
    while (pairs.size() > 0) {
      const btBroadphasePair& last = pairs[pairs.size() - 1];
      cache->removeOverlappingPair(last.m_pProxy0, last.m_pProxy1, nullptr);
    }
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
  double scale_ = 0;                   // largest |coordinate| Bullet was given
  std::vector<std::uint8_t> clamped_;  // the sweep: slots whose bounds were clamped (1)
  std::size_t clamped_count_ = 0;
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
