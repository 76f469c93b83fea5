// The MPI path's geometry without an MPI runtime (no MPI_Init): the tree of
// cuts that decides which rank owns a point and which ranks a box reaches.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/config_error.hpp>
#include <broadphase/mpi.hpp>
#include <string>
#include <vector>

namespace broadphase::mpi {
namespace {

TEST(Partition, RegionsHoldExactlyThePointsTheirOwnerIsGiven) {
  // A hand-built tree whose second cut lies outside its node's box (x < 5,
  // then x < 10 on the left): the left-right leaf owns nothing. Its region
  // was [10, 5) clipped wrongly to the whole of x < 10, so rank 0's and
  // rank 1's regions both held x = 7 (found by fuzz_partition).
  std::vector<Partition::Node> nodes{{0, 5.0, 1, -3}, {0, 10.0, -1, -2}};
  const Partition p(nodes, 3);
  for (double x : {-1e300, -1.0, 0.0, 4.999, 5.0, 7.0, 10.0, 1e300}) {
    const Vec3 q{x, 0, 0};
    const int o = p.owner(q);
    for (int r = 0; r < p.size(); ++r)
      EXPECT_EQ(p.holds(r, q), r == o) << "x " << x << " rank " << r;
  }
  EXPECT_EQ(p.owner({7, 0, 0}), 2);
  EXPECT_FALSE(p.region(1).lo.x < p.region(1).hi.x);  // empty
}

TEST(Partition, AnObjectReachesTheOwnerOfItsCentreAndOfAnyPairPoint) {
  const Partition p = Partition::grid({{0, 0, 0}, {100, 100, 100}}, {2, 2, 2});
  const Shape a = Shape::sphere({49.5, 50, 50}, 1), b = Shape::box({50.5, 50, 50}, {1, 1, 1});
  std::vector<int> ra, rb;
  p.ranks_meeting(bounds(a), 0, ra);
  p.ranks_meeting(bounds(b), 0, rb);
  const Aabb ba = bounds(a), bb = bounds(b);
  const int o =
      p.owner({std::max(ba.lo.x, bb.lo.x), std::max(ba.lo.y, bb.lo.y), std::max(ba.lo.z, bb.lo.z)});
  EXPECT_NE(std::find(ra.begin(), ra.end(), o), ra.end());
  EXPECT_NE(std::find(rb.begin(), rb.end(), o), rb.end());
  EXPECT_NE(std::find(ra.begin(), ra.end(), p.owner(a.center)), ra.end());
}

TEST(Partition, GridTextIsParsedAndABadOneIsAnInvalidConfig) {
  EXPECT_EQ(parse_dims("2x3x1"), (std::array<int, 3>{2, 3, 1}));
  for (const char* bad : {"", "2x2", "2x2x0", "2x-1x1", "2x2x1x", "axbxc", "2x2x1 "}) {
    try {
      parse_dims(bad);
      ADD_FAILURE() << "'" << bad << "' was accepted";
    } catch (const InvalidConfig& e) {
      EXPECT_EQ(std::string(e.what()),
                "grid '" + std::string(bad) + "': expected AxBxC with whole numbers >= 1");
    }
  }
  // The former namespace still names the same functions.
  EXPECT_EQ(broadphase::distributed::parse_dims("1x1x4"), (std::array<int, 3>{1, 1, 4}));
}

}  // namespace
}  // namespace broadphase::mpi
