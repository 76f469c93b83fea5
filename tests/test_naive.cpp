// naive: the oracle itself, checked against hand-computed answers.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/naive.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <utility>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

TEST(Naive, QueriesAndPairsOnAHandMadeScene) {
  Naive n;
  const Handle a = n.insert(Shape::sphere({0, 0, 0}, 1), 10);
  const Handle b = n.insert(Shape::sphere({2, 0, 0}, 1), 11);               // touches a
  n.insert(Shape::box({10, 0, 0}, {1, 1, 1}), 12);                          // alone
  const Handle d = n.insert(Shape::box({2, 1.5, 0}, {0.5, 0.5, 0.5}), 13);  // touches b
  std::vector<std::pair<std::uint64_t, std::uint64_t>> pairs;
  const QueryCost c = n.for_each_pair([&](Handle x, Handle y) {
    pairs.emplace_back(std::min(n.user_data(x), n.user_data(y)),
                       std::max(n.user_data(x), n.user_data(y)));
  });
  std::sort(pairs.begin(), pairs.end());
  EXPECT_EQ(pairs, (std::vector<std::pair<std::uint64_t, std::uint64_t>>{{10, 11}, {11, 13}}));
  EXPECT_EQ(c.tests, 6u);
  std::vector<Handle> hits;
  EXPECT_EQ(n.query(Shape::sphere({1, 0, 0}, 0), [&](Handle h) { hits.push_back(h); }).tests, 4u);
  std::sort(hits.begin(), hits.end(), [](Handle x, Handle y) { return x.index < y.index; });
  EXPECT_EQ(hits, (std::vector<Handle>{a, b}));
  n.remove(b);
  EXPECT_FALSE(n.contains(b));
  EXPECT_TRUE(n.contains(d));
  EXPECT_EQ(n.size(), 3u);
  n.validate();
}

TEST(Naive, EarlyStop) {
  Naive n;
  for (int i = 0; i < 10; ++i) n.insert(Shape::sphere({0, 0, 0}, 1), i);
  int seen = 0;
  EXPECT_TRUE(n.for_each_pair([&](Handle, Handle) { return ++seen < 4; }).stopped);
  EXPECT_EQ(seen, 4);
  seen = 0;
  const QueryCost c = n.query(Shape::sphere({0, 0, 0}, 0), [&](Handle) {
    ++seen;
    return false;
  });
  EXPECT_TRUE(c.stopped);
  EXPECT_EQ(seen, 1);
  EXPECT_EQ(c.tests, 1u);
}

TEST(Naive, StaleHandlesThrowAndSlotsAreReused) {
  Naive n;
  const Handle a = n.insert(Shape::sphere({0, 0, 0}, 1), 1);
  n.remove(a);
  EXPECT_THROW(n.remove(a), InvalidHandle);
  EXPECT_THROW(n.update(a, Shape::sphere({0, 0, 0}, 1)), InvalidHandle);
  EXPECT_THROW(n.user_data(a), InvalidHandle);
  const Handle b = n.insert(Shape::sphere({0, 0, 0}, 1), 2);
  EXPECT_EQ(b.index, a.index);
  EXPECT_FALSE(n.contains(a));
  EXPECT_EQ(n.user_data(b), 2u);
  EXPECT_THROW(n.insert(Shape::sphere({0, 0, 0}, -1), 3), InvalidShape);
  EXPECT_EQ(n.size(), 1u);
  n.validate();
}

TEST(Naive, MatchesBruteForceOnAStudyScene) {
  const Scene s = generate(Distribution::uneven, 500, 9);
  Naive n;
  std::vector<Handle> hs;
  for (std::size_t i = 0; i < s.size(); ++i) hs.push_back(n.insert(s.objects[i], i));
  FrameDigest d;
  n.for_each_pair([&](Handle x, Handle y) {
    d.add(static_cast<std::uint32_t>(n.user_data(x)), static_cast<std::uint32_t>(n.user_data(y)));
  });
  EXPECT_EQ(d, testing::brute_force(s.objects));
  // Removing from the middle keeps the dense array consistent.
  for (std::size_t i = 0; i < hs.size(); i += 3) n.remove(hs[i]);
  n.validate();
  EXPECT_EQ(n.size(), s.size() - (s.size() + 2) / 3);
}

TEST(Naive, MemoryGrowsWithObjectsAndOptionsAreRejected) {
  Naive n;
  const std::size_t empty = n.memory_bytes();
  for (int i = 0; i < 100; ++i) n.insert(Shape::sphere({0, 0, 0}, 1), i);
  EXPECT_GE(n.memory_bytes(), empty + 100 * (8 + sizeof(Shape)));
  Config c;
  c.options["cell"] = "1";
  EXPECT_THROW(Naive{c}, InvalidConfig);
}

TEST(Options, WholeNumberOptionsRefuseFractions) {
  // A fraction given for a count or a depth is refused, not truncated.
  for (const char* spec :
       {"kdtree:leaf=2.5", "octree:split=40.5", "octree-loose:depth=3.5", "octree-linear:depth=3.5",
        "aabb-tree:max_depth=7.5", "grid-hashed:buckets=100.5", "hgrid-paper:levels=2.5",
        "grid-verlet:threads=1.5", "grid-verlet:grain=2.5"})
    EXPECT_THROW(make_structure(spec), InvalidConfig) << spec;
  for (const char* spec :
       {"kdtree:leaf=2", "octree:split=40", "octree-loose:depth=3", "octree-linear:depth=3",
        "aabb-tree:max_depth=7", "grid-hashed:buckets=100", "hgrid-paper:levels=2",
        "grid-verlet:threads=1", "grid-verlet:grain=2"})
    EXPECT_NO_THROW(make_structure(spec)) << spec;
}

}  // namespace
}  // namespace broadphase
