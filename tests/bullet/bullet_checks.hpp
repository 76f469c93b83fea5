// Checks shared by the Bullet tests: pair sets of a cache and of brute
// force over proxies, compared by client objects.
#pragma once

#include <btBulletCollisionCommon.h>
#include <gtest/gtest.h>

#include <set>
#include <utility>
#include <vector>

namespace broadphase::bullet_testing {

using Pair = std::pair<const void*, const void*>;  // client objects, ordered

inline Pair ordered(const void* a, const void* b) { return a < b ? Pair{a, b} : Pair{b, a}; }

inline bool boxes_overlap(const btBroadphaseProxy& a, const btBroadphaseProxy& b) {
  return a.m_aabbMin.x() <= b.m_aabbMax.x() && b.m_aabbMin.x() <= a.m_aabbMax.x() &&
         a.m_aabbMin.y() <= b.m_aabbMax.y() && b.m_aabbMin.y() <= a.m_aabbMax.y() &&
         a.m_aabbMin.z() <= b.m_aabbMax.z() && b.m_aabbMin.z() <= a.m_aabbMax.z();
}

inline bool groups_pass(const btBroadphaseProxy& a, const btBroadphaseProxy& b) {
  return (a.m_collisionFilterGroup & b.m_collisionFilterMask) != 0 &&
         (b.m_collisionFilterGroup & a.m_collisionFilterMask) != 0;
}

/// The pairs of a cache whose proxies' boxes overlap (all of them when `exact_only` is false).
inline std::set<Pair> cache_pairs(btOverlappingPairCache& cache, bool exact_only) {
  std::set<Pair> out;
  btBroadphasePairArray& pairs = cache.getOverlappingPairArray();
  for (int i = 0; i < pairs.size(); ++i) {
    const btBroadphasePair& p = pairs[i];
    if (p.m_pProxy0 == nullptr || p.m_pProxy1 == nullptr) continue;
    if (exact_only && !boxes_overlap(*p.m_pProxy0, *p.m_pProxy1)) continue;
    const bool fresh =
        out.insert(ordered(p.m_pProxy0->m_clientObject, p.m_pProxy1->m_clientObject)).second;
    EXPECT_TRUE(fresh) << "a pair is twice in the cache";
  }
  return out;
}

/// Brute force over proxies: overlapping boxes that pass `needs`.
template <class Needs>
std::set<Pair> brute_pairs(const std::vector<btBroadphaseProxy*>& proxies, Needs needs) {
  std::set<Pair> out;
  for (std::size_t i = 0; i < proxies.size(); ++i)
    for (std::size_t j = i + 1; j < proxies.size(); ++j)
      if (boxes_overlap(*proxies[i], *proxies[j]) && needs(*proxies[i], *proxies[j]))
        out.insert(ordered(proxies[i]->m_clientObject, proxies[j]->m_clientObject));
  return out;
}

}  // namespace broadphase::bullet_testing
