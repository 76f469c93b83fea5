// Scene format version 3 (filters and rays): the reader and writer, every
// rejection naming its line, the hit hashes, the brute-force oracle against
// the shared reference lines, every structure against them through the
// code path `run` takes (Replay, frame_line), and the generator's filters
// and rays.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <broadphase/scenes/brute_force.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "scene_testing.hpp"
#include "testing.hpp"

namespace broadphase::testing {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

Scene parse(const std::string& text) {
  std::istringstream in(text);
  return parse_scene(in, "v3.scene");
}

std::string written(const Scene& s) {
  std::ostringstream out;
  write_scene(out, s);
  return out.str();
}

// The message must start with "bad.scene:LINE:" and contain `part`.
using scene_testing::expect_rejected;

const std::string kHead = "broadphase-scene 3\nworld 100\nobjects 2\n";
const std::string kObjects = "sphere 1 2 3 4 0 0 0\nbox 5 6 7 1 2 3 0.5 0 0\n";

TEST(SceneV3, ReadsFiltersInDecimalAndHex) {
  const Scene s = parse(kHead +
                        "sphere 1 2 3 4 0 0 0 filter 0x10 0XfF\n"
                        "box 5 6 7 1 2 3 0.5 0 0 filter 010 4294967295\n");
  ASSERT_EQ(s.filters.size(), 2u);
  EXPECT_EQ(s.filter(0), (Filter{0x10, 0xff}));
  EXPECT_EQ(s.filter(1), (Filter{10, 0xffffffffu}));  // a leading 0 is not octal
  EXPECT_TRUE(s.has_filters());
  EXPECT_FALSE(s.has_rays());
}

TEST(SceneV3, FiltersAfterDefaultObjectsAndNoneAtAll) {
  const Scene a = parse(kHead + "sphere 1 2 3 4 0 0 0\nbox 5 6 7 1 2 3 0.5 0 0 filter 2 3\n");
  ASSERT_EQ(a.filters.size(), 2u);
  EXPECT_EQ(a.filter(0), Filter{});
  EXPECT_EQ(a.filter(1), (Filter{2, 3}));
  const Scene b = parse(kHead + kObjects);
  EXPECT_TRUE(b.filters.empty());
  EXPECT_EQ(b.filter(1), Filter{});
  EXPECT_EQ(b.version(), 2);
}

TEST(SceneV3, ReadsRays) {
  const Scene s = parse(kHead + kObjects +
                        "# the rays\nrays 4\n"
                        "ray 0 0 50  1 0 0  inf\n\n"
                        "ray 10 10 10 0 0.5 -1 250 filter 0x2\n"
                        "ray 1 1 1 0 0 0 -0\n"
                        "ray 1 1 1 0 0 0 +inf filter 7\n");
  ASSERT_EQ(s.rays.size(), 4u);
  EXPECT_EQ(s.rays[0].origin, (Vec3{0, 0, 50}));
  EXPECT_EQ(s.rays[0].dir, (Vec3{1, 0, 0}));
  EXPECT_EQ(s.rays[0].tmax, kInf);
  EXPECT_EQ(s.rays[0].mask, 0xffffffffu);
  EXPECT_EQ(s.rays[1].tmax, 250);
  EXPECT_EQ(s.rays[1].mask, 2u);
  EXPECT_TRUE(same_bits(s.rays[2].tmax, 0.0));  // -0 counts as 0
  EXPECT_EQ(s.rays[3].tmax, kInf);
  EXPECT_EQ(s.rays[3].mask, 7u);
  EXPECT_EQ(s.version(), 3);
  // An empty block is a file without rays.
  EXPECT_FALSE(parse(kHead + kObjects + "rays 0\n").has_rays());
  // A direction whose squared length is exactly the smallest normal double.
  EXPECT_EQ(
      parse(kHead + kObjects + "rays 1\nray 0 0 0 1.4916681462400413e-154 0 0 1\n").rays[0].dir.x,
      0x1p-511);
}

TEST(SceneV3, RoundTripIsBitExactAndWritesTheLeastVersion) {
  Scene s = generate(Distribution::half_boxes, 200, 3);
  add_filters(s, FilterKind::random, 0, 3);
  add_rays(s, 50, RayKind::mixed, 3);
  s.rays.push_back(Ray{{1e-300, -0.0, 5e-324}, {0x1p-511, 0, 0}, 0, 0});
  s.rays.push_back(Ray{{1e15, 2, 3}, {-1, 0, 0}, 1e300, 0x80000000u});
  const std::string text = written(s);
  EXPECT_EQ(text.rfind("broadphase-scene 3\n", 0), 0u);
  const Scene back = parse(text);
  ASSERT_EQ(back.size(), s.size());
  ASSERT_EQ(back.filters.size(), s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(back.objects[i], s.objects[i]) << i;
    EXPECT_EQ(back.filter(i), s.filter(i)) << i;
  }
  ASSERT_EQ(back.rays.size(), s.rays.size());
  for (std::size_t k = 0; k < s.rays.size(); ++k) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_TRUE(same_bits(back.rays[k].origin[a], s.rays[k].origin[a])) << k;
      EXPECT_TRUE(same_bits(back.rays[k].dir[a], s.rays[k].dir[a])) << k;
    }
    EXPECT_TRUE(same_bits(back.rays[k].tmax, s.rays[k].tmax)) << k;
    EXPECT_EQ(back.rays[k].mask, s.rays[k].mask) << k;
  }
  EXPECT_EQ(written(back), text);
  // Without filters and rays, the version 1 or 2 text, whatever was read.
  const Scene plain = parse(kHead + kObjects + "rays 0\n");
  EXPECT_EQ(written(plain),
            written(parse("broadphase-scene 2\nworld 100\nobjects 2\n" + kObjects)));
  EXPECT_EQ(written(plain).rfind("broadphase-scene 2\n", 0), 0u);
  // Filters that are all the default are no filters.
  Scene defaults = generate(Distribution::even, 10, 1);
  defaults.filters.assign(10, Filter{});
  EXPECT_EQ(written(defaults).rfind("broadphase-scene 1\n", 0), 0u);
}

TEST(SceneV3, RejectsEveryMalformedFileNamingTheLine) {
  const std::string v3 = kHead + kObjects;
  // Filters.
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1\n" + kObjects, 4, "filter with one value",
                  "two values");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 2 3\n", 4, "filter with three values");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter -1 2\n", 4, "negative group", "'-1'");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter +1 2\n", 4, "signed group");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 4294967296\n", 4, "mask of 2^32", "2^32");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 0x100000000\n", 4, "hex mask of 2^32");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 0x\n", 4, "0x without digits");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 0xg\n", 4, "not a hex digit");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 1.5\n", 4, "fractional mask");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 filter 1 99999999999999999999999\n", 4,
                  "mask beyond 64 bits");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0 group 1 2\n", 4, "not 'filter'");
  expect_rejected(kHead + "sphere 1 2 3 filter 1 2\n", 4, "filter in place of numbers");
  expect_rejected("broadphase-scene 2\nworld 100\nobjects 1\nsphere 1 2 3 4 0 0 0 filter 1 2\n", 4,
                  "filter in version 2", "broadphase-scene 3");
  // The rays block.
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0\n", 7, "ray without tmax");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 1 2\n", 7, "ray with an extra field");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 1 filter\n", 7, "ray filter without mask");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 1 filter 1 2\n", 7, "ray filter with two");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 1 filter -1\n", 7, "negative ray mask");
  expect_rejected(v3 + "rays 1\nray nan 0 0 1 0 0 1\n", 7, "NaN origin");
  expect_rejected(v3 + "rays 1\nray 0 inf 0 1 0 0 1\n", 7, "infinite origin");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 -inf 0 1\n", 7, "infinite direction");
  expect_rejected(v3 + "rays 1\nray 0 0 0 nan 0 0 1\n", 7, "NaN direction");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1e200 0 0 1\n", 7, "squared length overflows",
                  "overflows");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1e-160 0 0 1\n", 7, "squared length underflows",
                  "smallest normal");
  expect_rejected(v3 + "rays 1\nray 0 0 0 7.4583407312002067e-155 0 0 1\n", 7,
                  "squared length subnormal");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 nan\n", 7, "NaN tmax");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 -1\n", 7, "negative tmax", "negative");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 -inf\n", 7, "minus infinity tmax");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 x\n", 7, "tmax not a number");
  expect_rejected(v3 + "rays 2\nray 0 0 0 1 0 0 1\n", 7, "fewer rays than declared",
                  "declares 2 rays but has 1");
  expect_rejected(v3 + "rays 1\nray 0 0 0 1 0 0 1\nray 0 0 0 1 0 0 1\n", 8,
                  "more rays than declared", "more ray lines");
  expect_rejected(v3 + "rays x\n", 6, "ray count not a number");
  expect_rejected(v3 + "rays -1\n", 6, "negative ray count");
  expect_rejected(v3 + "rays\n", 6, "rays without a count");
  expect_rejected(v3 + "rays 0\nrays 0\n", 7, "two rays blocks", "second");
  expect_rejected(v3 + "rays 1\nsphere 1 2 3 4 0 0 0\n", 7, "an object in the rays block");
  expect_rejected(kHead + "sphere 1 2 3 4 0 0 0\nrays 0\n", 5, "rays before the last object",
                  "declares 2 objects but has 1");
  expect_rejected(v3 + "ray 0 0 0 1 0 0 1\n", 6, "ray without a block");
  expect_rejected("broadphase-scene 2\nworld 100\nobjects 2\n" + kObjects + "rays 0\n", 6,
                  "rays in version 2", "broadphase-scene 3");
  expect_rejected("broadphase-scene 4\nworld 10\nobjects 0\n", 1, "version 4");
}

TEST(SceneV3, ReadsPeriodicWorlds) {
  const Scene s = parse(
      "broadphase-scene 3\n# a comment\nworld 100 periodic zx\nobjects 3\n"
      "sphere 0 -5 100 49.999 99.999 0 -99.999\n"
      "box 100 200 0 49 1e6 49.5 0 -1e9 0\n"
      "sphere 50 50 50 0 0 0 0\n");
  EXPECT_EQ(s.periodic, (std::array<bool, 3>{true, false, true}));
  EXPECT_TRUE(s.is_periodic());
  EXPECT_EQ(s.version(), 3);
  EXPECT_EQ(s.objects[1].center, (Vec3{100, 200, 0}));  // y is not periodic: anything goes
  for (const char* axes : {"xyz", "xy", "z", "zyx", "yx"})
    EXPECT_TRUE(
        parse("broadphase-scene 3\nworld 10 periodic " + std::string(axes) + "\nobjects 0\n")
            .is_periodic())
        << axes;
  EXPECT_FALSE(parse(kHead + kObjects).is_periodic());
}

TEST(SceneV3, RejectsMalformedPeriodicWorldsNamingTheLine) {
  const std::string w = "broadphase-scene 3\nworld 100 periodic xz\nobjects 1\n";
  expect_rejected("broadphase-scene 3\nworld 100 periodic\nobjects 0\n", 2, "no axes",
                  "needs its axes");
  expect_rejected("broadphase-scene 3\nworld 100 periodic xx\nobjects 0\n", 2, "repeated axis",
                  "twice");
  expect_rejected("broadphase-scene 3\nworld 100 periodic xw\nobjects 0\n", 2, "unknown letter",
                  "not an axis");
  expect_rejected("broadphase-scene 3\nworld 100 periodic X\nobjects 0\n", 2, "capital letter",
                  "not an axis");
  expect_rejected("broadphase-scene 3\nworld 100 periodic x y\nobjects 0\n", 2, "two words");
  expect_rejected("broadphase-scene 3\nworld 100 periodical xyz\nobjects 0\n", 2, "not 'periodic'");
  expect_rejected("broadphase-scene 2\nworld 100 periodic xyz\nobjects 0\n", 2, "version 2",
                  "broadphase-scene 3");
  // A centre outside [0, L] on a periodic axis, not on the others.
  expect_rejected(w + "sphere -1e-300 0 0 1 0 0 0\n", 4, "x below 0", "outside [0, L]");
  expect_rejected(w + "sphere 0 0 100.00000000000001 1 0 0 0\n", 4, "z above L", "periodic axis z");
  expect_rejected(w + "box 5 5 -3 1 1 1 0 0 0\n", 4, "box z below 0", "'-3'");
  EXPECT_EQ(parse(w + "sphere 0 -7 100 1 0 0 0\n").objects[0].center, (Vec3{0, -7, 100}));
  // Sizes of L/2 or more on a periodic axis.
  expect_rejected(w + "sphere 5 5 5 50 0 0 0\n", 4, "radius L/2", "radius '50'");
  expect_rejected(w + "box 5 5 5 1 1 50 0 0 0\n", 4, "hz L/2", "hz '50'");
  expect_rejected(w + "box 5 5 5 60 1 1 0 0 0\n", 4, "hx above L/2", "not below L/2");
  EXPECT_EQ(parse(w + "box 5 5 5 1 70 49.999 0 0 0\n").objects[0].half.y, 70);  // y is not periodic
  // A velocity component of L or more on a periodic axis.
  expect_rejected(w + "sphere 5 5 5 1 100 0 0\n", 4, "vx = L", "vx '100'");
  expect_rejected(w + "sphere 5 5 5 1 0 0 -100\n", 4, "vz = -L", "in magnitude");
  expect_rejected(w + "box 5 5 5 1 1 1 0 0 -1e300\n", 4, "box vz huge", "vz");
  EXPECT_EQ(parse(w + "sphere 5 5 5 1 0 1e300 0\n").velocity[0].y, 1e300);
  // Further down, the line of the object at fault.
  expect_rejected(
      "broadphase-scene 3\nworld 100 periodic y\nobjects 2\nsphere 5 5 5 1 0 0 0\n\n"
      "sphere 5 101 5 1 0 0 0 filter 1 1\n",
      6, "second object", "y");
}

TEST(SceneV3, PeriodicRoundTripIsBitExact) {
  for (const char* axes : {"xyz", "xy", "y", "zx"}) {
    SCOPED_TRACE(axes);
    Scene s = generate(Distribution::half_boxes, 200, 5);
    make_periodic(s, parse_periodic_axes(axes));
    add_filters(s, FilterKind::random, 0, 5);
    s.objects[0].center = {0, 1000, 0x1p-1074};  // the faces and the smallest double
    s.objects[1].center = {std::nextafter(1000.0, 0.0), 0, 1000};
    const std::string text = written(s);
    EXPECT_NE(text.find("\nworld 1000 periodic " + periodic_axes_text(s.periodic) + "\n"),
              std::string::npos);
    const Scene back = parse(text);
    EXPECT_EQ(back.periodic, s.periodic);
    for (std::size_t i = 0; i < s.size(); ++i) {
      EXPECT_EQ(back.objects[i], s.objects[i]) << i;
      EXPECT_EQ(back.velocity[i], s.velocity[i]) << i;
    }
    EXPECT_EQ(written(back), text);
  }
  EXPECT_EQ(periodic_axes_text(parse_periodic_axes("zyx")), "xyz");
  EXPECT_THROW(parse_periodic_axes(""), std::invalid_argument);
}

TEST(SceneV3, PeriodicMotionWrapsAndReflectsElsewhere) {
  Scene s = parse(
      "broadphase-scene 3\nworld 10 periodic xz\nobjects 4\n"
      "sphere 9.5 9.5 0.25 1 1 1 -0.5\n"
      "sphere 10 0 10 1 0.5 0 0\n"
      "sphere 10 5 5 1 0 0 0\n"
      "sphere 0 5 3 1 -9.999999999999998 0 9\n");
  step(s);
  EXPECT_EQ(s.objects[0].center, (Vec3{0.5, 9.5, 9.75}));  // x, z wrap; y reflects
  EXPECT_EQ(s.velocity[0], (Vec3{1, -1, -0.5}));
  EXPECT_EQ(s.objects[1].center.x, 0.5);  // at L, moved: past L, so back by L
  EXPECT_EQ(s.objects[1].center.z, 0);    // at L and moving (on x): to 0 on z too
  EXPECT_EQ(s.objects[2].center.x, 10);   // a static object stays at L
  EXPECT_EQ(s.objects[3].center.x, -9.999999999999998 + 10);
  EXPECT_EQ(s.objects[3].center.z, 2);  // 12 >= L: 12 - 10
  double p = -1e-300;
  step_axis_periodic(p, 0, 10);  // a rounding of p + L lands on L exactly
  EXPECT_EQ(p, 10);
}

TEST(SceneV3, HitHashFollowsTheContract) {
  const double t = 12.5;
  std::uint64_t bits;
  std::memcpy(&bits, &t, sizeof bits);
  EXPECT_EQ(hit_hash(3, 7, t), splitmix64(splitmix64((std::uint64_t{3} << 32) | 7) + bits));
  // The closest hit: the smallest t, then the smallest id, in any order.
  RayHits a(2), b(2);
  a.add(9, 1.0);
  a.add(4, 2.0);
  a.add(5, 1.0);
  b.add(5, 1.0);
  b.add(4, 2.0);
  b.add(9, 1.0);
  HitDigest da, db;
  a.add_to(da);
  b.add_to(db);
  EXPECT_EQ(da, db);
  EXPECT_EQ(da.hits, 3u);
  EXPECT_EQ(da.closest, hit_hash(2, 5, 1.0));
  // A ray without hits adds nothing, not even to the closest hash.
  HitDigest none;
  RayHits(0).add_to(none);
  EXPECT_EQ(none, HitDigest{});
  EXPECT_EQ(frame_line(4, FrameDigest{2, 0xab}, nullptr), "4 2 00000000000000ab");
  EXPECT_EQ(frame_line(4, FrameDigest{2, 0xab}, &da),
            "4 2 00000000000000ab 3 " + hex16(da.hash) + " " + hex16(da.closest));
}

// The version 3 reference scenes (tests/data/scenes/v3: the shared ones,
// and scenes made by `gen` with lines from the oracle).
struct V3Scene {
  std::string name;
  std::string path;
  std::vector<std::string> expected;
};

std::vector<V3Scene> v3_scenes() {
  std::vector<V3Scene> out;
  const std::filesystem::path dir = std::filesystem::path(BROADPHASE_TEST_DATA) / "scenes" / "v3";
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".scene") continue;
    V3Scene s{entry.path().stem().string(), entry.path().string(), {}};
    std::ifstream in(std::filesystem::path(entry.path()).replace_extension(".expected"));
    for (std::string line; std::getline(in, line);) s.expected.push_back(line);
    out.push_back(std::move(s));
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  return out;
}

TEST(SceneV3, OracleReproducesEveryReferenceScene) {
  const auto scenes = v3_scenes();
  ASSERT_GE(scenes.size(), 4u) << "version 3 reference scenes missing";
  for (const V3Scene& ref : scenes) {
    SCOPED_TRACE(ref.name);
    ASSERT_FALSE(ref.expected.empty());
    BruteForceReplay replay(read_scene(ref.path));
    const bool rays = replay.scene().has_rays();
    for (std::size_t f = 0; f < ref.expected.size(); ++f) {
      const BruteForceFrame r = replay.next();
      ASSERT_EQ(frame_line(static_cast<int>(f), r.pairs, rays ? &r.hits : nullptr),
                ref.expected[f]);
    }
  }
}

// Every structure through Replay, as `run` prints it. `kind` picks the
// scenes: periodic worlds (through the periodic adapter), those with
// filters (which wait on each structure applying them inside its pair
// paths), or those with rays alone.
enum class V3Kind { rays, filters, periodic };

V3Kind kind_of(const Scene& scene) {
  if (scene.is_periodic()) return V3Kind::periodic;
  return scene.has_filters() ? V3Kind::filters : V3Kind::rays;
}

void replay_v3_scenes(const std::string& spec, V3Kind kind) {
  int done = 0;
  for (const V3Scene& ref : v3_scenes()) {
    const Scene scene = read_scene(ref.path);
    if (kind_of(scene) != kind) continue;
    SCOPED_TRACE(ref.name);
    Config config;
    config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    config.expected_objects = scene.size();
    auto bp = make_structure(spec, config);
    const bool rays = scene.has_rays();
    Replay replay(*bp, scene);
    ASSERT_EQ(replay.periodic() != nullptr, kind == V3Kind::periodic);
    for (std::size_t f = 0; f < ref.expected.size(); ++f) {
      const FrameResult r = replay.next();
      if (replay.periodic())
        replay.periodic()->validate();
      else
        bp->validate();
      ASSERT_EQ(frame_line(static_cast<int>(f), r, rays), ref.expected[f]);
    }
    ++done;
  }
  EXPECT_GE(done, kind == V3Kind::periodic ? 3 : 2);
}

class ReferenceScenesV3 : public ::testing::TestWithParam<std::string> {};

TEST_P(ReferenceScenesV3, RaysReproduceEveryFrame) { replay_v3_scenes(GetParam(), V3Kind::rays); }

TEST_P(ReferenceScenesV3, FiltersReproduceEveryFrame) {
  replay_v3_scenes(GetParam(), V3Kind::filters);
}

TEST_P(ReferenceScenesV3, PeriodicReproduceEveryFrame) {
  replay_v3_scenes(GetParam(), V3Kind::periodic);
}

// The structure against the oracle on scenes `gen` makes, moving, for a
// few frames: every kind of ray, with or without filters (and rays with
// masks).
void match_oracle_on_generated(const std::string& spec, bool filters) {
  for (RayKind kind :
       {RayKind::random, RayKind::lidar, RayKind::axis, RayKind::inside, RayKind::zero}) {
    SCOPED_TRACE(std::string(to_string(kind)));
    Scene scene = generate(Distribution::box_decades, 300, 11);
    if (filters) add_filters(scene, FilterKind::layers, 5, 11);
    add_rays(scene, 60, kind, 11);
    Config config;
    config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    config.expected_objects = scene.size();
    auto bp = make_structure(spec, config);
    Replay replay(*bp, scene);
    BruteForceReplay oracle(scene);
    for (int f = 0; f < 4; ++f) {
      const FrameResult r = replay.next();
      const BruteForceFrame want = oracle.next();
      ASSERT_EQ(r.hits, want.hits) << "frame " << f;
      ASSERT_EQ(r.digest, want.pairs) << "frame " << f;
    }
  }
  // Filters on a crowded scene, where they remove most pairs.
  if (filters)
    for (FilterKind kind : {FilterKind::layers, FilterKind::random}) {
      Scene scene = generate(Distribution::uneven, 600, 12);
      add_filters(scene, kind, 16, 12);
      const auto got = replay(spec, scene, 3, true);
      BruteForceReplay oracle(scene);
      for (int f = 0; f < 3; ++f) ASSERT_EQ(got[f], oracle.next().pairs) << "frame " << f;
    }
}

TEST_P(ReferenceScenesV3, MatchOracleOnGeneratedRays) {
  match_oracle_on_generated(GetParam(), false);
}

TEST_P(ReferenceScenesV3, MatchOracleOnGeneratedFilters) {
  match_oracle_on_generated(GetParam(), true);
}

// A periodic world made to hurt the adapter (seeded): L = 100, periodic on
// `axes`; spheres and boxes, a quarter exactly on a face (0 or L), a
// quarter near an edge or a corner, one in ten with a size just below L/2,
// a third static, the movers fast enough to wrap often (up to 0.3 L a
// frame, some just below L), and a few stacked on each other.
Scene hurtful_periodic_scene(std::array<bool, 3> axes, std::size_t n, std::uint64_t seed,
                             bool filters) {
  Rng rng(seed);
  Scene s;
  s.world = 100;
  s.periodic = axes;
  const double L = s.world;
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 c{rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
    const double u = rng.uniform();
    if (u < 0.25) {
      c[static_cast<int>(rng.below(3))] = rng.below(2) ? L : 0;
    } else if (u < 0.5) {
      for (int a = 0; a < 3; ++a)
        if (rng.below(3) != 0) c[a] = rng.below(2) ? rng.uniform(0, 3) : L - rng.uniform(0, 3);
    } else if (u < 0.55 && i > 0) {
      c = s.objects[rng.below(i)].center;
    }
    const double size =
        rng.uniform() < 0.1 ? std::nextafter(L / 2, 0.0) - rng.uniform(0, 3) : rng.uniform(0, 8);
    Shape shape = rng.below(2) ? Shape::sphere(c, size)
                               : Shape::box(c, {size, rng.uniform(0, size), rng.uniform(0, 4)});
    Vec3 v{};
    if (rng.uniform() < 0.67)
      for (int a = 0; a < 3; ++a)
        v[a] = rng.uniform() < 0.05 ? std::nextafter(L, 0.0) * (rng.below(2) ? 1 : -1)
                                    : rng.uniform(-0.3 * L, 0.3 * L);
    s.objects.push_back(shape);
    s.velocity.push_back(v);
  }
  if (filters) add_filters(s, FilterKind::random, 0, seed);
  return s;
}

// Every structure through the periodic adapter against the oracle: slabs,
// tubes and bulk, with and without filters, moving and wrapping for a few
// frames, the adapter validated each frame.
TEST_P(ReferenceScenesV3, PeriodicMatchesOracleOnHurtfulScenes) {
  const std::array<bool, 3> kAxes[] = {
      {true, true, true}, {true, true, false}, {true, false, false}, {false, false, true}};
  for (std::uint64_t seed = 1; seed <= 2; ++seed)
    for (const auto& axes : kAxes)
      for (bool filters : {false, true}) {
        SCOPED_TRACE(::testing::Message() << "seed " << seed << " periodic "
                                          << periodic_axes_text(axes) << " filters " << filters);
        const Scene scene = hurtful_periodic_scene(axes, 120, seed, filters);
        Config config;
        config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
        auto bp = make_structure(GetParam(), config);
        Replay replay(*bp, scene);
        BruteForceReplay oracle(scene);
        for (int f = 0; f < 5; ++f) {
          const FrameResult r = replay.next();
          replay.periodic()->validate();
          ASSERT_EQ(r.digest, oracle.next().pairs) << "frame " << f;
        }
      }
}

INSTANTIATE_TEST_SUITE_P(All, ReferenceScenesV3, ::testing::ValuesIn(structure_specs()),
                         StructureParamName{});

TEST(GenV3, FiltersAndRaysLeaveTheObjectsAndAreDeterministic) {
  const Scene plain = generate(Distribution::uneven, 300, 9);
  Scene a = plain, b = plain;
  add_filters(a, FilterKind::layers, 6, 9);
  add_rays(a, 100, RayKind::mixed, 9);
  add_filters(b, FilterKind::layers, 6, 9);
  add_rays(b, 100, RayKind::mixed, 9);
  EXPECT_EQ(written(a), written(b));
  ASSERT_EQ(a.size(), plain.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a.objects[i], plain.objects[i]);
  Scene c = plain;
  add_filters(c, FilterKind::layers, 6, 10);
  EXPECT_NE(written(a), written(c).substr(0, written(a).size()));
}

TEST(GenV3, LayersPairOnlyWithTheirNeighbours) {
  Scene s = generate(Distribution::even, 2000, 4);
  add_filters(s, FilterKind::layers, 16, 4);
  std::vector<int> seen(16, 0);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Filter f = s.filter(i);
    ASSERT_EQ(std::popcount(f.group), 1);
    const int l = std::countr_zero(f.group);
    ++seen[l];
    EXPECT_EQ(f.mask, (1u << l) | (1u << (l + 1) % 16) | (1u << (l + 15) % 16));
  }
  for (int n : seen) EXPECT_GT(n, 50);
  // Layers 0 and 2 ignore each other; 0 and 1, 0 and 15 pair.
  EXPECT_FALSE(filters_pass(Filter{1u << 0, 0x8003u}, Filter{1u << 2, 0xeu}));
  Scene one = generate(Distribution::even, 5, 4);
  add_filters(one, FilterKind::layers, 1, 4);
  EXPECT_EQ(one.filter(3), (Filter{1, 1}));
  EXPECT_THROW(add_filters(one, FilterKind::layers, 0, 4), std::invalid_argument);
  EXPECT_THROW(add_filters(one, FilterKind::layers, 33, 4), std::invalid_argument);
}

TEST(GenV3, EveryKindOfRayIsValidAndCovered) {
  Scene s = generate(Distribution::half_boxes, 400, 2);
  add_filters(s, FilterKind::random, 0, 2);
  add_rays(s, 2000, RayKind::mixed, 2);
  ASSERT_EQ(s.rays.size(), 2000u);
  std::size_t zero_dir = 0, zero_tmax = 0, inf_tmax = 0, finite_tmax = 0, masked = 0, axis = 0,
              at_zero = 0;
  for (const Ray& r : s.rays) {
    ASSERT_TRUE(is_valid(r)) << ray_problem(r);
    const int zeros = (r.dir.x == 0) + (r.dir.y == 0) + (r.dir.z == 0);
    zero_dir += zeros == 3;
    axis += zeros == 2;
    zero_tmax += r.tmax == 0;
    inf_tmax += std::isinf(r.tmax);
    finite_tmax += r.tmax > 0 && std::isfinite(r.tmax);
    masked += r.mask != 0xffffffffu;
    for (const Shape& o : s.objects) {
      double t = 0;
      if (ray_hit(r, o, t) && t == 0) {
        ++at_zero;
        break;
      }
    }
  }
  for (std::size_t n : {zero_dir, zero_tmax, inf_tmax, finite_tmax, masked, axis, at_zero})
    EXPECT_GT(n, 20u);
  for (const char* name : {"mixed", "random", "lidar", "axis", "inside", "zero"})
    EXPECT_EQ(to_string(parse_ray_kind(name)), name);
  EXPECT_THROW(parse_ray_kind("laser"), std::invalid_argument);
  // A lidar fan starts at one point.
  Scene fan = generate(Distribution::even, 10, 5);
  add_rays(fan, 64, RayKind::lidar, 5);
  for (const Ray& r : fan.rays) EXPECT_EQ(r.origin, fan.rays[0].origin);
}

}  // namespace
}  // namespace broadphase::testing
