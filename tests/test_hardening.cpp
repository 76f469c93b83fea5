// Regression tests for inputs at the extremes of the double range, for
// every structure of the registry against brute force over the same shapes:
// centres spread over +-1.8e308 (the automatic cell size overflows), worlds
// whose width overflows a double, subnormal coordinates, objects whose float
// bounds are infinite; and bulk updates that fail part-way. Every call runs
// under a generous time limit that guards against never returning (not a
// timing assertion).
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/naive.hpp>
#include <broadphase/sap.hpp>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <future>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "testing.hpp"

namespace broadphase::testing {
namespace {

constexpr double kMax = std::numeric_limits<double>::max();
constexpr double kSub = std::numeric_limits<double>::denorm_min();

// Runs `f` on a thread of its own; when it has not returned after a minute
// (far beyond the milliseconds these small scenes take), the test fails and
// the process ends, since the hung thread cannot be joined.
void within_time_limit(const std::string& what, std::function<void()> f) {
  std::packaged_task<void()> task(std::move(f));
  std::future<void> done = task.get_future();
  std::thread(std::move(task)).detach();
  if (done.wait_for(std::chrono::seconds(60)) != std::future_status::ready) {
    std::fprintf(stderr, "FAILED: %s did not return within 60 s (hang guard)\n", what.c_str());
    std::fflush(stderr);
    std::_Exit(1);
  }
  done.get();  // rethrows what the call threw
}

using IdPairs = std::vector<std::pair<std::uint64_t, std::uint64_t>>;

IdPairs brute_pairs(const std::vector<Shape>& shapes, const std::vector<bool>& alive) {
  IdPairs out;
  for (std::size_t i = 0; i < shapes.size(); ++i)
    for (std::size_t j = i + 1; j < shapes.size(); ++j)
      if (alive[i] && alive[j] && overlaps(shapes[i], shapes[j])) out.emplace_back(i, j);
  return out;
}

IdPairs pairs_of(const AnyBroadPhase& bp) {
  std::vector<HandlePair> pairs;
  bp.find_pairs(pairs);
  IdPairs out;
  for (const HandlePair& p : pairs) {
    const std::uint64_t a = bp.user_data(p.a), b = bp.user_data(p.b);
    out.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::uint64_t> hits_of(const AnyBroadPhase& bp, const Shape& q) {
  std::vector<std::uint64_t> out;
  bp.query(q, [&](Handle h) {
    out.push_back(bp.user_data(h));
    return true;
  });
  std::sort(out.begin(), out.end());
  return out;
}

// Inserts `shapes` into structure `spec` over `world` and checks, under the
// hang guard, that all pairs, every object's query, a bulk update that
// swaps the shapes around, single updates and removals all give exactly
// what brute force gives, with validate() after each step.
void exact_on(const std::string& spec, const Aabb& world, const std::vector<Shape>& shapes,
              const std::string& scene_name) {
  SCOPED_TRACE(spec + " on " + scene_name);
  within_time_limit(spec + " on " + scene_name, [&] {
    Config config;
    config.world = world;
    auto bp = make_structure(spec, config);
    std::vector<Shape> now = shapes;
    std::vector<bool> alive(now.size(), true);
    std::vector<Handle> h;
    for (std::size_t i = 0; i < now.size(); ++i)
      h.push_back(bp->insert(now[i], i, i % 3 == 0 ? Motion::fixed : Motion::dynamic));
    auto check = [&](const char* step) {
      bp->validate();
      EXPECT_EQ(pairs_of(*bp), brute_pairs(now, alive)) << "all pairs after " << step;
      for (std::size_t i = 0; i < now.size(); ++i) {
        std::vector<std::uint64_t> want;
        for (std::size_t j = 0; j < now.size(); ++j)
          if (alive[j] && overlaps(now[i], now[j])) want.push_back(j);
        EXPECT_EQ(hits_of(*bp, now[i]), want) << "query of object " << i << " after " << step;
      }
    };
    check("insert");
    // A bulk update that rotates the shapes by one.
    std::vector<Move> moves;
    std::vector<Shape> next(now.size());
    for (std::size_t i = 0; i < now.size(); ++i) {
      next[i] = now[(i + 1) % now.size()];
      moves.push_back({h[i], next[i]});
    }
    bp->update(moves);
    now = next;
    check("bulk update");
    // Single updates back, one by one.
    for (std::size_t i = 0; i < now.size(); ++i) {
      now[i] = shapes[i];
      bp->update(h[i], now[i]);
    }
    check("single updates");
    for (std::size_t i = 0; i < now.size(); i += 2) {
      bp->remove(h[i]);
      alive[i] = false;
    }
    check("removals");
  });
}

Aabb cube(double lo, double hi) { return {{lo, lo, lo}, {hi, hi, hi}}; }

class Extremes : public ::testing::TestWithParam<std::string> {};

// Issue 21, finding 1: 30 points at the origin, one at y = DBL_MAX, one
// sphere of radius 1e300 at the origin. grid-hybrid's automatic cell
// overflowed, the big sphere's infinite float bounds gave NaN cells and
// every pair with it was lost (435 pairs instead of 466).
TEST_P(Extremes, CentresSpreadOverTheWholeRangeKeepEveryPair) {
  for (const double far : {kMax, 1e308, -kMax}) {
    std::vector<Shape> s(32, Shape::sphere({0, 0, 0}, 0));
    s[12] = Shape::sphere({0, far, 0}, 0);
    s[29] = Shape::sphere({0, 0, 0}, 1e300);
    exact_on(GetParam(), cube(0, 1000), s, "points at the origin and at " + std::to_string(far));
  }
  // Through a replay as `broadphase run` does, frame by frame.
  Scene scene;
  scene.world = 1000;
  scene.objects.assign(32, Shape::sphere({0, 0, 0}, 0));
  scene.objects[12] = Shape::sphere({0, kMax, 0}, 0);
  scene.objects[29] = Shape::sphere({0, 0, 0}, 1e300);
  scene.velocity.assign(32, {0, 0, 0});
  std::vector<FrameDigest> got;
  within_time_limit(GetParam() + " replay", [&] { got = replay(GetParam(), scene, 2, true); });
  const FrameDigest want = brute_force(scene.objects);
  EXPECT_EQ(want.pairs, 466u);
  for (const FrameDigest& d : got) EXPECT_EQ(d, want);
}

// Issue 21, finding 2: hgrid-paper never returned over a world of side
// 1.8e308 with a box as tall as the range and a point near its top.
TEST_P(Extremes, WorldOfTheLargestSideReturns) {
  const std::vector<Shape> s = {
      Shape::box({2.5, -1e300, kSub}, {1000, kMax, 1e-300}),
      Shape::sphere({2.5, 1.7976931248623157e308, kSub}, 0),
      Shape::sphere({0, 0, 0}, 1),
      Shape::box({-kMax, kMax, 0}, {kMax, kMax, kMax}),
  };
  exact_on(GetParam(), cube(0, kMax), s, "world [0, DBL_MAX]^3");
  exact_on(GetParam(), cube(-1e300, 1e300), s, "world [-1e300, 1e300]^3");
  // Corners at -DBL_MAX and DBL_MAX: a width no double holds, and no scene
  // file can give (its world is [0, L]); refused as a configuration.
  Config wide;
  wide.world = cube(-kMax, kMax);
  EXPECT_THROW(make_structure(GetParam(), wide), InvalidConfig);
}

// Issue 21, finding 4: a world with finite corners whose width overflows a
// double (grid-dense crashed on the first insert, grid-implicit threw
// std::length_error) is refused as a configuration by every structure; a
// world as wide as the largest double stays exact.
TEST_P(Extremes, WorldWhoseWidthOverflowsIsRefusedAndTheWidestWorldStaysExact) {
  std::vector<Shape> s;
  for (int i = 0; i < 20; ++i)
    s.push_back(Shape::sphere({i * 10.0, -i * 5e306, i * 1e300}, i % 4 == 0 ? 5e306 : 6));
  s.push_back(Shape::box({0, 0, 0}, {1e308, 1e308, 1e308}));
  s.push_back(Shape::sphere({1e308, 1e308, -1e308}, 0));
  Config wide;
  wide.world = cube(-1e308, 1e308);
  EXPECT_THROW(make_structure(GetParam(), wide), InvalidConfig);
  exact_on(GetParam(), cube(0, 1e308), s, "world [0, 1e308]^3");
  exact_on(GetParam(), cube(0, kMax), s, "world [0, DBL_MAX]^3");
}

// Subnormal coordinates and sizes, in a world of subnormal side and in an
// ordinary one; objects whose float bounds are infinite or zero-width.
TEST_P(Extremes, SubnormalAndInfiniteBoundsReturnAndStayExact) {
  std::vector<Shape> s;
  for (int i = 0; i < 24; ++i) {
    const double c = (i % 5 - 2) * kSub * (i + 1);
    s.push_back(i % 3 == 0 ? Shape::box({c, -c, 0}, {kSub * i, 0, kSub})
                           : Shape::sphere({c, c, -c}, kSub * (i % 4)));
  }
  s.push_back(Shape::sphere({0, 0, 0}, 1e300));             // float bounds infinite
  s.push_back(Shape::box({kMax, -kMax, 0}, {kMax, 0, 0}));  // infinite on two sides
  s.push_back(Shape::sphere({-kMax, kMax, kMax}, kMax));
  exact_on(GetParam(), cube(0, 4 * kSub), s, "subnormal world");
  exact_on(GetParam(), cube(0, 1000), s, "ordinary world");
  exact_on(GetParam(), cube(-kSub, kSub), s, "world of two subnormals");
}

// Random objects over every decade of the double range, both signs, in
// worlds of every scale, with repeated coordinates.
TEST_P(Extremes, RandomObjectsOverEveryDecadeStayExact) {
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    Rng rng(seed);
    auto value = [&] {
      switch (rng.below(6)) {
        case 0:
          return 0.0;
        case 1:
          return (rng.below(2) ? -1 : 1) * kSub * static_cast<double>(rng.below(4));
        case 2:
          return (rng.below(2) ? -1 : 1) * kMax;
        case 3:
          return (rng.below(2) ? -1 : 1) * std::pow(10.0, rng.uniform(-320, 308));
        case 4:
          return 1e7;
        default:
          return rng.uniform(-10, 10);
      }
    };
    std::vector<Shape> s;
    for (int i = 0; i < 40; ++i) {
      const Vec3 c{value(), value(), value()};
      const double r =
          rng.below(3) == 0 ? std::pow(10.0, rng.uniform(-320, 300)) : rng.uniform(0, 5);
      s.push_back(rng.below(3) == 0 ? Shape::box(c, {r, r * rng.uniform(), r * rng.uniform()})
                                    : Shape::sphere(c, r));
    }
    const double side = std::pow(10.0, rng.uniform(-300, 308));
    exact_on(GetParam(), cube(-side, side), s, "random decades, seed " + std::to_string(seed));
  }
}

// Issue 21, finding 3: a bulk update that throws part-way changes nothing.
// sap took its rebuild path on the ten even spheres' jump, then met the NaN
// centre: the endpoints disagreed with the boxes and pairs were lost.
TEST_P(Extremes, FailedBulkUpdateChangesNothing) {
  struct Bad {
    const char* what;
    bool stale;
    Shape shape;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Bad bads[] = {{"NaN centre", false, Shape::sphere({nan, 0, 0}, 1)},
                      {"negative radius", false, Shape::sphere({1, 0, 0}, -1)},
                      {"infinite half-extent", false,
                       Shape::box({0, 0, 0}, {std::numeric_limits<double>::infinity(), 1, 1})},
                      {"stale handle", true, Shape::sphere({0, 0, 0}, 1)}};
  for (const Bad& bad : bads) {
    SCOPED_TRACE(GetParam() + std::string(", bad move: ") + bad.what);
    within_time_limit(GetParam() + " failed bulk update", [&] {
      auto bp = make_structure(GetParam());
      std::vector<Shape> now;
      std::vector<Handle> h;
      for (int i = 0; i < 20; ++i) {
        now.push_back(Shape::sphere({10.0 * i, 0, 0}, 5));
        h.push_back(bp->insert(now.back(), static_cast<std::uint64_t>(i)));
      }
      const Handle gone = bp->insert(Shape::sphere({0, 0, 0}, 1), 99);
      bp->remove(gone);
      std::vector<Move> moves;
      for (int i = 0; i < 20; i += 2) moves.push_back({h[i], Shape::sphere({500, 500, 500}, 5)});
      moves.push_back({bad.stale ? gone : h[1], bad.shape});
      bool threw = false;
      try {
        bp->update(moves);
      } catch (const std::invalid_argument&) {
        threw = true;
      }
      EXPECT_TRUE(threw);
      bp->validate();
      const std::vector<bool> alive(now.size(), true);
      EXPECT_EQ(pairs_of(*bp), brute_pairs(now, alive));
      for (int i = 0; i < 20; ++i) EXPECT_EQ(bp->shape(h[i]), now[i]) << "object " << i;
      // And it stays right after valid updates.
      moves.pop_back();
      bp->update(moves);
      for (int i = 0; i < 20; i += 2) now[i] = Shape::sphere({500, 500, 500}, 5);
      bp->validate();
      EXPECT_EQ(pairs_of(*bp), brute_pairs(now, alive));
    });
  }
}

// A handle named twice in one batch: the last move wins, in every structure.
TEST_P(Extremes, HandleNamedTwiceInABatchTakesTheLastMove) {
  within_time_limit(GetParam() + " repeated handle", [&] {
    auto bp = make_structure(GetParam());
    std::vector<Shape> now;
    std::vector<Handle> h;
    for (int i = 0; i < 40; ++i) {
      now.push_back(Shape::sphere({10.0 * i, 0, 0}, 5));
      h.push_back(bp->insert(now.back(), static_cast<std::uint64_t>(i)));
    }
    std::vector<Move> moves;
    for (int round = 0; round < 3; ++round)
      for (int i = 0; i < 40; i += 3) {
        now[i] = Shape::sphere({10.0 * i + round * 300.0, 50.0 * round, 0}, 5 + round);
        moves.push_back({h[i], now[i]});
      }
    bp->update(moves);
    bp->validate();
    for (int i = 0; i < 40; ++i) EXPECT_EQ(bp->shape(h[i]), now[i]) << "object " << i;
    EXPECT_EQ(pairs_of(*bp), brute_pairs(now, std::vector<bool>(now.size(), true)));
  });
}

// Issue 21, finding 4: options whose arithmetic overflows over ordinary or
// huge worlds (a cell so small that its inverse is infinite, so large that
// it is nearly the whole range; octree-loose's looseness over [0, 1e308]^3)
// converted NaN to integers (undefined behaviour, which clang's
// -fsanitize=float-cast-overflow reports: the fuzzers are built with it).
// A configuration may be refused; one that is made must stay exact.
TEST(ExtremeOptions, CellArithmeticThatOverflowsStaysExact) {
  std::vector<Shape> s;
  for (int i = 0; i < 16; ++i)
    s.push_back(Shape::sphere({i * 1e-311, i * 3.0, i % 2 ? 1e300 : -1e300}, i % 3 ? 1e-311 : 2));
  s.push_back(Shape::sphere({0, 0, 0}, 1e300));
  const char* grids[] = {"grid-hashed", "grid-hybrid", "grid-dense", "grid-implicit",
                         "grid-static"};
  for (const char* g : grids)
    for (const char* cell : {":cell=1e-310", ":cell=5e-324", ":cell=1e300"})
      for (const Aabb& world : {cube(0, 1000), cube(-1e308, 1e308)}) {
        const std::string spec = std::string(g) + cell;
        Config config;
        config.world = world;
        try {
          make_structure(spec, config);
        } catch (const std::invalid_argument&) {
          continue;  // refused as a configuration: fine
        }
        exact_on(spec, world, s, "overflowing cell arithmetic");
      }
  for (const char* k : {"octree-loose:k=4.2", "octree-loose:k=8,depth=20", "octree-loose:k=1.1"})
    for (const Aabb& world : {cube(0, 1e308), cube(-1e308, 1e308), cube(0, 4e-323)}) {
      Config config;
      config.world = world;
      try {
        make_structure(k, config);
      } catch (const InvalidConfig&) {
        continue;  // refused as a configuration (a width that overflows): fine
      }
      exact_on(k, world, s, "a loose octree over a world of extreme size");
    }
}

INSTANTIATE_TEST_SUITE_P(All, Extremes, ::testing::ValuesIn(structure_specs()),
                         StructureParamName{});

// The reproducer for sap exactly, through the concrete class too
// (not only through the type-erased face).
TEST(SapBulkUpdate, ThrowingBatchOnTheRebuildPathLeavesSapIntact) {
  Sap sap;
  std::vector<Handle> h;
  std::vector<Shape> now;
  for (int i = 0; i < 20; ++i) {
    now.push_back(Shape::sphere({10.0 * i, 0, 0}, 5));
    h.push_back(sap.insert(now.back(), static_cast<std::uint64_t>(i), Motion::dynamic));
  }
  std::vector<Move> moves;
  for (int i = 0; i < 20; i += 2) moves.push_back({h[i], Shape::sphere({500, 500, 500}, 5)});
  moves.push_back({h[1], Shape::sphere({std::numeric_limits<double>::quiet_NaN(), 0, 0}, 5)});
  EXPECT_THROW(sap.update(moves), InvalidShape);
  EXPECT_NO_THROW(sap.validate());
  std::size_t pairs = 0;
  sap.for_each_pair([&](Handle, Handle) { ++pairs; });
  EXPECT_EQ(pairs, brute_pairs(now, std::vector<bool>(20, true)).size());
}

}  // namespace
}  // namespace broadphase::testing
