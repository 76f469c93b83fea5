// Every structure of the library against the naive oracle: random sequences
// of insert / remove / update / query / all-pairs with fixed seeds, and the
// structure's validate() after every step.
#include <gtest/gtest.h>

#include <limits>

#include "testing.hpp"

namespace broadphase::testing {
namespace {

class Differential : public ::testing::TestWithParam<std::string> {};

// The seed loops below run fewer seeds under the sanitizers (repeats():
// every world still runs); the Release build runs them all.
TEST_P(Differential, MatchesNaiveOnRandomOperations) {
  for (World w : {World::mixed, World::touching, World::far, World::huge})
    for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(4)); ++seed) {
      differential(GetParam(), w, seed * 7919 + static_cast<std::uint64_t>(w), 700);
      if (HasFailure()) return;
    }
}

TEST_P(Differential, MatchesNaiveWithPolesAndSlabs) {
  // One seed under the sanitizers (55 s of CPU over the registry under ASan
  // with three); the Release build runs the three.
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(3)); ++seed) {
    differential(GetParam(), World::shaped, 3000 + seed, 700);
    if (HasFailure()) return;
  }
}

TEST_P(Differential, MatchesNaiveWithThousandsInOneCell) {
  // 1 000 steps under the sanitizers: 2 500 took 125 s of CPU there over
  // the structures, the pairs growing with the square of the crowd.
  differential(GetParam(), World::crowded, 42, kAddressSanitizer || kThreadSanitizer ? 1000 : 2500);
}

TEST_P(Differential, MatchesNaiveWhereTheArithmeticOverflows) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(3)); ++seed) {
    differential(GetParam(), World::extreme, 1000 + seed, 500);
    if (HasFailure()) return;
  }
}

TEST_P(Differential, MatchesNaiveWhereTheSquaresUnderflow) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(3)); ++seed) {
    differential(GetParam(), World::tiny, 2000 + seed, 500);
    if (HasFailure()) return;
  }
}

TEST_P(Differential, MatchesNaiveInAFarAwayWorld) {
  // The world box itself far from the origin.
  Config c;
  c.world = {{1e7, 1e7, -1e7}, {1e7 + 1000, 1e7 + 1000, -1e7 + 1000}};
  differential(GetParam(), World::far, 99, 800, c);
}

TEST_P(Differential, MatchesBruteForceWithFilters) {
  // Random bits, and layered worlds (4 and 16 layers, each pairing with its
  // own and its two neighbours only), filters changing between steps and a
  // pair filter coming and going; every pair answer against brute force.
  for (Filters f : {Filters::bits, Filters::layers4, Filters::layers16})
    for (World w : {World::mixed, World::touching, World::huge}) {
      const std::uint64_t seed = 31 * static_cast<std::uint64_t>(f) + static_cast<std::uint64_t>(w);
      differential(GetParam(), w, seed, 600, {}, f);
      if (HasFailure()) return;
    }
}

TEST_P(Differential, MatchesBruteForceWithFiltersInACrowd) {
  differential(GetParam(), World::crowded, 77, 1500, {}, Filters::layers16);
}

TEST_P(Differential, RejectsAnInvalidQueryShape) {
  // As an insert would: a clear error, not a crash or a silent empty answer.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  auto bp = make_structure(GetParam());
  for (int i = 0; i < 50; ++i) bp->insert(Shape::sphere({i * 10.0, 5, 5}, 6), i);
  for (const Shape& bad :
       {Shape::sphere({nan, 0, 0}, 1), Shape::sphere({0, inf, 0}, 1), Shape::sphere({0, 0, 0}, -1),
        Shape::box({0, 0, 0}, {1, nan, 1}), Shape{{0, 0, 0}, {1, 2, 3}, ShapeKind::sphere}}) {
    EXPECT_THROW(bp->query(bad, [](Handle) { return true; }), InvalidShape);
  }
  bp->validate();
}

TEST_P(Differential, RejectsMoreExpectedObjectsThanHandlesCanName) {
  // An impossible size hint is named, not met with bad_alloc.
  Config c;
  c.expected_objects = std::size_t{1} << 40;
  EXPECT_THROW(make_structure(GetParam(), c), InvalidConfig);
  c.expected_objects = 1000;
  EXPECT_NO_THROW(make_structure(GetParam(), c));
}

TEST_P(Differential, ConstCallsRunConcurrently) {
  // Run under ThreadSanitizer in CI.
  const_calls_on_two_threads(GetParam(), generate(Distribution::uneven, 3000, 4));
}

INSTANTIATE_TEST_SUITE_P(All, Differential, ::testing::ValuesIn(structure_specs()),
                         StructureParamName{});

}  // namespace
}  // namespace broadphase::testing
