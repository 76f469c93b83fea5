// BulletBroadphase against brute force and against Bullet's own broad
// phases, through Bullet's API: its pair caches (hashed, sorted, null), a
// user's filter callback, ghost objects, rayTest, aabbTest and stepped
// worlds. Every random run prints its seed (SCOPED_TRACE).
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/registry.hpp>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "bullet_checks.hpp"
#include "testing.hpp"

namespace {
using broadphase::BulletBroadphase;
using broadphase::BulletOptions;
using namespace broadphase::bullet_testing;

/// A user's filter callback: pairs only client numbers of equal parity.
struct ParityFilter final : btOverlapFilterCallback {
  bool needBroadphaseCollision(btBroadphaseProxy* a, btBroadphaseProxy* b) const override {
    return (reinterpret_cast<std::uintptr_t>(a->m_clientObject) & 1) ==
           (reinterpret_cast<std::uintptr_t>(b->m_clientObject) & 1);
  }
};

struct Collect final : btBroadphaseRayCallback {
  std::set<const void*> seen;
  bool process(const btBroadphaseProxy* p) override {
    seen.insert(p->m_clientObject);
    return true;
  }
};

enum class CacheKind { hashed, sorted, null, filtered };

const char* name_of(CacheKind k) {
  switch (k) {
    case CacheKind::hashed:
      return "hashed";
    case CacheKind::sorted:
      return "sorted";
    case CacheKind::null:
      return "null";
    case CacheKind::filtered:
      return "hashed+filter";
  }
  return "?";
}

std::unique_ptr<btOverlappingPairCache> make_cache(CacheKind k) {
  switch (k) {
    case CacheKind::sorted:
      return std::make_unique<btSortedOverlappingPairCache>();
    case CacheKind::null:
      return std::make_unique<btNullPairCache>();
    default:
      return std::make_unique<btHashedOverlappingPairCache>();
  }
}

/// Random proxies created, moved, refiltered and destroyed; after every
/// pass the cache holds exactly the brute-force pairs, and aabbTest and
/// rayTest report what brute force says.
void random_run(const std::string& spec, CacheKind kind, std::uint64_t seed, int rounds) {
  SCOPED_TRACE("structure " + spec + ", cache " + name_of(kind) + ", seed " + std::to_string(seed));
  std::mt19937_64 rng(seed);
  auto uniform = [&](double lo, double hi) {
    return static_cast<btScalar>(lo + (hi - lo) * (static_cast<double>(rng() >> 11) * 0x1p-53));
  };
  auto cache = make_cache(kind);
  ParityFilter parity;
  if (kind == CacheKind::filtered) cache->setOverlapFilterCallback(&parity);
  // Margins of 0 (the structure holds the exact boxes) and Bullet's 0.05.
  BulletBroadphase bp(cache.get(), BulletOptions{spec, {}, seed % 2 == 0 ? 0.0 : 0.05});
  std::vector<btBroadphaseProxy*> proxies;
  std::uintptr_t next_client = 1;
  auto random_box = [&](btVector3& lo, btVector3& hi) {
    // Boxes on a coarse lattice of floats half of the time, so that many
    // touch exactly; the rest anywhere, a few large.
    for (int a = 0; a < 3; ++a) {
      const bool lattice = (rng() & 1) != 0;
      const btScalar c =
          lattice ? btScalar(static_cast<int>(rng() % 40)) * btScalar(0.5) : uniform(0, 20);
      const btScalar h = lattice ? btScalar(static_cast<int>(rng() % 4)) * btScalar(0.25)
                                 : (rng() % 16 == 0 ? uniform(0, 8) : uniform(0, 1));
      lo[a] = c - h;
      hi[a] = c + h;
    }
    if (rng() % 40 == 0) {  // as wide as a plane on one axis: kept apart from the structure
      const int a = static_cast<int>(rng() % 3);
      lo[a] = btScalar(-1e18);
      hi[a] = btScalar(1e18);
    }
  };
  auto random_filter = [&](int& group, int& mask) {
    group = 1 << (rng() % 4);
    mask = (rng() % 3 == 0) ? -1 : static_cast<int>(rng() & 0xf);
  };
  for (int round = 0; round < rounds; ++round) {
    const int ops = 1 + static_cast<int>(rng() % 40);
    for (int op = 0; op < ops; ++op) {
      const unsigned what = static_cast<unsigned>(rng() % 10);
      if (what < 3 || proxies.size() < 4) {
        btVector3 lo, hi;
        random_box(lo, hi);
        int group, mask;
        random_filter(group, mask);
        proxies.push_back(bp.createProxy(lo, hi, BOX_SHAPE_PROXYTYPE,
                                         reinterpret_cast<void*>(next_client++), group, mask,
                                         nullptr));
      } else if (what < 4) {
        const std::size_t i = rng() % proxies.size();
        bp.destroyProxy(proxies[i], nullptr);
        proxies[i] = proxies.back();
        proxies.pop_back();
      } else if (what < 5) {
        btBroadphaseProxy* p = proxies[rng() % proxies.size()];
        random_filter(p->m_collisionFilterGroup, p->m_collisionFilterMask);
      } else {
        btBroadphaseProxy* p = proxies[rng() % proxies.size()];
        btVector3 lo, hi;
        if (rng() % 4 == 0) {
          random_box(lo, hi);
        } else {
          const btVector3 d(uniform(-0.3, 0.3), uniform(-0.3, 0.3), uniform(-0.3, 0.3));
          lo = p->m_aabbMin + d;
          hi = p->m_aabbMax + d;
        }
        bp.setAabb(p, lo, hi, nullptr);
      }
    }
    bp.calculateOverlappingPairs(nullptr);
    bp.validate();
    ASSERT_EQ(bp.proxy_count(), proxies.size());
    if (kind == CacheKind::null) {
      EXPECT_EQ(cache->getNumOverlappingPairs(), 0);
    } else if (kind == CacheKind::filtered) {
      // The callback is asked when a pair begins; filters in the proxies
      // changed since are not (as btAxisSweep3): parity decides alone.
      const auto expected = brute_pairs(proxies, [&](btBroadphaseProxy& a, btBroadphaseProxy& b) {
        return parity.needBroadphaseCollision(&a, &b);
      });
      ASSERT_EQ(cache_pairs(*cache, false), expected) << "round " << round;
    } else {
      // Group and mask are read at every pass: a pair whose filter changed
      // follows the filter at the next pass.
      const auto got = cache_pairs(*cache, false);
      const auto expected = brute_pairs(proxies, groups_pass);
      ASSERT_EQ(got, expected) << "round " << round;
    }
    // aabbTest and rayTest against brute force.
    for (int q = 0; q < 4; ++q) {
      btVector3 lo, hi;
      random_box(lo, hi);
      Collect aabb;
      bp.aabbTest(lo, hi, aabb);
      std::set<const void*> expected;
      btBroadphaseProxy query(lo, hi, nullptr, 0, 0);
      for (btBroadphaseProxy* p : proxies)
        if (boxes_overlap(*p, query)) expected.insert(p->m_clientObject);
      ASSERT_EQ(aabb.seen, expected) << "aabbTest, round " << round;

      const btVector3 from(uniform(-2, 22), uniform(-2, 22), uniform(-2, 22));
      const btVector3 to(uniform(-2, 22), uniform(-2, 22), uniform(-2, 22));
      Collect ray;
      bp.rayTest(from, to, ray);
      const broadphase::Vec3 o{from.x(), from.y(), from.z()};
      const broadphase::Ray r{o, broadphase::Vec3{to.x(), to.y(), to.z()} - o, 1.0, 0xffffffffu};
      for (btBroadphaseProxy* p : proxies) {
        broadphase::Vec3 c, h, hg;
        for (int a = 0; a < 3; ++a) {
          c[a] = 0.5 * double(p->m_aabbMin[a]) + 0.5 * double(p->m_aabbMax[a]);
          h[a] = 0.5 * double(p->m_aabbMax[a]) - 0.5 * double(p->m_aabbMin[a]);
          hg[a] = h[a] * (1 + 0x1p-30) + 1e-12;
        }
        double t;
        const bool hit = broadphase::ray_hit(r, broadphase::Shape::box(c, h), t);
        const bool near = broadphase::ray_hit(r, broadphase::Shape::box(c, hg), t);
        const bool seen = ray.seen.count(p->m_clientObject) != 0;
        if (hit) {
          ASSERT_TRUE(seen) << "rayTest missed a box it hits, round " << round;
        }
        if (!near) {
          ASSERT_FALSE(seen) << "rayTest gave a box it misses, round " << round;
        }
      }
    }
  }
  // Whatever is left is destroyed; the cache ends empty, and resetPool
  // numbers proxies from 1 again.
  for (btBroadphaseProxy* p : proxies) bp.destroyProxy(p, nullptr);
  EXPECT_EQ(cache->getNumOverlappingPairs(), 0);
  bp.resetPool(nullptr);
  btBroadphaseProxy* p = bp.createProxy(btVector3(0, 0, 0), btVector3(1, 1, 1), BOX_SHAPE_PROXYTYPE,
                                        nullptr, 1, -1, nullptr);
  EXPECT_EQ(p->m_uniqueId, 1);
  bp.destroyProxy(p, nullptr);
}

TEST(BulletBroadphase, RandomProxiesAgainstBruteForceEveryCache) {
  const int rounds = broadphase::testing::repeats(60);
  for (CacheKind k : {CacheKind::hashed, CacheKind::sorted, CacheKind::null, CacheKind::filtered})
    for (std::uint64_t seed : {1u, 2u}) random_run("grid-verlet", k, seed, rounds);
}

TEST(BulletBroadphase, RandomProxiesOnEveryStructure) {
  const broadphase::Registry registry = broadphase::Registry::library();
  for (const broadphase::StructureInfo& info : registry.entries())
    random_run(info.name, CacheKind::hashed, 7, broadphase::testing::repeats(12));
}

TEST(BulletBroadphase, BadOptionsNameWhatIsWrong) {
  auto message = [](const BulletOptions& o) {
    try {
      BulletBroadphase bp(nullptr, o);
    } catch (const broadphase::InvalidConfig& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({"grid-verlet", {}, -1}).find("margin"), std::string::npos);
  EXPECT_NE(message({"grid-verlet", {}, std::nan("")}).find("margin"), std::string::npos);
  EXPECT_NE(message({"no-such-structure", {}, 0.05}).find("no-such-structure"), std::string::npos);
  EXPECT_NE(message({"grid-verlet:cell=-3", {}, 0.05}).find("cell"), std::string::npos);
}

TEST(BulletBroadphase, ProxiesNumberedAsAxisSweep) {
  BulletBroadphase bp;
  btAxisSweep3 sweep(btVector3(-10, -10, -10), btVector3(10, 10, 10));
  std::vector<btBroadphaseProxy*> ours, theirs;
  std::mt19937_64 rng(3);
  for (int i = 0; i < 200; ++i) {
    if (ours.size() > 2 && rng() % 3 == 0) {
      const std::size_t k = rng() % ours.size();
      bp.destroyProxy(ours[k], nullptr);
      sweep.destroyProxy(theirs[k], nullptr);
      ours.erase(ours.begin() + static_cast<std::ptrdiff_t>(k));
      theirs.erase(theirs.begin() + static_cast<std::ptrdiff_t>(k));
    } else {
      const btVector3 lo(0, 0, 0), hi(1, 1, 1);
      ours.push_back(bp.createProxy(lo, hi, BOX_SHAPE_PROXYTYPE, nullptr, 1, -1, nullptr));
      theirs.push_back(sweep.createProxy(lo, hi, BOX_SHAPE_PROXYTYPE, nullptr, 1, -1, nullptr));
    }
    ASSERT_EQ(ours.back()->m_uniqueId, theirs.back()->m_uniqueId) << "step " << i;
  }
  for (btBroadphaseProxy* p : ours) bp.destroyProxy(p, nullptr);
  for (btBroadphaseProxy* p : theirs) sweep.destroyProxy(p, nullptr);
}

TEST(BulletBroadphase, OddBoxes) {
  // Infinite, inverted and NaN boxes: pairs follow Bullet's closed test in
  // btScalar (NaN never overlaps), nothing throws.
  btHashedOverlappingPairCache cache;
  BulletBroadphase bp(&cache);
  const btScalar inf = std::numeric_limits<btScalar>::infinity();
  const btScalar nan = std::numeric_limits<btScalar>::quiet_NaN();
  std::vector<btBroadphaseProxy*> proxies;
  auto add = [&](btVector3 lo, btVector3 hi) {
    proxies.push_back(bp.createProxy(lo, hi, BOX_SHAPE_PROXYTYPE,
                                     reinterpret_cast<void*>(proxies.size() + 1), 1, -1, nullptr));
  };
  add(btVector3(-inf, -inf, -inf), btVector3(inf, inf, inf));
  add(btVector3(0, 0, 0), btVector3(1, 1, 1));
  add(btVector3(1, 1, 1), btVector3(2, 2, 2));  // touches the second at a corner
  add(btVector3(5, 0, 0), btVector3(3, 1, 1));  // inverted on x
  add(btVector3(nan, 0, 0), btVector3(1, 1, 1));
  add(btVector3(-1e30f, 0, 0), btVector3(1e30f, 1, 1));
  add(btVector3(2, 0.5f, 0.5f), btVector3(2, 0.5f, 0.5f));  // a point on the third's face
  bp.calculateOverlappingPairs(nullptr);
  EXPECT_EQ(cache_pairs(cache, false), brute_pairs(proxies, groups_pass));
  for (btBroadphaseProxy* p : proxies) bp.destroyProxy(p, nullptr);
}

}  // namespace
