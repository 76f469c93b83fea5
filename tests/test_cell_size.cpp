// The shared automatic cell size.
#include <gtest/gtest.h>

#include <broadphase/cell_size.hpp>
#include <vector>

namespace broadphase {
namespace {

TEST(CellSize, FollowsTheSizeQuantile) {
  std::vector<double> extents;
  for (int i = 1; i <= 100; ++i) extents.push_back(i);
  const Aabb small_box{{0, 0, 0}, {1, 1, 1}};
  EXPECT_NEAR(choose_cell_size(extents, small_box, {0.75, 0.5}), 75, 1);
  EXPECT_NEAR(choose_cell_size(extents, small_box, {0.95, 0.5}), 95, 1);
}

TEST(CellSize, PointsUseTheSpacingOfTheCentres) {
  std::vector<double> extents(1000, 0.0);
  const Aabb box{{0, 0, 0}, {1000, 1000, 1000}};
  // 1000 points in 1e9: spacing 100, half of it by default.
  EXPECT_NEAR(choose_cell_size(extents, box), 50, 1e-9);
}

TEST(CellSize, FlatAndDegeneratePopulationsGiveAPositiveSize) {
  std::vector<double> extents(100, 0.0);
  const Aabb flat{{0, 0, 0}, {1000, 0, 1000}};
  const double c = choose_cell_size(extents, flat);
  EXPECT_GT(c, 0);
  EXPECT_LT(c, 1000);
  const Aabb point{{5, 5, 5}, {5, 5, 5}};
  EXPECT_EQ(choose_cell_size(extents, point), 1.0);
  std::vector<double> none;
  EXPECT_EQ(choose_cell_size(none, point), 1.0);
}

}  // namespace
}  // namespace broadphase
