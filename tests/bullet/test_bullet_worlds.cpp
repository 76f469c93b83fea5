// BulletBroadphase in Bullet worlds built with Bullet's API alone: one
// trajectory under btDbvtBroadphase with ours as its shadow (the exact
// pairs of Bullet's cache are ours every step, every touching contact is
// in our pairs), worlds driven by ours (the cache is brute force every
// step, ghost objects see exactly their overlaps), and the world's rayTest
// and convexSweepTest against the dbvt's.
#include <BulletCollision/NarrowPhaseCollision/btRaycastCallback.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/bullet.hpp>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "bullet_checks.hpp"
#include "bullet_worlds.hpp"
#include "testing.hpp"

namespace {

using broadphase::BulletBroadphase;
using namespace broadphase::bullet_testing;

/// Mirrors every call of Bullet's broad phase (the world's, `primary`) to
/// ours (the shadow, with a hashed cache of its own), so that one
/// trajectory drives both.
class Tee final : public btBroadphaseInterface {
 public:
  Tee(btBroadphaseInterface* primary, btBroadphaseInterface* shadow)
      : primary_(primary), shadow_(shadow) {}
  btBroadphaseProxy* createProxy(const btVector3& lo, const btVector3& hi, int type, void* user,
                                 int group, int mask, btDispatcher* d) override {
    btBroadphaseProxy* p = primary_->createProxy(lo, hi, type, user, group, mask, d);
    twin_[p] = shadow_->createProxy(lo, hi, type, user, group, mask, nullptr);
    return p;
  }
  void destroyProxy(btBroadphaseProxy* p, btDispatcher* d) override {
    shadow_->destroyProxy(twin_.at(p), nullptr);
    twin_.erase(p);
    primary_->destroyProxy(p, d);
  }
  void setAabb(btBroadphaseProxy* p, const btVector3& lo, const btVector3& hi,
               btDispatcher* d) override {
    primary_->setAabb(p, lo, hi, d);
    btBroadphaseProxy* s = twin_.at(p);
    s->m_collisionFilterGroup = p->m_collisionFilterGroup;
    s->m_collisionFilterMask = p->m_collisionFilterMask;
    shadow_->setAabb(s, lo, hi, nullptr);
  }
  void getAabb(btBroadphaseProxy* p, btVector3& lo, btVector3& hi) const override {
    primary_->getAabb(p, lo, hi);
  }
  void rayTest(const btVector3& from, const btVector3& to, btBroadphaseRayCallback& cb,
               const btVector3& lo, const btVector3& hi) override {
    primary_->rayTest(from, to, cb, lo, hi);
  }
  void aabbTest(const btVector3& lo, const btVector3& hi, btBroadphaseAabbCallback& cb) override {
    primary_->aabbTest(lo, hi, cb);
  }
  void calculateOverlappingPairs(btDispatcher* d) override {
    primary_->calculateOverlappingPairs(d);
    shadow_->calculateOverlappingPairs(nullptr);
  }
  btOverlappingPairCache* getOverlappingPairCache() override {
    return primary_->getOverlappingPairCache();
  }
  const btOverlappingPairCache* getOverlappingPairCache() const override {
    return primary_->getOverlappingPairCache();
  }
  void getBroadphaseAabb(btVector3& lo, btVector3& hi) const override {
    primary_->getBroadphaseAabb(lo, hi);
  }
  void printStats() override {}
  btBroadphaseInterface& shadow() { return *shadow_; }
  ~Tee() override {
    delete primary_;
    delete shadow_;
  }

 private:
  btBroadphaseInterface* primary_;
  btBroadphaseInterface* shadow_;
  std::map<btBroadphaseProxy*, btBroadphaseProxy*> twin_;
};

/// Every proxy of a world's broad phase, from its objects.
std::vector<btBroadphaseProxy*> proxies_of(btCollisionWorld& w) {
  std::vector<btBroadphaseProxy*> out;
  for (int i = 0; i < w.getNumCollisionObjects(); ++i)
    out.push_back(w.getCollisionObjectArray()[i]->getBroadphaseHandle());
  return out;
}

/// The ghost's overlapping objects as the ghost sees them.
std::set<const void*> ghost_set(btPairCachingGhostObject& g) {
  std::set<const void*> out;
  for (int i = 0; i < g.getNumOverlappingObjects(); ++i) out.insert(g.getOverlappingObject(i));
  return out;
}
/// Brute force: the objects whose boxes overlap the ghost's and pass the filters.
std::set<const void*> ghost_expected(btCollisionWorld& w, btPairCachingGhostObject& g) {
  std::set<const void*> out;
  const btBroadphaseProxy& gp = *g.getBroadphaseHandle();
  for (btBroadphaseProxy* p : proxies_of(w))
    if (p != &gp && boxes_overlap(*p, gp) && groups_pass(*p, gp)) out.insert(p->m_clientObject);
  return out;
}

constexpr WorldKind kWorlds[] = {WorldKind::falling, WorldKind::pyramid, WorldKind::mixed,
                                 WorldKind::groups, WorldKind::ghost};

// One trajectory under btDbvtBroadphase, ours as the shadow: each step the
// pairs of Bullet's cache whose exact boxes overlap are ours, and every
// contact point at or below zero distance belongs to one of our pairs.
TEST(BulletWorlds, DbvtExactPairsAreOursEveryStep) {
  // 30 steps at least: at 15 (a tenth, under the sanitizers) the falling
  // bodies have not touched yet.
  const int steps = std::max(30, broadphase::testing::repeats(150));
  for (WorldKind kind : kWorlds) {
    const std::uint64_t seed = 11;
    SCOPED_TRACE(std::string("world ") + name_of(kind) + ", seed " + std::to_string(seed));
    btHashedOverlappingPairCache shadow_cache;
    auto* tee = new Tee(new btDbvtBroadphase(), new BulletBroadphase(&shadow_cache));
    auto w = make_world(kind, 160, seed, tee);
    std::size_t pairs_seen = 0, stale_seen = 0, contacts_seen = 0;
    for (int s = 0; s < steps; ++s) {
      w->step();
      const std::set<Pair> bullet_exact = cache_pairs(*w->world->getPairCache(), true);
      const std::set<Pair> bullet_all = cache_pairs(*w->world->getPairCache(), false);
      const std::set<Pair> ours = cache_pairs(shadow_cache, false);
      ASSERT_EQ(bullet_exact, ours) << "step " << s;
      pairs_seen += ours.size();
      stale_seen += bullet_all.size() - bullet_exact.size();
      for (int m = 0; m < w->dispatcher->getNumManifolds(); ++m) {
        const btPersistentManifold* man = w->dispatcher->getManifoldByIndexInternal(m);
        for (int c = 0; c < man->getNumContacts(); ++c) {
          if (man->getContactPoint(c).getDistance() > 0) continue;
          ++contacts_seen;
          ASSERT_TRUE(ours.count(ordered(man->getBody0(), man->getBody1())) != 0)
              << "step " << s << ": a touching contact outside our pairs";
        }
      }
    }
    EXPECT_GT(pairs_seen, 0u);
    EXPECT_GT(contacts_seen, 0u);
    std::printf(
        "%s: %zu exact pairs, %zu padded or stale dbvt pairs, %zu touching contacts over %d "
        "steps\n",
        name_of(kind), pairs_seen, stale_seen, contacts_seen, steps);
  }
}

// Ours as the world's broad phase: each step its cache (the world's) is the
// brute force over the proxies, the ghost sees exactly its overlaps, and
// the world settles as under Bullet's own (no body falls through the plane).
TEST(BulletWorlds, OursDrivesTheWorld) {
  const int steps = broadphase::testing::repeats(150);
  for (WorldKind kind : kWorlds) {
    const std::uint64_t seed = 12;
    SCOPED_TRACE(std::string("world ") + name_of(kind) + ", seed " + std::to_string(seed));
    auto w = make_world(kind, 160, seed, new BulletBroadphase());
    std::size_t filtered = 0;  // overlapping pairs the groups keep apart
    for (int s = 0; s < steps; ++s) {
      w->step();
      const auto proxies = proxies_of(*w->world);
      ASSERT_EQ(cache_pairs(*w->world->getPairCache(), false), brute_pairs(proxies, groups_pass))
          << "step " << s;
      if (kind == WorldKind::groups)
        filtered += brute_pairs(proxies, [](auto&, auto&) { return true; }).size() -
                    brute_pairs(proxies, groups_pass).size();
      if (w->ghost != nullptr) {
        ASSERT_EQ(ghost_set(*w->ghost), ghost_expected(*w->world, *w->ghost)) << "step " << s;
      }
    }
    for (int i = 0; i < w->world->getNumCollisionObjects(); ++i) {
      const btCollisionObject* o = w->world->getCollisionObjectArray()[i];
      EXPECT_GT(o->getWorldTransform().getOrigin().y(), btScalar(-1)) << "object " << i;
    }
    if (kind == WorldKind::groups) {
      EXPECT_GT(filtered, 0u);
    }
  }
}

// The same static world under both broad phases: btCollisionWorld's
// rayTest (closest hit) and convexSweepTest give the same object and the
// same fraction, bit for bit.
TEST(BulletWorlds, RayAndSweepTestsMatchDbvt) {
  auto ours = make_world(WorldKind::mixed, 300, 5, new BulletBroadphase());
  auto dbvt = make_world(WorldKind::mixed, 300, 5, new btDbvtBroadphase());
  ours->world->updateAabbs();
  dbvt->world->updateAabbs();
  ours->world->computeOverlappingPairs();
  dbvt->world->computeOverlappingPairs();
  std::mt19937_64 rng(9);
  auto uniform = [&](double lo, double hi) {
    return static_cast<btScalar>(lo + (hi - lo) * (static_cast<double>(rng() >> 11) * 0x1p-53));
  };
  auto index_of = [](const btCollisionObject* o) {
    return o == nullptr ? -1 : o->getWorldArrayIndex();
  };
  btSphereShape probe(btScalar(0.3));
  int hits = 0, sweep_hits = 0;
  for (int i = 0; i < 400; ++i) {
    const btVector3 from(uniform(-15, 15), uniform(-1, 14), uniform(-15, 15));
    const btVector3 to(uniform(-15, 15), uniform(-1, 14), uniform(-15, 15));
    btCollisionWorld::ClosestRayResultCallback a(from, to), b(from, to);
    // Bullet's default ray test against convex shapes (the subsimplex cast)
    // can report a hit several centimetres outside the object's own box,
    // which the dbvt's padded boxes reach and exact boxes do not: the GJK
    // cast stays within the shape.
    a.m_flags |= btTriangleRaycastCallback::kF_UseGjkConvexCastRaytest;
    b.m_flags |= btTriangleRaycastCallback::kF_UseGjkConvexCastRaytest;
    ours->world->rayTest(from, to, a);
    dbvt->world->rayTest(from, to, b);
    // A segment that starts inside several objects ties them at fraction 0:
    // the first one visited wins, so objects are compared beyond 0 only.
    ASSERT_EQ(a.m_closestHitFraction, b.m_closestHitFraction) << "ray " << i;
    if (a.m_closestHitFraction > 0) {
      ASSERT_EQ(index_of(a.m_collisionObject), index_of(b.m_collisionObject)) << "ray " << i;
    }
    hits += a.hasHit();
    btTransform t0, t1;
    t0.setIdentity();
    t1.setIdentity();
    t0.setOrigin(from);
    t1.setOrigin(to);
    btCollisionWorld::ClosestConvexResultCallback ca(from, to), cb(from, to);
    ours->world->convexSweepTest(&probe, t0, t1, ca);
    dbvt->world->convexSweepTest(&probe, t0, t1, cb);
    ASSERT_EQ(ca.m_closestHitFraction, cb.m_closestHitFraction) << "sweep " << i;
    if (ca.m_closestHitFraction > 0) {
      ASSERT_EQ(index_of(ca.m_hitCollisionObject), index_of(cb.m_hitCollisionObject))
          << "sweep " << i;
    }
    sweep_hits += ca.hasHit();
  }
  EXPECT_GT(hits, 50);
  EXPECT_GT(sweep_hits, 50);
}

}  // namespace
