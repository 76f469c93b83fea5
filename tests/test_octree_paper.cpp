// octree-paper: the node choice on exact cases, objects outside and larger
// than the world, removal from crowded nodes, and the invariants.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/study/octree_paper.hpp>
#include <set>
#include <utility>
#include <vector>

#include "structure_testing.hpp"
#include "testing.hpp"

namespace broadphase {
namespace {

// The 1000-unit world cube: finest cells of 125, level 2 of 250, level 1 of 500.
Config world_1000() { return Config{}; }

std::uint32_t node(int level, int x, int y, int z) {
  static constexpr std::uint32_t kStart[] = {0, 1, 9, 73};
  std::uint32_t m = 0;
  for (int b = 0; b < level; ++b)
    m |= static_cast<std::uint32_t>(((x >> b) & 1) | (((y >> b) & 1) << 1) | (((z >> b) & 1) << 2))
         << (3 * b);
  return kStart[level] + m;
}

// Pairs by user id, sorted, from the structure and by brute force.
using testing::brute;
using testing::pairs_of;

TEST(OctreePaper, LevelsOfNodeIndices) {
  EXPECT_EQ(OctreePaper::level_of(0), 0);
  EXPECT_EQ(OctreePaper::level_of(1), 1);
  EXPECT_EQ(OctreePaper::level_of(8), 1);
  EXPECT_EQ(OctreePaper::level_of(9), 2);
  EXPECT_EQ(OctreePaper::level_of(72), 2);
  EXPECT_EQ(OctreePaper::level_of(73), 3);
  EXPECT_EQ(OctreePaper::level_of(584), 3);
}

TEST(OctreePaper, ObjectGoesToTheDeepestNodeContainingItsBounds) {
  const OctreePaper t(world_1000());
  // Inside one finest cell.
  EXPECT_EQ(t.node_of(Shape::sphere({62.5, 62.5, 62.5}, 10)), node(3, 0, 0, 0));
  EXPECT_EQ(t.node_of(Shape::sphere({937.5, 937.5, 937.5}, 1)), node(3, 7, 7, 7));
  EXPECT_EQ(t.node_of(Shape::sphere({437.5, 62.5, 812.5}, 50)), node(3, 3, 0, 6));
  // Straddling x = 125 (finest cells 0|1), both in level-2 cell 0.
  EXPECT_EQ(t.node_of(Shape::sphere({125, 62.5, 62.5}, 1)), node(2, 0, 0, 0));
  // Straddling x = 250 (level-2 cells 0|1), both in level-1 cell 0.
  EXPECT_EQ(t.node_of(Shape::sphere({250, 62.5, 62.5}, 1)), node(1, 0, 0, 0));
  // Straddling y = 500: only the root contains it.
  EXPECT_EQ(t.node_of(Shape::sphere({62.5, 500, 62.5}, 1)), 0u);
  // A box straddling z = 750 only (level-2 cells 2|3 inside level-1 cell 1).
  EXPECT_EQ(t.node_of(Shape::box({700, 62.5, 750}, {10, 10, 10})), node(1, 1, 0, 1));
  // A point on a cell face: the slack of its conservative bounds crosses the
  // face, so it rises to the parent.
  EXPECT_EQ(t.node_of(Shape::sphere({125, 62.5, 62.5}, 0)), node(2, 0, 0, 0));
  // At the origin only the absolute slack (kBoundsFloor) is left: it
  // crosses the near faces, and the point lives at the root; a hair inside,
  // the bounds stay in cell 0.
  EXPECT_EQ(t.node_of(Shape::sphere({0, 0, 0}, 0)), 0u);
  EXPECT_EQ(t.node_of(Shape::sphere({1e-100, 1e-100, 1e-100}, 0)), node(3, 0, 0, 0));
}

TEST(OctreePaper, ObjectsOutsideOrLargerThanTheWorldLiveAtTheRoot) {
  const OctreePaper t(world_1000());
  EXPECT_EQ(t.node_of(Shape::sphere({1200, 500, 500}, 1)), 0u);
  EXPECT_EQ(t.node_of(Shape::sphere({-5, 62.5, 62.5}, 1)), 0u);
  EXPECT_EQ(t.node_of(Shape::sphere({1e300, 1e300, -1e300}, 1e299)), 0u);
  EXPECT_EQ(t.node_of(Shape::sphere({500, 500, 500}, 5000)), 0u);
  // Touching the far face from inside: the conservative bounds cross it.
  EXPECT_EQ(t.node_of(Shape::sphere({990, 62.5, 62.5}, 10)), 0u);
  // Touching the near face from inside: likewise.
  EXPECT_EQ(t.node_of(Shape::sphere({10, 62.5, 62.5}, 10)), 0u);
}

TEST(OctreePaper, WorldCubeIsTheWorldBoxsLargestExtent) {
  Config c;
  c.world = {{-100, 0, 0}, {100, 800, 10}};  // cube of side 800 from (-100, 0, 0)
  OctreePaper t(c);
  EXPECT_EQ(t.node_of(Shape::sphere({50, 50, 50}, 1)), node(3, 1, 0, 0));
  EXPECT_EQ(t.node_of(Shape::sphere({-50, 750, 650}, 1)), node(3, 0, 7, 6));
  // Beyond the box's z extent but inside the cube: still placed in the tree.
  EXPECT_NE(t.node_of(Shape::sphere({-50, 50, 450}, 1)), 0u);
  EXPECT_EQ(t.node_of(Shape::sphere({-150, 50, 50}, 1)), 0u);
}

TEST(OctreePaper, ExactWithObjectsEverywhere) {
  OctreePaper t(world_1000());
  std::vector<Shape> shapes = {
      Shape::sphere({62.5, 62.5, 62.5}, 10),  Shape::sphere({75, 62.5, 62.5}, 2.5),
      Shape::sphere({125, 62.5, 62.5}, 40),   Shape::sphere({500, 500, 500}, 400),
      Shape::sphere({-50, 500, 500}, 60),     Shape::sphere({500, 500, 500}, 1e5),
      Shape::box({1e300, 0, 0}, {1, 1, 1}),   Shape::box({1e300, 0.5, 0}, {1, 1, 1}),
      Shape::sphere({1000, 1000, 1000}, 0),   Shape::box({1000, 1000, 1000}, {0, 0, 0}),
      Shape::box({999, 999, 999}, {1, 1, 1}), Shape::sphere({1e7, 1e7, 1e7}, 1),
      Shape::sphere({1e7 + 2, 1e7, 1e7}, 1),  Shape::sphere({0, 0, 0}, 0),
  };
  for (std::size_t i = 0; i < shapes.size(); ++i) t.insert(shapes[i], i);
  t.validate();
  EXPECT_EQ(pairs_of(t), brute(shapes));
  for (const Shape& q : shapes) {
    std::set<std::uint64_t> got;
    t.query(q, [&](Handle h) { got.insert(t.user_data(h)); });
    std::set<std::uint64_t> want;
    for (std::size_t i = 0; i < shapes.size(); ++i)
      if (overlaps(q, shapes[i])) want.insert(i);
    EXPECT_EQ(got, want);
  }
}

TEST(OctreePaper, QueryOutsideTheWorldTestsOnlyTheRoot) {
  OctreePaper t(world_1000());
  for (int i = 0; i < 100; ++i) t.insert(Shape::sphere({62.5 + i, 62.5, 62.5}, 1), i);
  t.insert(Shape::sphere({2000, 0, 0}, 5), 100);
  std::vector<std::uint64_t> hits;
  const QueryCost c =
      t.query(Shape::sphere({2003, 0, 0}, 1), [&](Handle h) { hits.push_back(t.user_data(h)); });
  EXPECT_EQ(hits, std::vector<std::uint64_t>{100});
  EXPECT_EQ(c.tests, 1u);
}

TEST(OctreePaper, QueryTestsOnlyTheNodesOnTheWayDown) {
  OctreePaper t(world_1000());
  // One object in each finest cell of the lower corner octant, one at the root.
  int id = 0;
  for (int x = 0; x < 4; ++x)
    for (int y = 0; y < 4; ++y)
      for (int z = 0; z < 4; ++z)
        t.insert(Shape::sphere({62.5 + 125 * x, 62.5 + 125 * y, 62.5 + 125 * z}, 1), id++);
  t.insert(Shape::sphere({500, 500, 500}, 1), id++);
  const QueryCost c = t.query(Shape::sphere({62.5, 62.5, 62.5}, 1), [](Handle) {});
  EXPECT_EQ(c.tests, 2u);  // the root's object and the one in cell (0, 0, 0)
}

TEST(OctreePaper, RemovalSearchesTheNodeList) {
  OctreePaper t(world_1000());
  Rng rng(5);
  std::vector<Handle> hs;
  // 300 objects in one finest cell, 100 spread over the world.
  for (int i = 0; i < 300; ++i)
    hs.push_back(t.insert(
        Shape::sphere({rng.uniform(20, 100), rng.uniform(20, 100), rng.uniform(20, 100)}, 1), i));
  for (int i = 0; i < 100; ++i)
    hs.push_back(t.insert(
        Shape::sphere({rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, 10),
        300 + i));
  EXPECT_EQ(t.objects_at(node(3, 0, 0, 0)).size() >= 300, true);
  for (std::size_t k = 0; k < hs.size(); ++k) std::swap(hs[k], hs[k + rng.below(hs.size() - k)]);
  while (!hs.empty()) {
    const Handle h = hs.back();
    hs.pop_back();
    t.remove(h);
    EXPECT_FALSE(t.contains(h));
    EXPECT_THROW(t.remove(h), InvalidHandle);
    if (hs.size() % 37 == 0) t.validate();
  }
  EXPECT_EQ(t.size(), 0u);
  t.validate();
}

TEST(OctreePaper, UpdateMovesBetweenNodesOnlyWhenNeeded) {
  OctreePaper t(world_1000());
  const Handle h = t.insert(Shape::sphere({62.5, 62.5, 62.5}, 1), 7);
  t.update(h, Shape::sphere({63, 62.5, 62.5}, 1));
  EXPECT_EQ(t.objects_at(node(3, 0, 0, 0)).size(), 1u);
  t.update(h, Shape::sphere({500, 62.5, 62.5}, 1));
  EXPECT_TRUE(t.objects_at(node(3, 0, 0, 0)).empty());
  EXPECT_EQ(t.objects_at(0).size(), 1u);
  t.update(h, Shape::sphere({-500, 62.5, 62.5}, 1));
  t.update(h, Shape::box({937, 937, 937}, {1, 2, 3}));
  EXPECT_EQ(t.objects_at(node(3, 7, 7, 7)).size(), 1u);
  t.validate();
  EXPECT_THROW(t.update(h, Shape::sphere({0, 0, 0}, -1)), InvalidShape);
  EXPECT_EQ(t.shape(h), Shape::box({937, 937, 937}, {1, 2, 3}));
  t.validate();
}

TEST(OctreePaper, EveryPairOnceAndEarlyStop) {
  OctreePaper t(world_1000());
  const Scene s = generate(Distribution::uneven, 800, 3);
  for (std::size_t i = 0; i < s.size(); ++i) t.insert(s.objects[i], i);
  const auto got = pairs_of(t);
  EXPECT_EQ(std::adjacent_find(got.begin(), got.end()), got.end());
  EXPECT_EQ(got, brute(s.objects));
  int seen = 0;
  const QueryCost c = t.for_each_pair([&](Handle, Handle) { return ++seen < 3; });
  EXPECT_EQ(seen, 3);
  EXPECT_TRUE(c.stopped);
}

TEST(OctreePaper, MemoryCountsTheNodeListsAndTheFixedNodes) {
  OctreePaper t(world_1000());
  const std::size_t empty = t.memory_bytes();
  EXPECT_GE(empty, OctreePaper::kNodeCount * (sizeof(std::vector<std::uint32_t>) + 4));
  for (int i = 0; i < 1000; ++i) t.insert(Shape::sphere({62.5, 62.5, 62.5}, 1), i);
  EXPECT_GE(t.memory_bytes(), empty + 1000 * (4 + sizeof(Shape) + 8 + 8));
}

TEST(OctreePaper, RejectsOptions) {
  Config c;
  c.options["depth"] = "5";
  EXPECT_THROW(OctreePaper{c}, InvalidConfig);
  Config bad;
  bad.options["outside"] = "drop";
  EXPECT_THROW(OctreePaper{bad}, InvalidConfig);
}

TEST(OctreePaper, ClampPlacesOutsideObjectsByTheirClippedBounds) {
  Config c;
  c.options["outside"] = "clamp";
  OctreePaper t(c);
  // Crossing the ground: clipped, it fits the finest cell at the face.
  EXPECT_EQ(t.node_of(Shape::sphere({62.5, 10, 62.5}, 20)), node(3, 0, 0, 0));
  // Wholly outside, far away: the corner cell it is clipped to.
  EXPECT_EQ(t.node_of(Shape::sphere({-1e300, 2e12, 62.5}, 1)), node(3, 0, 7, 0));
  // Larger than the world: clipped, it is the whole cube.
  EXPECT_EQ(t.node_of(Shape::sphere({500, 500, 500}, 5000)), 0u);
  std::vector<Shape> shapes = {
      Shape::sphere({-1e300, 2e12, 62.5}, 1), Shape::sphere({-1e300, 2e12, 62.5}, 0),
      Shape::sphere({62.5, 10, 62.5}, 20),    Shape::sphere({62.5, -20, 62.5}, 10),
      Shape::sphere({-2000, 900, 62.5}, 1e6), Shape::sphere({500, 500, 500}, 5000)};
  for (std::size_t i = 0; i < shapes.size(); ++i) t.insert(shapes[i], i);
  t.validate();
  EXPECT_EQ(pairs_of(t), brute(shapes));
  // A query wholly outside still reaches the objects clipped to the face.
  std::set<std::uint64_t> got;
  t.query(Shape::sphere({62.5, -25, 62.5}, 6), [&](Handle h) { got.insert(t.user_data(h)); });
  EXPECT_EQ(got, (std::set<std::uint64_t>{3, 4, 5}));
}

TEST(OctreePaper, DifferentialOnMixedWorlds) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed)
    testing::differential("octree-paper", testing::World::mixed, 1000 + seed, 1500);
}

TEST(OctreePaper, DifferentialWithOutsideObjectsClamped) {
  Config c;
  c.options["outside"] = "clamp";
  for (testing::World w :
       {testing::World::mixed, testing::World::touching, testing::World::far, testing::World::huge})
    testing::differential("octree-paper", w, 2000 + static_cast<std::uint64_t>(w), 1200, c);
  testing::differential("octree-paper", testing::World::crowded, 2100, 2000, c);
}

}  // namespace
}  // namespace broadphase
