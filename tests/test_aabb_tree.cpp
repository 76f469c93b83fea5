// aabb-tree: every ordering, depth limit and front mode against brute force,
// the front's savings, early stops, and the inline stack.
#include <gtest/gtest.h>

#include <broadphase/aabb_tree.hpp>

#include "testing.hpp"

namespace broadphase {
namespace {

std::vector<FrameDigest> brute_frames(Scene scene, int frames) {
  std::vector<FrameDigest> out;
  for (int f = 0; f < frames; ++f) {
    if (f > 0) step(scene);
    out.push_back(testing::brute_force(scene.objects));
  }
  return out;
}

TEST(AabbTree, EveryOptionComboIsExact) {
  const Scene scene = generate(Distribution::clusters, 700, 4);
  const auto want = brute_frames(scene, 12);
  for (const char* order : {"leaves-first", "smaller-first", "hit-ratio", "near-far", "none"})
    for (const char* front : {"off", "basic", "deferred"})
      for (const char* depth : {"0", "3"}) {
        const std::string spec =
            std::string("aabb-tree:order=") + order + ",front=" + front + ",max_depth=" + depth;
        EXPECT_EQ(testing::replay(spec, scene, 12, true), want) << spec;
      }
}

TEST(AabbTree, ExplosionAndMarginsAreExact) {
  const Scene scene = generate(Distribution::explosion, 800, 2);
  const auto want = brute_frames(scene, 15);
  for (const char* spec : {"aabb-tree:margin=0", "aabb-tree:margin=50", "aabb-tree:front=basic",
                           "aabb-tree:front=deferred,margin=0"})
    EXPECT_EQ(testing::replay(spec, scene, 15, true), want) << spec;
}

// Replays a scene directly on an AabbTree and returns per-frame stats.
std::vector<TraversalStats> stats_of(const std::string& front, const Scene& start, int frames) {
  Config c;
  c.options["front"] = front;
  AabbTree t(c);
  Scene scene = start;
  std::vector<Handle> h;
  for (std::size_t i = 0; i < scene.size(); ++i)
    h.push_back(
        t.insert(scene.objects[i], i, scene.is_moving(i) ? Motion::dynamic : Motion::fixed));
  std::vector<TraversalStats> out;
  for (int f = 0; f < frames; ++f) {
    if (f > 0) {
      step(scene);
      for (std::size_t i = 0; i < scene.size(); ++i)
        if (scene.is_moving(i)) t.update(h[i], scene.objects[i]);
    }
    TraversalStats s;
    FrameDigest d;
    t.for_each_pair(
        [&](Handle a, Handle b) {
          d.add(static_cast<std::uint32_t>(t.user_data(a)),
                static_cast<std::uint32_t>(t.user_data(b)));
        },
        s);
    EXPECT_EQ(d, testing::brute_force(scene.objects)) << front << " frame " << f;
    out.push_back(s);
  }
  return out;
}

TEST(AabbTree, FrontTrackingTestsFewerNodePairs) {
  const Scene scene = generate(Distribution::even, 1500, 8);
  const auto off = stats_of("off", scene, 10);
  const auto basic = stats_of("basic", scene, 10);
  const auto deferred = stats_of("deferred", scene, 10);
  EXPECT_TRUE(basic[0].front_rebuilt);
  std::uint64_t t_off = 0, t_basic = 0, t_deferred = 0;
  for (int f = 1; f < 10; ++f) {
    EXPECT_FALSE(basic[f].front_rebuilt) << f;
    t_off += off[f].node_tests;
    t_basic += basic[f].node_tests;
    t_deferred += deferred[f].node_tests;
  }
  EXPECT_LT(t_basic, t_off);
  EXPECT_LT(t_deferred, t_off);
}

TEST(AabbTree, EarlyStopDiscardsThePartialFront) {
  const Scene scene = generate(Distribution::even, 500, 9);
  Config c;
  c.options["front"] = "basic";
  AabbTree t(c);
  for (std::size_t i = 0; i < scene.size(); ++i) t.insert(scene.objects[i], i);
  int seen = 0;
  EXPECT_TRUE(t.for_each_pair([&](Handle, Handle) { return ++seen < 5; }).stopped);
  EXPECT_EQ(seen, 5);
  FrameDigest d;
  TraversalStats s;
  t.for_each_pair(
      [&](Handle a, Handle b) {
        d.add(static_cast<std::uint32_t>(t.user_data(a)),
              static_cast<std::uint32_t>(t.user_data(b)));
      },
      s);
  EXPECT_TRUE(s.front_rebuilt);
  EXPECT_EQ(d, testing::brute_force(scene.objects));
}

TEST(AabbTree, DepthLimitFallsBackToBruteForce) {
  const Scene scene = generate(Distribution::even, 400, 10);
  Config c;
  c.options["max_depth"] = "2";
  AabbTree t(c);
  for (std::size_t i = 0; i < scene.size(); ++i) t.insert(scene.objects[i], i);
  TraversalStats s;
  std::uint64_t pairs = 0;
  t.for_each_pair([&](Handle, Handle) { ++pairs; }, s);
  EXPECT_GT(s.brute_pairs, 0u);
  EXPECT_EQ(pairs, testing::brute_force(scene.objects).pairs);
}

TEST(AabbTree, StaysShallowOnSortedInsertion) {
  // Inserting along a line is the worst order for a naive tree; the
  // surface-area choice and rotations keep it near logarithmic.
  AabbTree t;
  for (int i = 0; i < 4096; ++i)
    t.insert(Shape::sphere({i * 2.0, 0, 0}, 0.5), static_cast<std::uint64_t>(i));
  t.validate();
  EXPECT_LT(t.height(), 40);
  std::uint64_t hits = 0;
  t.query(Shape::sphere({100, 0, 0}, 1.6), [&](Handle) { ++hits; });
  EXPECT_EQ(hits, 3u);
}

TEST(AabbTree, InlineStackSpillsWithoutLoss) {
  detail::InlineStack<int, 4> s;
  for (int i = 0; i < 1000; ++i) s.push(i);
  EXPECT_EQ(s.size(), 1000u);
  for (int i = 999; i >= 0; --i) ASSERT_EQ(s.pop(), i);
  EXPECT_TRUE(s.empty());
}

TEST(AabbTree, RejectsBadOptions) {
  for (const char* spec : {"aabb-tree:order=random", "aabb-tree:front=lazy", "aabb-tree:margin=-1",
                           "aabb-tree:depth=3", "aabb-tree-front:front=maybe"})
    EXPECT_THROW(make_structure(spec), InvalidConfig) << spec;
}

}  // namespace
}  // namespace broadphase
