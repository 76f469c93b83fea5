// Scene files: bit-exact round trips, every rejection with FILE:LINE, the
// contract's motion step, the pair hash, and the study's generator.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/scenes/scene.hpp>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>

#include "scene_testing.hpp"

namespace broadphase {
namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expect_same_bits(const Scene& a, const Scene& b) {
  ASSERT_TRUE(same_bits(a.world, b.world));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.objects[i].kind, b.objects[i].kind) << i;
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(same_bits(a.objects[i].center[k], b.objects[i].center[k])) << i;
      ASSERT_TRUE(same_bits(a.objects[i].half[k], b.objects[i].half[k])) << i;
      ASSERT_TRUE(same_bits(a.velocity[i][k], b.velocity[i][k])) << i;
    }
  }
}

Scene round_trip(const Scene& s) {
  std::stringstream io;
  write_scene(io, s);
  return parse_scene(io, "round-trip");
}

TEST(Scene, RoundTripIsBitExact) {
  for (Distribution d : kAllDistributions) {
    const Scene s = generate(d, 300, 17);
    expect_same_bits(s, round_trip(s));
  }
  Scene odd;
  odd.world = 0.1;
  const double awkward[] = {0.1,
                            1.0 / 3,
                            -0.0,
                            5e-324,
                            1e-300,
                            1e300,
                            -1e300,
                            0x1.fffffffffffffp+1023,
                            123456789.123456789,
                            2.5e-310};
  for (double v : awkward) {
    odd.objects.push_back(Shape::sphere({v, -v, v / 7}, std::fabs(v)));
    odd.velocity.push_back({v, 0, -v});
  }
  odd.objects.push_back(Shape::box({1, 2, 3}, {0.1, 0.2, 0.3}));
  odd.velocity.push_back({});
  EXPECT_TRUE(odd.has_boxes());
  expect_same_bits(odd, round_trip(odd));
}

TEST(Scene, WritesVersionOneWithoutBoxes) {
  Scene s;
  s.world = 10;
  s.objects.push_back(Shape::sphere({1, 2, 3}, 0.5));
  s.velocity.push_back({0, 0, 0});
  std::stringstream io;
  write_scene(io, s);
  EXPECT_EQ(io.str().rfind("broadphase-scene 1\nworld 10\nobjects 1\n", 0), 0u) << io.str();
}

TEST(Scene, AcceptsCommentsBlankLinesAndCarriageReturns) {
  std::istringstream in(
      "broadphase-scene 2\r\n# a comment\n\nworld 100\n  # indented comment\nobjects 2\n"
      "sphere 1 2 3 4 0 0 0\r\n\n# between\nbox 5 6 7 1 2 3 0.5 0 0\n# trailing\n");
  const Scene s = parse_scene(in, "ok.scene");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s.objects[1], Shape::box({5, 6, 7}, {1, 2, 3}));
  EXPECT_TRUE(s.is_moving(1));
  EXPECT_FALSE(s.is_moving(0));
}

TEST(Scene, AcceptsAByteOrderMarkAndPlusSigns) {
  std::istringstream in(
      "\xEF\xBB\xBF"
      "broadphase-scene 1\nworld +10\nobjects 1\n+1 2 +3e0 4 +0.5 -0 0\n");
  const Scene s = parse_scene(in, "ok.scene");
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s.world, 10);
  EXPECT_EQ(s.objects[0], Shape::sphere({1, 2, 3}, 4));
  EXPECT_EQ(s.velocity[0].x, 0.5);
}

// The message must start with "bad.scene:LINE:".
using scene_testing::expect_rejected;

TEST(Scene, RejectsEveryMalformedFileNamingTheLine) {
  const std::string v1 = "broadphase-scene 1\nworld 10\nobjects 1\n";
  const std::string v2 = "broadphase-scene 2\nworld 10\nobjects 1\n";
  expect_rejected("", 0, "empty file");
  expect_rejected("broadphase-scene 4\nworld 10\nobjects 0\n", 1, "wrong header");
  expect_rejected("\nbroadphase-scene 1\nworld 10\nobjects 0\n", 1, "header not on line 1");
  expect_rejected("broadphase-scene 1\nobjects 0\n", 2, "missing world");
  expect_rejected("broadphase-scene 1\nworld\nobjects 0\n", 2, "world without a value");
  expect_rejected("broadphase-scene 1\nworld 0\nobjects 0\n", 2, "world 0");
  expect_rejected("broadphase-scene 1\nworld -5\nobjects 0\n", 2, "negative world");
  expect_rejected("broadphase-scene 1\nworld nan\nobjects 0\n", 2, "NaN world");
  expect_rejected("broadphase-scene 1\nworld 1e999\nobjects 0\n", 2, "world out of range");
  expect_rejected("broadphase-scene 1\nworld 10\n", 2, "missing objects line");
  expect_rejected("broadphase-scene 1\nworld 10\nobjects x\n", 3, "count not a number");
  expect_rejected("broadphase-scene 1\nworld 10\nobjects -1\n", 3, "negative count");
  expect_rejected("broadphase-scene 1\nworld 10\nobjects 1.5\n", 3, "fractional count");
  expect_rejected(v1 + "1 2 3 4 0 0\n", 4, "missing field");
  expect_rejected(v1 + "1 2 3 4 0 0 0 9\n", 4, "extra field");
  expect_rejected(v1 + "1 abc 3 4 0 0 0\n", 4, "not a number");
  expect_rejected(v1 + "1 2 3 4 0 0 0x\n", 4, "trailing garbage");
  expect_rejected(v1 + "1 ++2 3 4 0 0 0\n", 4, "two plus signs");
  expect_rejected(v1 + "1 +-2 3 4 0 0 0\n", 4, "plus then minus");
  expect_rejected(v1 + "1 + 3 4 0 0 0\n", 4, "a lone plus");
  expect_rejected(v1 + "1 2 +inf 4 0 0 0\n", 4, "plus infinity");
  expect_rejected(v1 + "1 nan 3 4 0 0 0\n", 4, "NaN");
  expect_rejected(v1 + "1 2 inf 4 0 0 0\n", 4, "infinity");
  expect_rejected(v1 + "1 2 3 4 0 -inf 0\n", 4, "infinite velocity");
  expect_rejected(v1 + "1 2 3 -4 0 0 0\n", 4, "negative radius");
  expect_rejected(v1 + "1 2 3 4 0 0 0\n1 2 3 4 0 0 0\n", 5, "more lines than declared");
  expect_rejected("broadphase-scene 1\nworld 10\nobjects 2\n1 2 3 4 0 0 0\n# end\n", 5,
                  "fewer lines than declared");
  expect_rejected(v2 + "cube 1 2 3 4 0 0 0\n", 4, "unknown kind");
  expect_rejected(v2 + "1 2 3 4 0 0 0\n", 4, "version 2 without a kind");
  expect_rejected(v2 + "box 1 2 3 4 5 0 0 0\n", 4, "box missing a field");
  expect_rejected(v2 + "box 1 2 3 4 -5 6 0 0 0\n", 4, "negative half-extent");
  expect_rejected(v2 + "sphere 1 2 3 4 0 0 0 0 0\n", 4, "sphere with box fields");
  expect_rejected(v1 + "sphere 1 2 3 4 0 0 0\n", 4, "kind in version 1");
}

TEST(Scene, ReadSceneNamesAMissingFile) {
  try {
    read_scene("/nonexistent/dir/x.scene");
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/x.scene"), std::string::npos);
  }
}

TEST(Scene, StepMovesAndReflectsAxisByAxis) {
  Scene s;
  s.world = 1000;
  s.objects = {Shape::sphere({999, 0.5, 500}, 1), Shape::sphere({10, 20, 30}, 1),
               Shape::box({500, 500, 500}, {1, 2, 3})};
  s.velocity = {{2, -1, 0.25}, {0, 0, 0}, {-600, 600, 0}};
  step(s);
  EXPECT_EQ(s.objects[0].center, (Vec3{999, 0.5, 500.25}));  // 1001 -> 999, -0.5 -> 0.5
  EXPECT_EQ(s.velocity[0], (Vec3{-2, 1, 0.25}));
  EXPECT_EQ(s.objects[1].center, (Vec3{10, 20, 30}));  // static
  EXPECT_EQ(s.objects[2].center, (Vec3{100, 900, 500}));
  EXPECT_EQ(s.velocity[2], (Vec3{600, -600, 0}));
  EXPECT_EQ(s.objects[2].half, (Vec3{1, 2, 3}));
  // Exactly on a wall: no reflection (only p < 0 or p > L reflect).
  double p = 999, v = 1;
  step_axis(p, v, 1000);
  EXPECT_EQ(p, 1000);
  EXPECT_EQ(v, 1);
  p = 1, v = -1;
  step_axis(p, v, 1000);
  EXPECT_EQ(p, 0);
  EXPECT_EQ(v, -1);
}

TEST(Scene, PairHashAndDigest) {
  EXPECT_EQ(splitmix64(0), 0xe220a8397b1dcdafull);
  EXPECT_EQ(pair_hash(3, 9), pair_hash(9, 3));
  EXPECT_EQ(pair_hash(3, 9), splitmix64((std::uint64_t{3} << 32) | 9));
  FrameDigest a, b;
  a.add(1, 2);
  a.add(5, 4);
  b.add(4, 5);
  b.add(2, 1);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a.pairs, 2u);
  EXPECT_EQ(hex16(0xabcull), "0000000000000abc");
  EXPECT_EQ(hex16(~0ull), "ffffffffffffffff");
}

TEST(Scene, StudyWorkloadsFollowTheContract) {
  const Scene even = generate(Distribution::even, 1000, 5);
  const Scene again = generate(Distribution::even, 1000, 5);
  expect_same_bits(even, again);
  const Scene uneven = generate(Distribution::uneven, 1000, 5);
  for (const Scene* s : {&even, &uneven}) {
    EXPECT_EQ(s->world, 1000);
    std::size_t moving = 0, low = 0;
    for (std::size_t i = 0; i < s->size(); ++i) {
      const Shape& o = s->objects[i];
      EXPECT_TRUE(o.is_sphere());
      EXPECT_GE(o.radius(), 0.5);
      EXPECT_LE(o.radius(), 50);
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(o.center[a], 0);
        EXPECT_LE(o.center[a], 1000);
      }
      if (s->is_moving(i)) {
        ++moving;
        const Vec3& v = s->velocity[i];
        const double speed = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
        EXPECT_GE(speed, 0.1 - 1e-12);
        EXPECT_LE(speed, 2.0 + 1e-12);
      }
      if (o.center.y <= 100) ++low;
    }
    EXPECT_EQ(moving, 200u);
    if (s == &uneven)
      EXPECT_GE(low, 800u);
    else
      EXPECT_LT(low, 200u);
  }
  const Scene scaled = generate(Distribution::scaled_even, 800, 5);
  EXPECT_DOUBLE_EQ(scaled.world, 500);
  EXPECT_THROW(parse_distribution("lumpy"), std::invalid_argument);
  EXPECT_EQ(parse_distribution("scaled-uneven"), Distribution::scaled_uneven);
}

// The shaped worlds: half spheres, half boxes in quarters (poles, slabs,
// three independent half sides, cubes), one slab in twenty of zero
// thickness, sizes and placement as generate() says.
TEST(Scene, ShapedWorldsMakeTheirShapes) {
  for (Distribution d :
       {Distribution::shapes_uneven, Distribution::shapes_decades, Distribution::shapes_flat}) {
    SCOPED_TRACE(to_string(d));
    const Scene s = generate(d, 8000, 3);
    expect_same_bits(s, generate(d, 8000, 3));
    EXPECT_EQ(parse_distribution(to_string(d)), d);
    const bool decades = d == Distribution::shapes_decades;
    const double lo = decades ? 0.01 : 0.5, hi = decades ? 100 : 50;
    std::size_t spheres = 0, poles = 0, slabs = 0, flat_slabs = 0, cubes = 0, others = 0;
    std::size_t moving = 0, low = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      const Shape& o = s.objects[i];
      if (s.is_moving(i)) ++moving;
      if (o.center.y <= 100) ++low;
      if (d == Distribution::shapes_flat) {
        EXPECT_GE(o.center.y, 0);
        EXPECT_LE(o.center.y, 1);
      }
      if (o.is_sphere()) {
        ++spheres;
        EXPECT_GE(o.radius(), lo * (1 - 1e-12));
        EXPECT_LE(o.radius(), decades ? hi : 5.0);
        continue;
      }
      double h[3] = {o.half.x, o.half.y, o.half.z};
      std::sort(h, h + 3);
      EXPECT_LE(h[2], hi * (1 + 1e-12));
      if (h[0] == h[2]) {
        ++cubes;
      } else if (h[1] == h[2] && h[0] == 0) {
        ++flat_slabs;
      } else if (h[1] == h[2] && h[2] / h[0] >= 10 * (1 - 1e-12) &&
                 h[2] / h[0] <= 100 * (1 + 1e-12)) {
        ++slabs;
      } else if (h[2] / h[1] >= 10 * (1 - 1e-12) && h[2] / h[1] <= 100 * (1 + 1e-12) &&
                 h[2] / h[0] <= 100 * (1 + 1e-12)) {
        ++poles;
      } else {
        ++others;
        EXPECT_GE(h[0], lo * (1 - 1e-12));
      }
    }
    EXPECT_EQ(moving, 1600u);
    EXPECT_NEAR(static_cast<double>(spheres), 4000, 200);
    // Three independent half sides fall among poles or slabs now and then.
    for (std::size_t quarter : {poles, slabs + flat_slabs, cubes, others})
      EXPECT_NEAR(static_cast<double>(quarter), 1000, 150);
    EXPECT_NEAR(static_cast<double>(flat_slabs), 50, 25);
    if (d != Distribution::shapes_flat) {
      EXPECT_GE(low, 6400u);
    }
  }
}

}  // namespace
}  // namespace broadphase
