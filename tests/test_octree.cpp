// The adaptive octree: splitting and merging, objects outside or larger
// than the world, touching across midplanes, and its options.
#include <gtest/gtest.h>

#include <broadphase/octree.hpp>
#include <cstdint>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

std::size_t count_pairs(const Octree& t) {
  std::size_t n = 0;
  t.for_each_pair([&](Handle, Handle) { ++n; });
  return n;
}

TEST(Octree, SplitsPastTheThresholdAndMergesBackWhenEmptied) {
  Config c;
  c.options["split"] = "4";
  Octree t(c);
  Rng rng(3);
  std::vector<Handle> hs;
  for (int i = 0; i < 400; ++i) {
    hs.push_back(t.insert(
        Shape::sphere({rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, 1),
        static_cast<std::uint64_t>(i)));
    t.validate();
  }
  EXPECT_GT(t.node_count(), 64u);
  for (Handle h : hs) {
    t.remove(h);
    t.validate();
  }
  EXPECT_EQ(t.node_count(), 1u) << "empty children must be merged back into the root";
}

TEST(Octree, FindsObjectsOutsideAndLargerThanTheWorld) {
  Octree t;
  const Handle far = t.insert(Shape::sphere({-5000, 500, 500}, 10), 1);
  const Handle huge = t.insert(Shape::box({500, 500, 500}, {6000, 6000, 6000}), 2);
  const Handle inside = t.insert(Shape::sphere({-4995, 500, 500}, 1), 3);
  t.insert(Shape::sphere({100, 100, 100}, 1), 4);
  t.validate();
  EXPECT_EQ(count_pairs(t), 4u);  // far with inside, and huge with each of the others
  std::vector<std::uint64_t> got;
  t.query(Shape::sphere({-5000, 500, 500}, 0), [&](Handle h) { got.push_back(t.user_data(h)); });
  EXPECT_EQ(got.size(), 2u);
  t.update(far, Shape::sphere({300, 300, 300}, 10));
  t.update(huge, Shape::sphere({300, 300, 300}, 0));
  t.remove(inside);
  t.validate();
  EXPECT_EQ(count_pairs(t), 1u);
}

TEST(Octree, ReportsObjectsTouchingAcrossAMidplane) {
  // The world's centre plane x = 500 is the root's midplane: boxes touching
  // on it, and spheres touching at a point on it.
  Octree t;
  t.insert(Shape::box({499, 300, 300}, {1, 1, 1}), 0);
  t.insert(Shape::box({501, 300, 300}, {1, 1, 1}), 1);
  t.insert(Shape::sphere({499, 700, 700}, 1), 2);
  t.insert(Shape::sphere({501, 700, 700}, 1), 3);
  t.validate();
  EXPECT_EQ(count_pairs(t), 2u);
}

TEST(Octree, ThousandsOfCoincidentPointsStopAtTheMaximumDepth) {
  Octree t;
  for (int i = 0; i < 1200; ++i) t.insert(Shape::sphere({123.25, 456.5, 789.75}, 0), i);
  t.validate();
  EXPECT_EQ(count_pairs(t), 1200u * 1199u / 2);
}

TEST(Octree, UpdateInPlaceKeepsTheNode) {
  Octree t;
  const Handle h = t.insert(Shape::sphere({100, 100, 100}, 1), 0);
  const std::size_t nodes = t.node_count();
  for (int i = 0; i < 50; ++i) {
    t.update(h, Shape::sphere({100 + 0.01 * i, 100, 100}, 1));
    t.validate();
  }
  EXPECT_EQ(t.node_count(), nodes);
  EXPECT_THROW(t.update(Handle{}, Shape::sphere({0, 0, 0}, 1)), InvalidHandle);
}

TEST(Octree, RejectsBadOptions) {
  EXPECT_THROW(make_structure("octree:split=0"), InvalidConfig);
  EXPECT_THROW(make_structure("octree:depth=3"), InvalidConfig);
  Config c;
  c.world = {{0, 0, 0}, {-1, 1, 1}};
  EXPECT_THROW(Octree{c}, std::invalid_argument);
}

TEST(Octree, MatchesNaiveAtExtremeThresholds) {
  for (const char* spec : {"octree:split=1", "octree:split=200"}) {
    for (auto w : {testing::World::mixed, testing::World::touching, testing::World::huge}) {
      testing::differential(spec, w, 11, 500);
      if (HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace broadphase
