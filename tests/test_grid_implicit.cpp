// grid-implicit: the slab cap, bit arrays growing past 64 objects, objects
// outside the world, exact pairs against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/grid_implicit.hpp>
#include <broadphase/scenes/scene.hpp>
#include <vector>

#include "structure_testing.hpp"

namespace broadphase {
namespace {

using testing::brute;
using testing::Pairs;
using testing::pairs_of;

TEST(GridImplicit, SlabsAreCappedPerAxis) {
  Config c;
  c.options["cell"] = "0.001";
  GridImplicit g(c);
  EXPECT_GE(g.cell_size(), 1000.0 / GridImplicit::kMaxSlabs);
  g.insert(Shape::sphere({1, 1, 1}, 0.5), 0);
  g.validate();
}

TEST(GridImplicit, BitArraysGrowAndObjectsOutsideAreExact) {
  Config c;
  c.world = {{0, 0, 0}, {100, 100, 100}};
  c.options["cell"] = "5";
  GridImplicit g(c);
  Rng rng(9);
  std::vector<Shape> shapes;
  std::vector<Handle> h;
  for (int i = 0; i < 500; ++i) {
    const double lo = i % 3 == 0 ? -400 : 0, hi = i % 3 == 0 ? 500 : 100;
    shapes.push_back(Shape::sphere({rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi)},
                                   rng.uniform(0, 6)));
    h.push_back(g.insert(shapes.back(), static_cast<std::uint64_t>(i)));
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
  for (int step = 0; step < 500; ++step) {
    const std::size_t k = rng.below(shapes.size());
    shapes[k].center.x += rng.uniform(-10, 10);
    g.update(h[k], shapes[k]);
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridImplicit, EarlyStopAndQuery) {
  GridImplicit g;
  for (int i = 0; i < 10; ++i)
    g.insert(Shape::sphere({500, 500, 500}, 1), static_cast<std::uint64_t>(i));
  int seen = 0;
  const QueryCost c = g.for_each_pair([&](Handle, Handle) { return ++seen < 3; });
  EXPECT_TRUE(c.stopped);
  EXPECT_EQ(seen, 3);
  std::size_t hits = 0;
  g.query(Shape::box({500, 500, 500}, {0, 0, 0}), [&](Handle) { ++hits; });
  EXPECT_EQ(hits, 10u);
}

}  // namespace
}  // namespace broadphase
