// sort-sweep: axis choice and the sweep against brute force.
#include <gtest/gtest.h>

#include <broadphase/sort_sweep.hpp>

#include "testing.hpp"

namespace broadphase {
namespace {

FrameDigest digest_of(const SortSweep& s) {
  FrameDigest d;
  s.for_each_pair([&](Handle a, Handle b) {
    d.add(static_cast<std::uint32_t>(s.user_data(a)), static_cast<std::uint32_t>(s.user_data(b)));
  });
  return d;
}

TEST(SortSweep, SweepsAlongTheAxisOfLargestSpread) {
  SortSweep s;
  for (int i = 0; i < 100; ++i)
    s.insert(Shape::sphere({0, 0, i * 3.0}, 1), static_cast<std::uint64_t>(i));
  EXPECT_EQ(s.sweep_axis(), 2);
}

TEST(SortSweep, MatchesBruteForceOnFlatAndCoincidentScenes) {
  // Both sizes: below and above the radix-sort threshold.
  for (std::size_t n : {100u, 3000u})
    for (Distribution d : {Distribution::flat, Distribution::coincident, Distribution::outside}) {
      const Scene scene = generate(d, n, 5);
      SortSweep s;
      for (std::size_t i = 0; i < n; ++i) s.insert(scene.objects[i], i);
      s.validate();
      EXPECT_EQ(digest_of(s), testing::brute_force(scene.objects)) << to_string(d) << " " << n;
    }
}

TEST(SortSweep, TouchingAndNegativeCoordinates) {
  SortSweep s;
  s.insert(Shape::box({-2, 0, 0}, {1, 1, 1}), 0);
  s.insert(Shape::box({0, 0, 0}, {1, 1, 1}), 1);
  s.insert(Shape::sphere({-0.0, 50, 0}, 0), 2);
  s.insert(Shape::sphere({0.0, 50, 0}, 0), 3);
  EXPECT_EQ(digest_of(s).pairs, 2u);
}

TEST(SortSweep, EarlyStop) {
  SortSweep s;
  for (int i = 0; i < 10; ++i) s.insert(Shape::sphere({0, 0, 0}, 1), static_cast<std::uint64_t>(i));
  int seen = 0;
  const QueryCost c = s.for_each_pair([&](Handle, Handle) { return ++seen < 3; });
  EXPECT_EQ(seen, 3);
  EXPECT_TRUE(c.stopped);
}

}  // namespace
}  // namespace broadphase
