// hgrid: one level per object matched to its size, empty levels skipped,
// sizes over seven decades and far coordinates in one structure.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/hgrid.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <vector>

#include "structure_testing.hpp"

namespace broadphase {
namespace {

using testing::brute;
using testing::Pairs;
using testing::pairs_of;

TEST(HGrid, SizesOverSevenDecadesInOneWorld) {
  HGrid g;
  Rng rng(12);
  std::vector<Shape> shapes;
  std::vector<Handle> h;
  for (int i = 0; i < 1500; ++i) {
    const double r = std::pow(10.0, rng.uniform(-3, 4));
    shapes.push_back(
        Shape::sphere({rng.uniform(0, 2000), rng.uniform(0, 2000), rng.uniform(0, 2000)}, r));
    h.push_back(g.insert(shapes.back(), static_cast<std::uint64_t>(i)));
  }
  g.validate();
  EXPECT_GE(g.levels().size(), 15u);
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    // The level's cell holds the object, and the next finer would not.
    const double cell = std::ldexp(1.0, g.level_of(h[i]));
    const AabbF b = bounds_f(shapes[i]);
    const double extent = static_cast<double>(b.hi[0]) - static_cast<double>(b.lo[0]);
    EXPECT_LE(extent, cell);
    if (g.level_of(h[i]) > std::ilogb(2000.0) - 20) {
      EXPECT_GT(extent, cell / 2);
    }
  }
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(HGrid, EmptyLevelsAreDroppedFromTheLevelList) {
  HGrid g;
  const Handle small = g.insert(Shape::sphere({0, 0, 0}, 0.01), 0);
  const Handle big = g.insert(Shape::sphere({0, 0, 0}, 100), 1);
  EXPECT_EQ(g.levels().size(), 2u);
  g.update(small, Shape::sphere({0, 0, 0}, 99));
  EXPECT_EQ(g.levels().size(), 1u);
  g.remove(big);
  g.remove(small);
  EXPECT_TRUE(g.levels().empty());
  g.validate();
}

TEST(HGrid, FarCoordinatesAndFloatOverflowStayExact) {
  HGrid g;
  std::vector<Shape> shapes;
  for (int i = 0; i < 100; ++i) shapes.push_back(Shape::sphere({1e7 + i * 0.01, -1e7, 1e7}, 0.006));
  // Beyond the float range: bounds are infinite, the object overflows.
  shapes.push_back(Shape::sphere({1e39, 0, 0}, 1));
  shapes.push_back(Shape::sphere({1e39 + 1e24, 0, 0}, 1e24));
  shapes.push_back(Shape::box({0, 0, 0}, {1e30, 1e30, 1e30}));
  for (std::size_t i = 0; i < shapes.size(); ++i) g.insert(shapes[i], i);
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
  const Shape q = Shape::sphere({1e39, 0, 0}, 1e23);
  std::size_t hits = 0, want = 0;
  g.query(q, [&](Handle) { ++hits; });
  for (const Shape& s : shapes) want += overlaps(q, s);
  EXPECT_EQ(hits, want);
  EXPECT_GE(want, 2u);
}

TEST(HGrid, SameLevelPairsAreReportedOnce) {
  HGrid g;
  for (int i = 0; i < 50; ++i) g.insert(Shape::sphere({0, 0, 0}, 1), static_cast<std::uint64_t>(i));
  int seen = 0;
  g.for_each_pair([&](Handle, Handle) { ++seen; });
  EXPECT_EQ(seen, 50 * 49 / 2);
  EXPECT_THROW(HGrid(Config{{}, 0, {{"cell", "3"}}}), InvalidConfig);
}

}  // namespace
}  // namespace broadphase
