// hgrid-paper: the level and cell choice on exact cases, bucket sharing,
// objects outside and larger than the world, the oversize list, removal
// through the remembered bucket, and the invariants.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/study/hgrid_paper.hpp>
#include <set>
#include <utility>
#include <vector>

#include "structure_testing.hpp"
#include "testing.hpp"

namespace broadphase {
namespace {

// Pairs by user id, sorted, from the structure and by brute force.
using testing::brute;
using testing::pairs_of;

std::set<std::uint64_t> query_ids(const HGridPaper& g, const Shape& q) {
  std::set<std::uint64_t> ids;
  g.query(q, [&](Handle h) { ids.insert(g.user_data(h)); });
  return ids;
}
std::set<std::uint64_t> brute_query(const std::vector<Shape>& s, const Shape& q) {
  std::set<std::uint64_t> ids;
  for (std::size_t i = 0; i < s.size(); ++i)
    if (overlaps(q, s[i])) ids.insert(i);
  return ids;
}

TEST(HGridPaper, LevelsHalveTheCellFromTheWorldDown) {
  const HGridPaper g{Config{}};
  EXPECT_EQ(g.levels(), 10);
  EXPECT_EQ(g.cell_side(1), 500.0);
  EXPECT_EQ(g.cell_side(2), 250.0);
  EXPECT_EQ(g.cell_side(10), 1000.0 / 1024);
}

TEST(HGridPaper, ObjectGoesToTheFinestLevelWithCellsFourTimesItsExtent) {
  const HGridPaper g{Config{}};
  // Extent 124.8: 4 x 124.8 = 499.2 <= 500 (level 1), > 250.
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 62.4)), 1);
  // Extent 2 x 62.5 plus the bounds' slack: more than 500 / 4, oversize.
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 62.5)), 0);
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 31.2)), 2);
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 31.25)), 1);
  // The largest extent of a box decides.
  EXPECT_EQ(g.level_of(Shape::box({500, 500, 500}, {0, 0, 60})), 1);
  EXPECT_EQ(g.level_of(Shape::box({500, 500, 500}, {0.01, 0.01, 0.01})), 10);
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 0)), 10);
  // The study's sizes: diameters 1 to 100 use levels 1 to 7.
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 0.5)), 7);
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 50)), 1);
}

TEST(HGridPaper, LevelCountIsAnOption) {
  Config c;
  c.options["levels"] = "3";
  const HGridPaper g{c};
  EXPECT_EQ(g.levels(), 3);
  EXPECT_EQ(g.level_of(Shape::sphere({1, 1, 1}, 0)), 3);
  for (const char* bad : {"0", "31", "2.5", "x"}) {
    Config b;
    b.options["levels"] = bad;
    EXPECT_THROW(HGridPaper{b}, InvalidConfig) << bad;
  }
  Config unknown;
  unknown.options["cell"] = "2";
  EXPECT_THROW(HGridPaper{unknown}, InvalidConfig);
}

TEST(HGridPaper, ObjectsOutsideTheWorldUseCellsBeyondIt) {
  HGridPaper g{Config{}};
  const Handle a = g.insert(Shape::sphere({-300, 5000, 1e7}, 1), 0);
  const Handle b = g.insert(Shape::sphere({-301.5, 5000, 1e7}, 1), 1);
  EXPECT_EQ(g.level_of(a), g.level_of(Shape::sphere({0, 0, 0}, 1)));
  EXPECT_EQ(g.oversize_count(), 0u);
  EXPECT_EQ(pairs_of(g).size(), 1u);
  g.remove(b);
  g.validate();
}

TEST(HGridPaper, HugeAndFarObjectsGoToTheOversizeList) {
  HGridPaper g{Config{}};
  std::vector<Shape> shapes = {
      Shape::sphere({500, 500, 500}, 5000), Shape::sphere({1e300, 0, 0}, 1),
      Shape::sphere({1e300, 0, 0.5}, 1),    Shape::box({-1e300, 1e300, 0}, {1, 1, 1}),
      Shape::sphere({2e12, 0, 0}, 0),       Shape::sphere({10, 10, 10}, 1),
      Shape::sphere({2e12, 0, 1}, 1),       Shape::sphere({5000, 5000, 5000}, 1),
      Shape::box({0, 0, 0}, {600, 0, 0}),
  };
  for (std::size_t i = 0; i < shapes.size(); ++i) g.insert(shapes[i], i);
  g.validate();
  EXPECT_EQ(g.level_of(Shape::sphere({500, 500, 500}, 5000)), 0);
  EXPECT_EQ(g.level_of(Shape::sphere({1e300, 0, 0}, 1)), 0);
  // The bounds' slack grows with the distance from the origin, so a point
  // far away is as coarse as its slack, and its cell number stays small.
  EXPECT_EQ(g.level_of(Shape::sphere({2e12, 0, 0}, 0)), 6);
  EXPECT_EQ(g.oversize_count(), 5u);
  EXPECT_EQ(pairs_of(g), brute(shapes));
  for (const Shape& q : shapes) EXPECT_EQ(query_ids(g, q), brute_query(shapes, q));
}

TEST(HGridPaper, CellNumbersPastTwoToTheFortyGoOversize) {
  // Far from the world's corner but near the origin: no slack to coarsen it.
  Config c;
  c.world = {{1e13, 1e13, 1e13}, {1e13 + 1000, 1e13 + 1000, 1e13 + 1000}};
  HGridPaper g{c};
  EXPECT_EQ(g.level_of(Shape::sphere({0, 0, 0}, 0)), 0);
  // Inside the world the slack of 1e13 * 2^-40 makes a point level 3.
  EXPECT_EQ(g.level_of(Shape::sphere({1e13 + 5, 1e13, 1e13}, 0)), 3);
  std::vector<Shape> shapes = {Shape::sphere({0, 0, 0}, 0), Shape::sphere({0, 0, 0}, 1),
                               Shape::sphere({1e13 + 5, 1e13, 1e13}, 1),
                               Shape::sphere({1e13 + 6, 1e13, 1e13}, 1)};
  for (std::size_t i = 0; i < shapes.size(); ++i) g.insert(shapes[i], i);
  EXPECT_EQ(g.oversize_count(), 1u);  // the point; the unit sphere is level 6, cell -6.4e11
  EXPECT_EQ(pairs_of(g), brute(shapes));
  g.validate();
}

TEST(HGridPaper, EntriesOfOtherCellsInTheSameBucketAreSkipped) {
  // 64 objects in 64 distinct cells share 64 buckets: collisions are all
  // but certain, and no query may test an entry of another cell.
  HGridPaper g{Config{}};
  ASSERT_EQ(g.bucket_count(), 64u);
  std::vector<Shape> shapes;
  for (int i = 0; i < 64; ++i) {
    shapes.push_back(Shape::sphere({0.5 + 3 * (i % 8), 0.5 + 3 * (i / 8), 0.5}, 0.01));
    g.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  ASSERT_EQ(g.bucket_count(), 64u);
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    std::vector<std::uint64_t> hits;
    const QueryCost c = g.query(shapes[i], [&](Handle h) { hits.push_back(g.user_data(h)); });
    EXPECT_EQ(hits, std::vector<std::uint64_t>{i});
    EXPECT_EQ(c.tests, 1u);
  }
  const QueryCost all = g.for_each_pair([](Handle, Handle) {});
  EXPECT_EQ(all.tests, 0u);
}

TEST(HGridPaper, ThousandsInOneCell) {
  HGridPaper g{Config{}};
  Rng rng(11);
  std::vector<Shape> shapes;
  for (int i = 0; i < 2000; ++i) {
    shapes.push_back(Shape::sphere(
        {rng.uniform(100, 100.5), rng.uniform(100, 100.5), rng.uniform(100, 100.5)}, 0.05));
    g.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  g.validate();
  const auto got = pairs_of(g);
  EXPECT_EQ(std::adjacent_find(got.begin(), got.end()), got.end());
  EXPECT_EQ(got, brute(shapes));
}

TEST(HGridPaper, WideQueriesScanInsteadOfProbing) {
  HGridPaper g{Config{}};
  Rng rng(12);
  std::vector<Shape> shapes;
  for (int i = 0; i < 500; ++i) {
    const double r = i % 2 ? 0.01 : rng.uniform(0.5, 50);
    shapes.push_back(
        Shape::sphere({rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, r));
    g.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  const Shape wide = Shape::box({500, 500, 500}, {1e6, 400, 1e6});
  const QueryCost c = g.query(wide, [](Handle) {});
  EXPECT_EQ(query_ids(g, wide), brute_query(shapes, wide));
  EXPECT_LE(c.tests, shapes.size());
}

TEST(HGridPaper, RemovalWalksTheRememberedBucket) {
  HGridPaper g{Config{}};
  Rng rng(13);
  std::vector<Handle> hs;
  std::vector<Shape> kept;
  for (int i = 0; i < 600; ++i) {
    const double r = rng.uniform() < 0.05 ? 2000 : rng.uniform(0, 60);
    const Vec3 c = rng.uniform() < 0.5 ? Vec3{rng.uniform(0, 1000), rng.uniform(0, 100), 5}
                                       : Vec3{rng.uniform(-1e4, 1e4), 0, rng.uniform(0, 1000)};
    hs.push_back(g.insert(Shape::sphere(c, r), static_cast<std::uint64_t>(i)));
  }
  g.validate();
  for (std::size_t k = 0; k < hs.size(); ++k) std::swap(hs[k], hs[k + rng.below(hs.size() - k)]);
  while (!hs.empty()) {
    const Handle h = hs.back();
    hs.pop_back();
    g.remove(h);
    EXPECT_FALSE(g.contains(h));
    EXPECT_THROW(g.remove(h), InvalidHandle);
    if (hs.size() % 41 == 0) g.validate();
  }
  EXPECT_EQ(g.size(), 0u);
  EXPECT_EQ(g.oversize_count(), 0u);
}

TEST(HGridPaper, UpdateChangesLevelCellAndList) {
  HGridPaper g{Config{}};
  const Handle h = g.insert(Shape::sphere({100, 100, 100}, 1), 1);
  const Handle other = g.insert(Shape::sphere({100, 100, 100}, 1), 2);
  EXPECT_EQ(g.level_of(h), 6);
  g.update(h, Shape::sphere({100.5, 100, 100}, 1));  // same cell
  g.update(h, Shape::sphere({200, 100, 100}, 1));    // another cell
  g.update(h, Shape::sphere({200, 100, 100}, 40));   // another level
  EXPECT_EQ(g.level_of(h), 1);
  g.update(h, Shape::sphere({200, 100, 100}, 4000));  // oversize
  EXPECT_EQ(g.oversize_count(), 1u);
  EXPECT_EQ(pairs_of(g).size(), 1u);
  g.update(h, Shape::sphere({1e9, 1, 1}, 0));  // back into the table, far away
  EXPECT_EQ(g.oversize_count(), 0u);
  EXPECT_TRUE(pairs_of(g).empty());
  EXPECT_THROW(g.update(h, Shape::sphere({0, 0, 0}, std::nan(""))), InvalidShape);
  g.validate();
  g.remove(other);
  g.validate();
}

TEST(HGridPaper, TableGrowsAndKeepsEveryObject) {
  Config c;
  c.expected_objects = 10;
  HGridPaper g{c};
  const Scene s = generate(Distribution::uneven, 3000, 4);
  for (std::size_t i = 0; i < s.size(); ++i) g.insert(s.objects[i], i);
  EXPECT_GE(g.bucket_count(), 2048u);
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(s.objects));
  int seen = 0;
  EXPECT_TRUE(g.for_each_pair([&](Handle, Handle) { return ++seen < 5; }).stopped);
  EXPECT_EQ(seen, 5);
}

TEST(HGridPaper, MemoryCountsEntriesBucketsAndTheStore) {
  HGridPaper g{Config{}};
  const std::size_t empty = g.memory_bytes();
  EXPECT_GE(empty, 64 * sizeof(std::uint32_t));
  for (int i = 0; i < 1000; ++i) g.insert(Shape::sphere({i * 0.5, 1, 1}, 0.1), i);
  EXPECT_GE(g.memory_bytes(), empty + 1000 * (32 + 4 + 4 + 4 + sizeof(Shape) + 8 + 8));
}

TEST(HGridPaper, DifferentialWithFewLevels) {
  Config c;
  c.options["levels"] = "2";
  testing::differential("hgrid-paper", testing::World::mixed, 77, 1500, c);
  testing::differential("hgrid-paper", testing::World::huge, 78, 1500, c);
}

TEST(HGridPaper, DifferentialWithManyLevels) {
  Config c;
  c.options["levels"] = "30";
  testing::differential("hgrid-paper", testing::World::mixed, 79, 1500, c);
  testing::differential("hgrid-paper", testing::World::far, 80, 1500, c);
}

}  // namespace
}  // namespace broadphase
