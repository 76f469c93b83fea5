// grid-hashed: bucket collisions, table growth, an unbounded world.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/grid_hashed.hpp>
#include <broadphase/scenes/scene.hpp>
#include <vector>

#include "structure_testing.hpp"

namespace broadphase {
namespace {

using testing::brute;
using testing::Pairs;
using testing::pairs_of;

std::vector<Shape> scattered(std::size_t n, double side, double r, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Shape> out;
  for (std::size_t i = 0; i < n; ++i)
    out.push_back(Shape::sphere(
        {rng.uniform(-side, side), rng.uniform(-side, side), rng.uniform(-side, side)},
        rng.uniform(0, r)));
  return out;
}

TEST(GridHashed, OneBucketForAllCellsIsStillExactWithoutDuplicates) {
  Config c;
  c.options["cell"] = "5";
  c.options["buckets"] = "1";
  GridHashed g(c);
  const auto shapes = scattered(300, 60, 6, 5);
  for (std::size_t i = 0; i < shapes.size(); ++i) g.insert(shapes[i], i);
  g.validate();
  EXPECT_EQ(g.cell_count(), 1u);
  EXPECT_EQ(pairs_of(g), brute(shapes));
  const Shape q = Shape::sphere({0, 0, 0}, 20);
  std::size_t hits = 0, want = 0;
  g.query(q, [&](Handle) { ++hits; });
  for (const Shape& s : shapes) want += overlaps(q, s);
  EXPECT_EQ(hits, want);
}

TEST(GridHashed, TableGrowsWithTheObjects) {
  Config c;
  c.options["cell"] = "2";
  GridHashed g(c);
  const std::size_t before = g.cell_count();
  const auto shapes = scattered(2000, 500, 1, 6);
  for (std::size_t i = 0; i < shapes.size(); ++i) g.insert(shapes[i], i);
  g.validate();
  EXPECT_GT(g.cell_count(), before);
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridHashed, WorldIsUnboundedAndMemoryDoesNotFollowIt) {
  GridHashed g;
  std::vector<Shape> shapes;
  for (int i = 0; i < 200; ++i) {
    const double base = (i % 2 ? 1e7 : -1e7) + i * 0.5;
    shapes.push_back(Shape::sphere({base, -base, base}, 1));
    g.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
  EXPECT_LT(g.memory_bytes() / shapes.size(), 2000u);
}

TEST(GridHashed, AutomaticCellFollowsThePopulation) {
  GridHashed g;
  const auto small = scattered(1000, 100, 0.5, 7);
  for (std::size_t i = 0; i < small.size(); ++i) g.insert(small[i], i);
  EXPECT_LT(g.cell_size(), 20);
  Config c;
  GridHashed big(c);
  const auto large = scattered(1000, 10000, 100, 8);
  for (std::size_t i = 0; i < large.size(); ++i) big.insert(large[i], i);
  EXPECT_GT(big.cell_size(), 50);
  EXPECT_THROW(GridHashed(Config{{}, 0, {{"cell", "-1"}}}), InvalidConfig);
}

}  // namespace
}  // namespace broadphase
