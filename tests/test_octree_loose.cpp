// The loose octree: placement by size and centre, pruning of empty nodes,
// objects that fit nowhere, and its options.
#include <gtest/gtest.h>

#include <broadphase/octree_loose.hpp>
#include <cstdint>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

std::size_t count_pairs(const LooseOctree& t) {
  std::size_t n = 0;
  t.for_each_pair([&](Handle, Handle) { ++n; });
  return n;
}

TEST(LooseOctree, SmallObjectsGoDeeperThanLargeOnes) {
  Config c;
  c.options["depth"] = "10";
  LooseOctree t(c);
  t.insert(Shape::sphere({100, 100, 100}, 200), 0);
  const std::size_t shallow = t.node_count();
  t.insert(Shape::sphere({100, 100, 100}, 0.01), 1);
  t.validate();
  EXPECT_GT(t.node_count(), shallow + 3) << "a tiny object needs a chain of deeper nodes";
  EXPECT_EQ(count_pairs(t), 1u);
}

TEST(LooseOctree, PrunesEmptiedNodes) {
  LooseOctree t;
  Rng rng(5);
  std::vector<Handle> hs;
  for (int i = 0; i < 300; ++i)
    hs.push_back(
        t.insert(Shape::sphere({rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)},
                               rng.uniform(0, 20)),
                 static_cast<std::uint64_t>(i)));
  for (Handle h : hs) {
    t.remove(h);
    t.validate();
  }
  EXPECT_EQ(t.node_count(), 1u);
}

TEST(LooseOctree, ObjectsThatFitNowhereLiveAtTheRoot) {
  LooseOctree t;
  t.insert(Shape::sphere({1e7, 1e7, 1e7}, 1), 0);
  t.insert(Shape::sphere({1e7, 1e7, 1e7 + 2}, 1), 1);
  t.insert(Shape::box({500, 500, 500}, {1e5, 1, 1}), 2);
  EXPECT_EQ(t.node_count(), 1u);  // all three at the root
  t.insert(Shape::sphere({900, 500, 500}, 1), 3);
  t.validate();
  EXPECT_EQ(count_pairs(t), 2u);
}

TEST(LooseOctree, NeighboursAtTheSameDepthAreFoundOnce) {
  // Equal spheres in a row across many cells: each touches the next.
  LooseOctree t;
  for (int i = 0; i < 200; ++i) t.insert(Shape::sphere({1.0 + 2.0 * i, 333, 333}, 1), i);
  t.validate();
  EXPECT_EQ(count_pairs(t), 199u);
}

TEST(LooseOctree, RejectsBadOptions) {
  EXPECT_THROW(make_structure("octree-loose:k=1"), InvalidConfig);
  EXPECT_THROW(make_structure("octree-loose:depth=21"), InvalidConfig);
  EXPECT_THROW(make_structure("octree-loose:split=3"), InvalidConfig);
}

TEST(LooseOctree, MatchesNaiveWithOtherFactorsAndDepths) {
  for (const char* spec : {"octree-loose:k=1.1", "octree-loose:k=4", "octree-loose:depth=0",
                           "octree-loose:depth=20"}) {
    for (auto w : {testing::World::mixed, testing::World::touching, testing::World::huge}) {
      testing::differential(spec, w, 13, 400);
      if (HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace broadphase
