// sap: endpoint order, the incrementally kept pair set, and coherent motion.
#include <gtest/gtest.h>

#include <broadphase/sap.hpp>

#include "testing.hpp"

namespace broadphase {
namespace {

std::size_t pair_count(const Sap& s) {
  std::size_t n = 0;
  s.for_each_pair([&](Handle, Handle) { ++n; });
  return n;
}

TEST(Sap, TouchingBoxesAndSignedZerosOverlap) {
  Sap s;
  // Two points at -0 and +0: the float keys differ in sign but must compare
  // as equal endpoints, or the pair would be lost.
  s.insert(Shape::sphere({-0.0, -0.0, -0.0}, 0), 0);
  s.insert(Shape::sphere({0.0, 0.0, 0.0}, 0), 1);
  // Two boxes touching face to face.
  s.insert(Shape::box({10, 0, 0}, {1, 1, 1}), 2);
  s.insert(Shape::box({12, 0, 0}, {1, 1, 1}), 3);
  s.validate();
  EXPECT_EQ(pair_count(s), 2u);
}

TEST(Sap, PairSetFollowsMovesAndRemovals) {
  Sap s;
  const Handle a = s.insert(Shape::sphere({0, 0, 0}, 1), 0);
  const Handle b = s.insert(Shape::sphere({5, 0, 0}, 1), 1);
  EXPECT_EQ(s.box_pairs(), 0u);
  s.update(b, Shape::sphere({1.5, 0, 0}, 1));
  s.validate();
  EXPECT_EQ(s.box_pairs(), 1u);
  EXPECT_EQ(pair_count(s), 1u);
  // Jump clean over the other object: both crossings must cancel out.
  s.update(b, Shape::sphere({-10, 0, 0}, 1));
  s.validate();
  EXPECT_EQ(s.box_pairs(), 0u);
  s.update(b, Shape::sphere({0.5, 0.5, 0}, 1));
  EXPECT_EQ(s.box_pairs(), 1u);
  s.remove(a);
  s.validate();
  EXPECT_EQ(s.box_pairs(), 0u);
  EXPECT_THROW(s.remove(a), InvalidHandle);
}

TEST(Sap, CoherentMotionCrossesFewEndpoints) {
  const Scene scene = generate(Distribution::even, 800, 3);
  Config c;
  auto bp = std::make_unique<Erased<Sap>>(c);
  Scene moving = scene;
  std::vector<Handle> h;
  for (std::size_t i = 0; i < scene.size(); ++i)
    h.push_back(bp->insert(scene.objects[i], i, Motion::dynamic));
  const std::uint64_t before = bp->get().swaps();
  for (int f = 0; f < 10; ++f) {
    step(moving);
    std::vector<Move> moves;
    for (std::size_t i = 0; i < moving.size(); ++i)
      if (moving.is_moving(i)) moves.push_back({h[i], moving.objects[i]});
    bp->update(moves);
    bp->validate();
    FrameDigest d;
    bp->get().for_each_pair([&](Handle x, Handle y) {
      d.add(static_cast<std::uint32_t>(bp->user_data(x)),
            static_cast<std::uint32_t>(bp->user_data(y)));
    });
    EXPECT_EQ(d, testing::brute_force(moving.objects)) << "frame " << f;
  }
  // 160 movers at speed <= 2 among 800 objects: a few crossings each, far
  // from the n per object a re-sort would touch.
  const double per_mover_per_frame = static_cast<double>(bp->get().swaps() - before) / (160.0 * 10);
  EXPECT_LT(per_mover_per_frame, 40.0);
}

TEST(Sap, IncoherentBatchesRebuildAndStayExact) {
  Scene scene = generate(Distribution::explosion, 1500, 6);
  Sap s;
  std::vector<Handle> h;
  for (std::size_t i = 0; i < scene.size(); ++i) h.push_back(s.insert(scene.objects[i], i));
  for (int f = 0; f < 14; ++f) {
    step(scene);
    std::vector<Move> moves;
    for (std::size_t i = 0; i < scene.size(); ++i) moves.push_back({h[i], scene.objects[i]});
    s.update(moves);
    s.validate();
    FrameDigest d;
    s.for_each_pair([&](Handle x, Handle y) {
      d.add(static_cast<std::uint32_t>(s.user_data(x)), static_cast<std::uint32_t>(s.user_data(y)));
    });
    ASSERT_EQ(d, testing::brute_force(scene.objects)) << "frame " << f;
  }
  EXPECT_GT(s.rebuilds(), 0u);
}

TEST(Sap, LargeObjectsComeAndGo) {
  Sap s;
  std::vector<Handle> small;
  for (int i = 0; i < 50; ++i)
    small.push_back(s.insert(Shape::sphere({i * 10.0, 0, 0}, 1), static_cast<std::uint64_t>(i)));
  const Handle big = s.insert(Shape::box({250, 0, 0}, {1e6, 1, 1}), 99);
  EXPECT_EQ(s.box_pairs(), 50u);
  s.remove(big);
  s.update(std::span<const Move>{});
  s.validate();
  EXPECT_EQ(s.box_pairs(), 0u);
  std::size_t hits = 0;
  s.query(Shape::sphere({100, 0, 0}, 0.5), [&](Handle) { ++hits; });
  EXPECT_EQ(hits, 1u);
}

TEST(Sap, RejectsOptions) {
  Config c;
  c.options["cell"] = "3";
  EXPECT_THROW(Sap{c}, InvalidConfig);
}

}  // namespace
}  // namespace broadphase
