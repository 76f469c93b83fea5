/// \file bullet.hpp
/// `broadphase::BulletBroadphase`: a `btBroadphaseInterface` for Bullet's
/// collision worlds, backed by any structure of the registry (`broadphase
/// list`). A Bullet program changes one line:
///
///     btBroadphaseInterface* broadphase = new broadphase::BulletBroadphase();
///
/// and keeps its dispatcher, pair cache, filter callbacks, ghost objects
/// and ray tests as they are. Built as the target `broadphase::bullet`
/// (float Bullet, Debian's default) and `broadphase::bullet_double`
/// (BT_USE_DOUBLE_PRECISION, libBullet*-float64), when libbullet-dev is
/// found; docs/bullet.md is the page for Bullet users.
///
/// Pairs. `calculateOverlappingPairs` adds to Bullet's own pair cache
/// (hashed, sorted or null; the caller's, or a hashed one of its own) each
/// pair whose proxy boxes begin to overlap, and removes each pair whose
/// boxes stop overlapping, so the cache holds exactly the pairs whose
/// boxes overlap now (closed boxes, touching counts, compared in btScalar
/// as Bullet stores them: `lo0 <= hi1 && lo1 <= hi0` on each axis; a box
/// with a NaN never overlaps). Bullet's own btDbvtBroadphase keeps more:
/// pairs of boxes fattened by a margin and a velocity prediction, dropped
/// lazily. The cache's `needsBroadphaseCollision` (group and mask, or the
/// user's btOverlapFilterCallback) is asked once when a pair begins, as
/// btAxisSweep3 does; without a filter callback, group and mask changed in
/// a proxy take effect at the next pass (a pair they forbid ends).
///
/// Proxies are numbered (m_uniqueId) as btAxisSweep3 numbers its handles:
/// 1, 2, ..., a destroyed proxy's number reused first.
///
/// Thread-safety: as Bullet's own broad phases, one thread mutates
/// (createProxy, destroyProxy, setAabb, calculateOverlappingPairs,
/// resetPool). rayTest, aabbTest, getAabb and getBroadphaseAabb only read,
/// and may run concurrently with each other when no mutation runs.
#pragma once

#include <btBulletCollisionCommon.h>

#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace broadphase {

/// The options of BulletBroadphase.
struct BulletOptions {
  /// The structure, as a registry spec (`broadphase list`; options after a
  /// colon, `grid-verlet:threads=2`). It is asked for the pairs of fat
  /// boxes of the proxies that left theirs, one query each, or for all its
  /// pairs when many did. The default is `kdtree`: on 3 000 boxes falling
  /// onto a plane, side by side, its broad phase took 0.55 ms a step
  /// (median), hgrid 0.55, grid-hashed 0.65, octree 0.69, grid-verlet 0.90,
  /// sap 1.10, against btDbvtBroadphase's 0.83 (docs/bullet.md).
  std::string structure = "kdtree";
  /// The structure's Config: the region most objects live in and the
  /// expected object count are hints; objects anywhere stay exact.
  Config config = {};
  /// The structure holds each proxy's box grown by this much on every side
  /// (and stretched by the box's travel since its last fat box, on the side
  /// it travelled to) and is told of a move only when the box leaves it
  /// (btDbvtBroadphase's fat leaves, whose margin gDbvtMargin is 0.05). Pairs stay exact
  /// whatever the margin: it trades structure queries for candidates to
  /// test. On 3 000 boxes of side 1 falling onto a plane (three runs each,
  /// alternated), 0.1 and 0.15 gave the dbvt's broad phase over ours as
  /// 1.48 and 1.47 (medians), 0.05 gave 1.32. In world units, >= 0 and
  /// finite (InvalidConfig).
  double margin = 0.1;
  /// 0 (the default): pairs of the exact boxes, over `structure`. 16 or 32:
  /// btAxisSweep3's test instead, and its order: pairs of the boxes rounded
  /// outward onto a grid of that many bits over [world_min, world_max]
  /// (boxes outside clamped to it), added and removed in Bullet's cache in
  /// the order btAxisSweep3 (16) or bt32BitAxisSweep3 (32) adds and removes
  /// them, proxies numbered alike. With Bullet's deterministic pair order
  /// (btDispatcherInfo::m_deterministicOverlappingPairs) a world stepped
  /// with it is, bit for bit, the world stepped with that Bullet sweep over
  /// the same box (tests/bullet/test_bullet_quantized.cpp). `structure`,
  /// `config` and `margin` are not used then. Other values: InvalidConfig.
  int quantized_bits = 0;
  /// The grid's world box (quantized_bits only): finite, min < max on
  /// every axis (InvalidConfig).
  btVector3 world_min = btVector3(-1000, -1000, -1000);
  btVector3 world_max = btVector3(1000, 1000, 1000);
  /// The most proxies live at once (quantized_bits only); room for all is
  /// taken at construction, as Bullet's sweep takes it. Bullet's defaults
  /// are 16 384 (btAxisSweep3) and 1 500 000 (bt32BitAxisSweep3); the
  /// count bounds the proxy numbers and changes nothing else. 1 to 32 766
  /// with 16 bits, 1 to 2^31 - 2 with 32 (InvalidConfig).
  std::uint32_t max_proxies = 16384;
};

namespace bullet_detail {
class QuantizedSweep;
}

/// A btBroadphaseInterface over one of our structures (see the file comment).
/// createProxy, setAabb: O(1) amortised here; destroyProxy: O(its pairs);
/// calculateOverlappingPairs: the structure's bulk update of the boxes that
/// left their fat box, one test of every pair of fat boxes, and one query
/// for each proxy that is new or left its fat box (docs/bullet.md).
/// Proxies stay valid until destroyProxy.
class BulletBroadphase final : public btBroadphaseInterface {
 public:
  /// Uses `cache` for the pairs (not owned; it must outlive this object) or,
  /// when null, a btHashedOverlappingPairCache of its own, as
  /// btDbvtBroadphase does. Throws broadphase::InvalidConfig for a bad
  /// structure spec or Config.
  explicit BulletBroadphase(btOverlappingPairCache* cache = nullptr,
                            const BulletOptions& options = {});
  ~BulletBroadphase() override;
  BulletBroadphase(const BulletBroadphase&) = delete;
  BulletBroadphase& operator=(const BulletBroadphase&) = delete;

  /// Adds a proxy with its box, group and mask. Its pairs appear at the
  /// next calculateOverlappingPairs.
  btBroadphaseProxy* createProxy(const btVector3& aabbMin, const btVector3& aabbMax, int shapeType,
                                 void* userPtr, int collisionFilterGroup, int collisionFilterMask,
                                 btDispatcher* dispatcher) override;
  /// Removes the proxy and, at once, its pairs from the pair cache.
  void destroyProxy(btBroadphaseProxy* proxy, btDispatcher* dispatcher) override;
  /// Sets the proxy's box; an unchanged box costs a comparison (Bullet
  /// sets every object's box every step). Pairs change at the next
  /// calculateOverlappingPairs.
  void setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin, const btVector3& aabbMax,
               btDispatcher* dispatcher) override;
  /// The box last given to createProxy or setAabb.
  void getAabb(btBroadphaseProxy* proxy, btVector3& aabbMin, btVector3& aabbMax) const override;

  /// Calls `callback.process` for every proxy whose box the segment from
  /// `rayFrom` to `rayTo` meets (the structure's exact ray cast, tmax 1 on
  /// the direction rayTo - rayFrom). With a non-zero `aabbMin`/`aabbMax`
  /// (a swept box, as convexSweepTest passes), for every proxy whose box,
  /// grown by -aabbMax below and -aabbMin above, the segment meets. Bullet's
  /// own broad phases ignore what `process` returns and so does this one. A
  /// segment the contract cannot cast (a non-finite end, a length too short
  /// or too long to square in double) is given every proxy, as
  /// btSimpleBroadphase does.
  void rayTest(const btVector3& rayFrom, const btVector3& rayTo, btBroadphaseRayCallback& callback,
               const btVector3& aabbMin = btVector3(0, 0, 0),
               const btVector3& aabbMax = btVector3(0, 0, 0)) override;
  /// Calls `callback.process` for every proxy whose box overlaps the
  /// closed box [aabbMin, aabbMax] (compared in btScalar).
  void aabbTest(const btVector3& aabbMin, const btVector3& aabbMax,
                btBroadphaseAabbCallback& callback) override;

  /// Brings the pair cache up to date: the moves since the last call go to
  /// the structure in one bulk update, the new pairs are added to the cache
  /// and the pairs that ended are removed (cleaning their algorithms
  /// through `dispatcher`).
  void calculateOverlappingPairs(btDispatcher* dispatcher) override;

  btOverlappingPairCache* getOverlappingPairCache() override { return cache_; }
  const btOverlappingPairCache* getOverlappingPairCache() const override { return cache_; }

  /// The union of all proxies' boxes; a point at the origin when there are none.
  void getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const override;
  /// With no proxy left, starts afresh: a new structure, proxy numbers from 1.
  void resetPool(btDispatcher* dispatcher) override;
  /// Prints the structure, the proxy count and the pairs of the last pass.
  void printStats() override;

  /// The structure behind the adapter (for checks and statistics); empty
  /// with quantized_bits.
  const AnyBroadPhase& structure() const { return *structure_; }
  /// Live proxies.
  std::size_t proxy_count() const;
  /// Checks the adapter's own bookkeeping after a pass (each pair in both
  /// proxies' lists, each begun pair among the candidates with its bit set
  /// and the other way round, the counts) and the structure's; throws
  /// std::logic_error naming what is broken. O(proxies + candidates); for
  /// tests. Nothing to check with quantized_bits.
  void validate() const;

 private:
  struct Proxy;
  /// What the pass reads of a proxy, in one piece: its box as Bullet
  /// stores it (btScalar), group and mask; 32 bytes in float Bullet, 64 in
  /// double, so that a candidate's test reads one cache line a proxy.
  struct alignas(sizeof(btScalar) * 8) Box {
    btScalar lo[3], hi[3];
    Filter filter;
  };
  /// A pair of proxies (by id) whose fat boxes overlap; `in` when the pair
  /// has begun (is in Bullet's cache and in both partner lists).
  struct Candidate {
    std::uint32_t a, b;
    std::uint32_t in;
  };
  void make_structure();
  Shape fatten(Proxy& p) const;
  bool begins(std::uint32_t a, std::uint32_t b) const;
  void begin_pair(Proxy* p, Proxy* q);
  void end_pair(Proxy* p, Proxy* q, btDispatcher* dispatcher);
  void end_link(Proxy* p, std::size_t i, btDispatcher* dispatcher);
  void mark_fresh(const Proxy& p);
  void remove_move(Proxy& p);
  void remove_deferred(btDispatcher* dispatcher);
  void enter_structure(Proxy& p, Motion motion);
  void leave_structure(Proxy& p);
  void add_huge(Proxy& p);
  void drop_huge(Proxy& p);
  void add_candidate(Proxy* p, Proxy* q);
  void incremental_pass(btDispatcher* dispatcher);
  void full_pass(btDispatcher* dispatcher);

  BulletOptions options_;
  std::unique_ptr<bullet_detail::QuantizedSweep> sweep_;  // quantized_bits: every call goes here
  std::unique_ptr<AnyBroadPhase> structure_;
  btOverlappingPairCache* cache_;
  bool owns_cache_;
  bool filters_apply_ = true;    // group and mask decide (no filter callback)
  bool removed_ = false;         // a pair ended in this pass (deferred removal)
  std::vector<Proxy*> by_slot_;  // structure handle index -> proxy
  std::vector<Proxy*> live_;     // every live proxy, in no order
  std::vector<Proxy*> huge_;     // proxies kept out of the structure (see bullet.cpp)
  std::vector<Move> moves_;      // boxes that left their fat box, one per proxy
  std::vector<int> free_uids_;   // numbers of destroyed proxies, reused last first
  int next_uid_ = 1;
  bool settle_due_ = false;     // inserted since the last pass
  std::size_t pair_count_ = 0;  // pairs begun and not ended
  // By proxy id (dense, reused after the pass that follows a destroy):
  std::vector<std::uint8_t> fresh_;       // kFresh: new or left its fat box; kDead: destroyed
  std::vector<Box> boxes_;                // each proxy's box, group and mask as of this pass
  std::vector<Proxy*> proxy_of_;          // null when free or destroyed
  std::vector<std::uint8_t> moved_;       // 1: box or filter changed since the last pass
  bool any_moved_ = false;                // some moved_ is 1
  std::vector<std::uint32_t> fresh_ids_;  // the ids marked in fresh_, each once
  std::vector<std::uint32_t> free_ids_;   // ids to reuse
  std::vector<Candidate> candidates_;     // every pair of fat boxes, each once
  std::vector<HandlePair> found_;         // the structure's pairs, scratch of a full pass
};

}  // namespace broadphase
