// grid-static: the three move policies agree, bulk updates rebuild at most
// once, the fixed-pair cache follows fixed objects that move or leave.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/grid_static.hpp>
#include <broadphase/scenes/scene.hpp>
#include <string>
#include <vector>

#include "structure_testing.hpp"

namespace broadphase {
namespace {

using testing::brute;
using testing::Pairs;
using testing::pairs_of;

Config with(std::initializer_list<std::pair<const std::string, std::string>> options) {
  Config c;
  c.options = options;
  return c;
}

TEST(GridStatic, PoliciesAgreeWithBruteForceOverAReplay) {
  for (const char* policy : {"rebuild", "patch", "auto"}) {
    SCOPED_TRACE(policy);
    Scene scene = generate(Distribution::even, 800, 4);
    GridStatic g(with({{"policy", policy}}));
    std::vector<Handle> h;
    for (std::size_t i = 0; i < scene.size(); ++i)
      h.push_back(
          g.insert(scene.objects[i], i, scene.is_moving(i) ? Motion::dynamic : Motion::fixed));
    for (int f = 0; f < 15; ++f) {
      step(scene);
      std::vector<Move> moves;
      for (std::size_t i = 0; i < scene.size(); ++i)
        if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
      g.update(moves);
      g.validate();
      ASSERT_EQ(pairs_of(g), brute(scene.objects)) << "frame " << f;
    }
  }
}

TEST(GridStatic, RebuildPolicyRepacksOncePerBatch) {
  GridStatic g(with({{"policy", "rebuild"}, {"cell", "10"}}));
  std::vector<Handle> h;
  for (int i = 0; i < 100; ++i) h.push_back(g.insert(Shape::sphere({i * 3.0, 0, 0}, 1), i));
  std::vector<Move> moves;
  for (int i = 0; i < 100; ++i) moves.push_back({h[i], Shape::sphere({i * 3.0 + 5, 1, 0}, 1)});
  const std::uint64_t before = g.rebuilds();
  g.update(moves);
  EXPECT_EQ(g.rebuilds(), before + 1);
  g.validate();
}

TEST(GridStatic, PatchPolicyMovesWithoutRepacking) {
  GridStatic g(with({{"policy", "patch"}, {"cell", "10"}}));
  std::vector<Handle> h;
  for (int i = 0; i < 200; ++i) h.push_back(g.insert(Shape::sphere({i * 7.0, 0, 0}, 1), i));
  const std::uint64_t before = g.rebuilds();
  // Small moves, a few crossing into a neighbouring cell each time.
  for (int round = 1; round <= 5; ++round) {
    std::vector<Move> moves;
    for (int i = 0; i < 200; i += 10)
      moves.push_back({h[i], Shape::sphere({i * 7.0 + round, 0, 0}, 1)});
    g.update(moves);
  }
  EXPECT_EQ(g.rebuilds(), before);
  g.validate();
}

TEST(GridStatic, FixedPairsAreCachedAndDroppedWhenAFixedObjectMoves) {
  GridStatic g(with({{"cell", "10"}}));
  const Handle a = g.insert(Shape::sphere({0, 0, 0}, 2), 0, Motion::fixed);
  const Handle b = g.insert(Shape::sphere({3, 0, 0}, 2), 1, Motion::fixed);
  g.insert(Shape::sphere({6, 0, 0}, 2), 2, Motion::fixed);
  EXPECT_EQ(g.cached_pairs(), 2u);
  g.update(b, Shape::sphere({100, 0, 0}, 2));  // b becomes dynamic
  EXPECT_EQ(g.cached_pairs(), 0u);
  EXPECT_TRUE(pairs_of(g).empty());
  g.update(b, Shape::sphere({1, 0, 0}, 2));
  EXPECT_EQ(pairs_of(g), (Pairs{{0, 1}}));
  g.remove(a);
  g.validate();
  EXPECT_TRUE(pairs_of(g).empty());
}

TEST(GridStatic, PlainModeIgnoresTheHint) {
  GridStatic g(with({{"fixed", "plain"}}));
  g.insert(Shape::sphere({0, 0, 0}, 2), 0, Motion::fixed);
  g.insert(Shape::sphere({1, 0, 0}, 2), 1, Motion::fixed);
  EXPECT_EQ(g.cached_pairs(), 0u);
  EXPECT_EQ(pairs_of(g), (Pairs{{0, 1}}));
  EXPECT_THROW(GridStatic(with({{"policy", "sometimes"}})), InvalidConfig);
}

TEST(GridStatic, BulkUpdateChecksEverythingBeforeChangingAnything) {
  GridStatic g;
  const Handle a = g.insert(Shape::sphere({0, 0, 0}, 1), 0);
  const Handle gone = g.insert(Shape::sphere({5, 0, 0}, 1), 1);
  g.remove(gone);
  const std::vector<Move> moves = {{a, Shape::sphere({50, 0, 0}, 1)},
                                   {gone, Shape::sphere({0, 0, 0}, 1)}};
  EXPECT_THROW(g.update(moves), InvalidHandle);
  EXPECT_EQ(g.shape(a).center.x, 0);
  g.validate();
}

TEST(GridStatic, LargeObjectsOverflowAndStayExact) {
  GridStatic g(with({{"cell", "1"}}));
  std::vector<Shape> shapes = {Shape::sphere({0, 0, 0}, 50), Shape::sphere({40, 0, 0}, 1),
                               Shape::box({0, 0, 0}, {100, 0.1, 0.1}), Shape::sphere({3, 3, 3}, 0)};
  for (std::size_t i = 0; i < shapes.size(); ++i)
    g.insert(shapes[i], i, i % 2 ? Motion::fixed : Motion::dynamic);
  EXPECT_EQ(g.overflow_count(), 2u);
  g.validate();
  EXPECT_EQ(pairs_of(g), brute(shapes));
}

}  // namespace
}  // namespace broadphase
