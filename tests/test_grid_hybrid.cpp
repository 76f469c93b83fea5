// grid-hybrid: a city and an empty sky, x order kept under motion.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/grid_hybrid.hpp>
#include <broadphase/scenes/scene.hpp>
#include <vector>

#include "structure_testing.hpp"

namespace broadphase {
namespace {

using testing::brute;
using testing::Pairs;
using testing::pairs_of;

TEST(GridHybrid, CityAndSkyWithMotion) {
  GridHybrid g;
  Rng rng(21);
  std::vector<Shape> shapes;
  std::vector<Handle> h;
  for (int i = 0; i < 1200; ++i) {
    const bool city = i % 10 != 0;
    const Vec3 c = city ? Vec3{rng.uniform(0, 50), rng.uniform(0, 5), rng.uniform(0, 50)}
                        : Vec3{rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)};
    shapes.push_back(rng.uniform() < 0.3 ? Shape::box(c, {0.5, 2, 0.5}) : Shape::sphere(c, 0.4));
    h.push_back(g.insert(shapes.back(), static_cast<std::uint64_t>(i)));
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
  for (int step = 0; step < 3000; ++step) {
    const std::size_t k = rng.below(shapes.size());
    shapes[k].center.x += rng.uniform(-1, 1);
    shapes[k].center.z += rng.uniform(-1, 1);
    g.update(h[k], shapes[k]);
  }
  g.validate();  // also checks every list is in x order
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

TEST(GridHybrid, CellsAreCoarserThanTheUniformGrids) {
  GridHybrid g;
  for (int i = 0; i < 500; ++i)
    g.insert(Shape::sphere({i * 2.0, 0, 0}, 1), static_cast<std::uint64_t>(i));
  EXPECT_GE(g.cell_size(), 8.0);
  g.validate();
}

}  // namespace
}  // namespace broadphase
