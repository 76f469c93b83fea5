// grid-dense: its world box, the cell cap, the overflow list, and the
// lowest-shared-cell rule, each checked against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/grid_dense.hpp>
#include <broadphase/scenes/scene.hpp>
#include <vector>

#include "structure_testing.hpp"

namespace broadphase {
namespace {

using testing::brute;
using testing::Pairs;
using testing::pairs_of;

TEST(GridDense, ObjectsOutsideTheWorldAreClampedIntoBorderCells) {
  Config c;
  c.world = {{0, 0, 0}, {100, 100, 100}};
  c.options["cell"] = "10";
  GridDense g(c);
  Rng rng(3);
  std::vector<Shape> shapes;
  for (int i = 0; i < 400; ++i) {
    // Half of them far outside the world on every side.
    const double spread = i % 2 ? 100 : 3000;
    shapes.push_back(Shape::sphere(
        {rng.uniform(-spread, spread), rng.uniform(-spread, spread), rng.uniform(-spread, spread)},
        rng.uniform(0, 4)));
    g.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  g.validate();
  EXPECT_EQ(g.cell_count(), 1000u);
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridDense, CellCountIsCappedByGrowingTheCell) {
  Config c;
  c.world = {{0, 0, 0}, {1e6, 1e6, 1e6}};
  c.options["cell"] = "1";  // 1e18 cells asked for
  GridDense g(c);
  EXPECT_LE(g.cell_count(), 4096u);
  EXPECT_GT(g.cell_size(), 1.0);
  std::vector<Shape> shapes;
  for (int i = 0; i < 50; ++i) {
    shapes.push_back(Shape::sphere({i * 3e4, 5e5, 5e5}, 2e4));
    g.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridDense, LargeObjectsOverflowAndStayExact) {
  Config c;
  c.options["cell"] = "10";
  GridDense g(c);
  std::vector<Shape> shapes = {Shape::sphere({500, 500, 500}, 200),  // spans 41 cells per axis
                               Shape::box({520, 500, 500}, {100, 1, 1}),
                               Shape::sphere({650, 500, 500}, 1), Shape::sphere({900, 900, 900}, 1),
                               Shape::sphere({651, 500, 500}, 1)};
  for (std::size_t i = 0; i < shapes.size(); ++i) g.insert(shapes[i], i);
  g.validate();
  EXPECT_EQ(g.overflow_count(), 2u);
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridDense, PairSpanningManyCellsIsReportedOnce) {
  // Two boxes that share 2 x 2 x 2 cells: found in each, reported once.
  Config c;
  c.options["cell"] = "10";
  GridDense g(c);
  g.insert(Shape::box({10, 10, 10}, {9, 9, 9}), 0);
  g.insert(Shape::box({11, 11, 11}, {9, 9, 9}), 1);
  int seen = 0;
  g.for_each_pair([&](Handle, Handle) { ++seen; });
  EXPECT_EQ(seen, 1);
}

TEST(GridDense, UpdatesKeepTheListsConsistent) {
  GridDense g;
  Rng rng(11);
  std::vector<Shape> shapes;
  std::vector<Handle> h;
  for (int i = 0; i < 300; ++i) {
    shapes.push_back(Shape::sphere(
        {rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, rng.uniform(0.5, 50)));
    h.push_back(g.insert(shapes.back(), static_cast<std::uint64_t>(i)));
  }
  for (int step = 0; step < 2000; ++step) {
    const std::size_t k = rng.below(shapes.size());
    for (int a = 0; a < 3; ++a) shapes[k].center[a] += rng.uniform(-20, 20);
    g.update(h[k], shapes[k]);
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridDense, RejectsUnknownOptionsAndStaleHandles) {
  Config c;
  c.options["buckets"] = "8";
  EXPECT_THROW(GridDense{c}, InvalidConfig);
  GridDense g;
  const Handle h = g.insert(Shape::sphere({1, 1, 1}, 1), 0);
  g.remove(h);
  EXPECT_THROW(g.remove(h), InvalidHandle);
  EXPECT_THROW(g.update(h, Shape::sphere({1, 1, 1}, 1)), InvalidHandle);
}

}  // namespace
}  // namespace broadphase
