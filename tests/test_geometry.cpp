// The exact predicates of docs/scene-format.md on exact touching, zero-size and
// box cases, and the promise every structure relies on: whenever two shapes
// overlap, their conservative bounds (double and float) overlap too.
#include <gtest/gtest.h>

#include <broadphase/geometry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace broadphase {
namespace {

// Both argument orders, which must agree.
bool overlap_both(const Shape& a, const Shape& b) {
  const bool ab = overlaps(a, b);
  EXPECT_EQ(ab, overlaps(b, a));
  return ab;
}

TEST(Geometry, SpheresTouchingCount) {
  EXPECT_TRUE(overlap_both(Shape::sphere({0, 0, 0}, 1), Shape::sphere({2, 0, 0}, 1)));
  EXPECT_FALSE(overlap_both(Shape::sphere({0, 0, 0}, 1),
                            Shape::sphere({std::nextafter(2.0, 3.0), 0, 0}, 1)));
  // 3-4-5: d2 = 25 exactly, s = 5.
  EXPECT_TRUE(overlap_both(Shape::sphere({0, 0, 0}, 2), Shape::sphere({3, 4, 0}, 3)));
  // One ulp less radius: but 2 + (3 - ulp) rounds back to 5, as written.
  EXPECT_TRUE(overlap_both(Shape::sphere({0, 0, 0}, 2),
                           Shape::sphere({3, 4, 0}, std::nextafter(3.0, 0.0))));
  EXPECT_FALSE(overlap_both(Shape::sphere({0, 0, 0}, 0),
                            Shape::sphere({3, 4, 0}, std::nextafter(5.0, 0.0))));
}

TEST(Geometry, ZeroRadiusPoints) {
  const Shape p = Shape::sphere({1, 2, 3}, 0);
  EXPECT_TRUE(overlap_both(p, p));
  EXPECT_FALSE(overlap_both(p, Shape::sphere({1, 2, std::nextafter(3.0, 4.0)}, 0)));
  // A point on a sphere's surface.
  EXPECT_TRUE(overlap_both(Shape::sphere({0, 0, 0}, 5), Shape::sphere({3, 4, 0}, 0)));
  // A point on a box's face, edge and corner; a point box is a point.
  const Shape box = Shape::box({0, 0, 0}, {1, 2, 3});
  EXPECT_TRUE(overlap_both(box, Shape::sphere({1, 0, 0}, 0)));
  EXPECT_TRUE(overlap_both(box, Shape::sphere({1, 2, 0}, 0)));
  EXPECT_TRUE(overlap_both(box, Shape::sphere({-1, -2, 3}, 0)));
  EXPECT_TRUE(overlap_both(box, Shape::box({-1, -2, 3}, {0, 0, 0})));
  EXPECT_FALSE(overlap_both(box, Shape::sphere({-1, -2, std::nextafter(3.0, 4.0)}, 0)));
}

TEST(Geometry, BoxesTouchingFacesEdgesCorners) {
  const Shape a = Shape::box({0, 0, 0}, {1, 1, 1});
  EXPECT_TRUE(overlap_both(a, Shape::box({2, 0, 0}, {1, 1, 1})));        // face
  EXPECT_TRUE(overlap_both(a, Shape::box({2, 2, 0}, {1, 1, 1})));        // edge
  EXPECT_TRUE(overlap_both(a, Shape::box({2, 2, 2}, {1, 1, 1})));        // corner
  EXPECT_TRUE(overlap_both(a, Shape::box({0.5, 0.5, 0.5}, {0, 0, 0})));  // inside
  EXPECT_FALSE(overlap_both(a, Shape::box({2, 2, std::nextafter(2.0, 3.0)}, {1, 1, 1})));
  // Flat boxes (one half-extent zero) still touch.
  EXPECT_TRUE(overlap_both(Shape::box({0, 0, 0}, {1, 0, 1}), Shape::box({0, 0, 0}, {0, 1, 0})));
}

TEST(Geometry, SphereAgainstBox) {
  const Shape box = Shape::box({0, 0, 0}, {1, 1, 1});
  EXPECT_TRUE(overlap_both(box, Shape::sphere({2, 0, 0}, 1)));  // face
  EXPECT_FALSE(overlap_both(box, Shape::sphere({2, 0, 0}, std::nextafter(1.0, 0.0))));
  // Off an edge: e = (3, 4, -1 -> 0), d2 = 25.
  EXPECT_TRUE(overlap_both(box, Shape::sphere({4, 5, 0}, 5)));
  EXPECT_FALSE(overlap_both(box, Shape::sphere({4, 5, 0}, std::nextafter(5.0, 0.0))));
  // Inside the box, any radius.
  EXPECT_TRUE(overlap_both(box, Shape::sphere({0.25, -0.5, 0.9}, 0)));
  // Off a corner by (1, 1, 1): d2 = 3 against r*r as computed in double.
  const double r = std::sqrt(3.0);
  EXPECT_EQ(overlap_both(box, Shape::sphere({2, 2, 2}, r)), 3.0 <= r * r);
}

TEST(Geometry, BoundsContainTheShape) {
  for (const Shape& s :
       {Shape::sphere({1, -2, 3}, 4), Shape::box({1e7, -1e7, 0}, {1, 0, 3}),
        Shape::sphere({0, 0, 0}, 0), Shape::box({1e300, -1e300, 5}, {1e299, 0, 0})}) {
    const Aabb b = bounds(s);
    const AabbF f = bounds_f(s);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(b.lo[a], s.center[a] - s.half[a]);
      EXPECT_GE(b.hi[a], s.center[a] + s.half[a]);
      EXPECT_LE(static_cast<double>(f.lo[a]), b.lo[a]);
      EXPECT_GE(static_cast<double>(f.hi[a]), b.hi[a]);
    }
  }
  // Around a point at the origin only the absolute floor is left.
  const double f = kBoundsFloor;
  EXPECT_EQ(bounds(Shape::sphere({0, 0, 0}, 0)), (Aabb{{-f, -f, -f}, {f, f, f}}));
}

TEST(Geometry, BoundsOverlapWhereTheSquaresUnderflow) {
  // Points 1e-170 apart: d² rounds to zero, so the contract's predicate
  // holds (0 <= 0) though they are far apart for their size; their bounds
  // must overlap too, at any offset from the origin where that can happen.
  for (const double base : {0.0, 1e-300, -1e-200, 1e-160}) {
    const Shape a = Shape::sphere({base, base, 0}, 0);
    const Shape b = Shape::sphere({base + 1e-170, base, 0}, 0);
    const Shape c = Shape::sphere({base, base - 1e-170, 1e-170}, 1e-300);
    for (const Shape& other : {b, c}) {
      ASSERT_TRUE(overlaps(a, other)) << base;
      EXPECT_TRUE(bounds(a).overlaps(bounds(other))) << base;
      EXPECT_TRUE(bounds_f(a).overlaps(bounds_f(other))) << base;
    }
    // A sphere and a box: e = |cs - cb| - hb squares to zero as well.
    const Shape box = Shape::box({base - 1e-170, base, 0}, {0, 0, 0});
    ASSERT_TRUE(overlaps(a, box)) << base;
    EXPECT_TRUE(bounds(a).overlaps(bounds(box))) << base;
  }
}

// A shape at distance about `gap` (in units of the touching distance) from
// `a` along a random direction or axis, within a few ulps of touching.
class NearTouching {
 public:
  explicit NearTouching(std::uint64_t seed) : rng_(seed) {}

  Shape around(double base, double size) {
    const Vec3 c{base * (1 + rng_.uniform(-1e-3, 1e-3)), base * rng_.uniform(-1, 1),
                 -base * (1 + rng_.uniform(-1e-3, 1e-3))};
    const double r = size * rng_.uniform(0, 1);
    if (rng_.uniform() < 0.5) return Shape::sphere(c, r);
    return Shape::box(c, {r * rng_.uniform(0, 1), r * rng_.uniform(0, 1), r * rng_.uniform(0, 1)});
  }

  Shape near(const Shape& a, double size) {
    const double r = size * rng_.uniform(0, 1);
    Shape b = rng_.uniform() < 0.5 ? Shape::sphere({}, r)
                                   : Shape::box({}, {r * rng_.uniform(0, 1), r * rng_.uniform(0, 1),
                                                     r * rng_.uniform(0, 1)});
    const double wiggle = 1 + static_cast<double>(static_cast<int>(rng_.below(9)) - 4) * 0x1p-52;
    if (a.is_sphere() && b.is_sphere()) {
      const Vec3 u = rng_.direction();
      b.center = a.center + u * ((a.radius() + b.radius()) * wiggle);
    } else {
      // Touching across one axis, inside the overlap range on the others.
      const int axis = static_cast<int>(rng_.below(3));
      b.center = a.center;
      const double sign = rng_.uniform() < 0.5 ? -1 : 1;
      b.center[axis] += sign * (a.half[axis] + b.half[axis]) * wiggle;
      for (int o = 0; o < 3; ++o)
        if (o != axis) b.center[o] += rng_.uniform(-0.5, 0.5) * (a.half[o] + b.half[o]);
    }
    return b;
  }

 private:
  Rng rng_;
};

TEST(Geometry, OverlapImpliesBoundsOverlapOnNearTouchingPairs) {
  struct Case {
    double base, size;
  };
  // Coordinates near 0, near 1e7, and near 1e300 (with sizes whose squares
  // do not overflow), with sizes from tiny to large against the base.
  const Case cases[] = {{0, 10},    {1, 1e-6},      {1e7, 1e-3},    {1e7, 10},
                        {1e7, 1e6}, {1e300, 1e150}, {1e300, 1e-10}, {1e-300, 1e-300}};
  NearTouching gen(2024);
  for (const Case& c : cases) {
    int overlapping = 0, trials = 0;
    for (int t = 0; t < 20000; ++t) {
      const Shape a = gen.around(c.base, c.size);
      const Shape b = gen.near(a, c.size);
      ++trials;
      if (!overlaps(a, b)) continue;
      ++overlapping;
      ASSERT_TRUE(bounds(a).overlaps(bounds(b)))
          << "base " << c.base << " size " << c.size << " trial " << t;
      ASSERT_TRUE(bounds_f(a).overlaps(bounds_f(b)))
          << "base " << c.base << " size " << c.size << " trial " << t;
    }
    // The pairs really are near the edge: some touch, some miss.
    EXPECT_GT(overlapping, trials / 20) << "base " << c.base;
  }
}

TEST(Geometry, ShapeValidity) {
  EXPECT_TRUE(is_valid(Shape::sphere({0, 0, 0}, 0)));
  EXPECT_TRUE(is_valid(Shape::box({0, 0, 0}, {0, 1, 2})));
  EXPECT_FALSE(is_valid(Shape::sphere({0, 0, 0}, -1)));
  EXPECT_FALSE(is_valid(Shape::sphere({std::nan(""), 0, 0}, 1)));
  EXPECT_FALSE(is_valid(Shape::sphere({0, 0, 0}, std::numeric_limits<double>::infinity())));
  EXPECT_FALSE(is_valid(Shape::box({0, 0, 0}, {1, -0.5, 1})));
  EXPECT_FALSE(is_valid(Shape{{0, 0, 0}, {1, 2, 1}, ShapeKind::sphere}));
}

TEST(Geometry, RoundingOutwardsToFloat) {
  EXPECT_LE(static_cast<double>(round_down(0.1)), 0.1);
  EXPECT_GE(static_cast<double>(round_up(0.1)), 0.1);
  EXPECT_EQ(round_down(0.5), 0.5f);
  EXPECT_EQ(round_up(0.5), 0.5f);
  EXPECT_EQ(round_down(-1e300), -std::numeric_limits<float>::infinity());
  EXPECT_EQ(round_up(1e300), std::numeric_limits<float>::infinity());
  EXPECT_EQ(round_up(-1e300), -std::numeric_limits<float>::max());
  EXPECT_EQ(round_down(1e300), std::numeric_limits<float>::max());
  EXPECT_EQ(round_down(-1e-300), -std::numeric_limits<float>::denorm_min());
  EXPECT_EQ(round_up(1e-300), std::numeric_limits<float>::denorm_min());
}

TEST(Geometry, RoundingIsTightAndOutwards) {
  // round_down(x) is the largest float not above x: at or below it, with
  // the next float up above it; round_up likewise. Across magnitudes,
  // signs, exact floats, zeros, subnormals and the ends of the float range.
  constexpr double kMax = std::numeric_limits<float>::max();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mant(-1, 1);
  std::uniform_int_distribution<int> expo(-160, 140);
  std::vector<double> xs = {0.0,
                            -0.0,
                            1e-46,
                            -1e-46,
                            1e-300,
                            -1e-300,
                            kMax,
                            -kMax,
                            kMax * (1 + 0x1p-30),
                            -kMax * (1 + 0x1p-30),
                            1e300,
                            -1e300};
  for (int i = 0; i < 200000; ++i) {
    const double x = std::ldexp(mant(rng), expo(rng));
    xs.push_back(x);
    xs.push_back(static_cast<double>(static_cast<float>(x)));  // exactly a float
  }
  // Just above floats of every binade, subnormals and the range's ends included.
  std::vector<float> floats = {std::numeric_limits<float>::denorm_min(),
                               std::numeric_limits<float>::min(), std::numeric_limits<float>::max(),
                               1.0f};
  std::uniform_real_distribution<double> half(0.5, 1);
  std::uniform_int_distribution<int> binade(-148, 127);
  for (int i = 0; i < 20000; ++i)
    floats.push_back(static_cast<float>(std::ldexp(half(rng), binade(rng))));
  for (const float f : floats)
    for (const double sign : {1.0, -1.0}) xs.push_back(sign * f * (1 + 0x1p-30));
  for (const double x : xs) {
    const float d = round_down(x), u = round_up(x);
    ASSERT_LE(static_cast<double>(d), x) << x;
    ASSERT_GE(static_cast<double>(u), x) << x;
    if (d != kInf && x >= -kMax) {
      ASSERT_GT(static_cast<double>(std::nextafter(d, kInf)), x) << x;
    }
    if (u != -kInf && x <= kMax) {
      ASSERT_LT(static_cast<double>(std::nextafter(u, -kInf)), x) << x;
    }
  }
  EXPECT_EQ(round_down(HUGE_VAL), kInf);
  EXPECT_EQ(round_up(HUGE_VAL), kInf);
  EXPECT_EQ(round_down(-HUGE_VAL), -kInf);
  EXPECT_EQ(round_up(-HUGE_VAL), -kInf);
  EXPECT_TRUE(std::isnan(round_down(std::nan(""))));
  EXPECT_TRUE(std::isnan(round_up(std::nan(""))));
}

}  // namespace
}  // namespace broadphase
