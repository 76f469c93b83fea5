// WitnessCache: exact yes/no answers, and hits under coherent motion.
#include <gtest/gtest.h>

#include <broadphase/naive.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/witness_cache.hpp>

#include "testing.hpp"

namespace broadphase {
namespace {

TEST(WitnessCache, AnswersExactlyAndHitsUnderCoherentMotion) {
  Scene scene = generate(Distribution::even, 600, 11);
  auto bp = make_structure("aabb-tree");
  std::vector<Handle> h;
  for (std::size_t i = 0; i < scene.size(); ++i)
    h.push_back(bp->insert(scene.objects[i], i, Motion::dynamic));
  WitnessCache cache;
  std::uint64_t yes_after_first = 0;
  for (int f = 0; f < 20; ++f) {
    if (f > 0) {
      step(scene);
      for (std::size_t i = 0; i < scene.size(); ++i)
        if (scene.is_moving(i)) bp->update(h[i], scene.objects[i]);
    }
    for (std::size_t i = 0; i < scene.size(); ++i) {
      bool want = false;
      for (std::size_t j = 0; j < scene.size() && !want; ++j)
        want = j != i && overlaps(scene.objects[i], scene.objects[j]);
      ASSERT_EQ(cache.touching(*bp, h[i]), want) << "frame " << f << " object " << i;
      yes_after_first += (want && f > 0);
    }
  }
  // A "no" is never cached (anything may move into the object), but most
  // "yes" answers after the first frame come from the witness alone.
  EXPECT_GT(static_cast<double>(cache.hits()), 0.8 * static_cast<double>(yes_after_first));
}

TEST(WitnessCache, StaleWitnessesMiss) {
  Naive n;
  const Handle a = n.insert(Shape::sphere({0, 0, 0}, 1), 0);
  const Handle b = n.insert(Shape::sphere({1, 0, 0}, 1), 1);
  WitnessCache cache;
  EXPECT_TRUE(cache.touching(n, a));
  n.remove(b);
  const Handle c = n.insert(Shape::sphere({50, 0, 0}, 1), 2);  // reuses b's slot
  EXPECT_FALSE(cache.touching(n, a));
  EXPECT_FALSE(cache.touching(n, c));
  EXPECT_EQ(cache.hits(), 0u);
  EXPECT_THROW(cache.touching(n, b), InvalidHandle);
}

TEST(WitnessCache, FollowsTheFilters) {
  // Touching counts only objects the filters let pair; a witness whose
  // filter changed is not trusted.
  for (const std::string& name : testing::library_structures()) {
    SCOPED_TRACE(name);
    auto bp = make_structure(name);
    const Handle a = bp->insert(Shape::sphere({10, 10, 10}, 1), 0, Motion::dynamic, {1, 0x3u});
    const Handle b = bp->insert(Shape::sphere({11, 10, 10}, 1), 1, Motion::dynamic, {2, 0x3u});
    const Handle c = bp->insert(Shape::sphere({9, 10, 10}, 1), 2, Motion::dynamic, {4, 0x4u});
    bp->settle();
    WitnessCache cache;
    EXPECT_TRUE(cache.touching(*bp, a));   // by b, not c
    EXPECT_FALSE(cache.touching(*bp, c));  // c pairs only with group 4
    bp->set_filter(b, {8, 0xffu});         // the witness b leaves a's mask
    EXPECT_FALSE(cache.touching(*bp, a));
    bp->set_filter(b, {2, 0x3u});
    bp->set_pair_filter([&](Handle x, Handle y) { return !(x == a || y == a); });
    EXPECT_FALSE(cache.touching(*bp, a));
    bp->set_pair_filter({});
    EXPECT_TRUE(cache.touching(*bp, a));
  }
}

}  // namespace
}  // namespace broadphase
