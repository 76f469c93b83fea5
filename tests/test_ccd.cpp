// Time of impact, swept bounds, and tunneling: a discrete step misses
// contacts that the exact swept-sphere ground truth finds; `swept` misses none.
#include <gtest/gtest.h>

#include <broadphase/naive.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/ccd.hpp>
#include <broadphase/scenes/sim.hpp>
#include <cmath>

#include "testing.hpp"

namespace broadphase {
namespace {

TEST(TimeOfImpact, HeadOn) {
  const auto t = time_of_impact({10, 0, 0}, {-2, 0, 0}, 2, 10);
  ASSERT_TRUE(t.has_value());
  EXPECT_DOUBLE_EQ(*t, 4.0);
}

TEST(TimeOfImpact, BeyondTheStepOrMissing) {
  EXPECT_FALSE(time_of_impact({10, 0, 0}, {-2, 0, 0}, 2, 3.9).has_value());
  // Passes at distance 3 > s = 2.
  EXPECT_FALSE(time_of_impact({10, 3, 0}, {-2, 0, 0}, 2, 100).has_value());
  // Moving apart.
  EXPECT_FALSE(time_of_impact({10, 0, 0}, {2, 0, 0}, 2, 100).has_value());
  // No relative motion.
  EXPECT_FALSE(time_of_impact({10, 0, 0}, {0, 0, 0}, 2, 100).has_value());
}

TEST(TimeOfImpact, GrazingAtExactlyTheSumOfRadii) {
  const auto t = time_of_impact({10, 2, 0}, {-1, 0, 0}, 2, 100);
  ASSERT_TRUE(t.has_value());
  EXPECT_DOUBLE_EQ(*t, 10.0);
}

TEST(TimeOfImpact, OverlappingApproachesNowSeparatesNever) {
  EXPECT_EQ(time_of_impact({1, 0, 0}, {-1, 0, 0}, 2, 1).value_or(-1), 0.0);
  EXPECT_FALSE(time_of_impact({1, 0, 0}, {1, 0, 0}, 2, 1).has_value());
}

TEST(TimeOfImpact, TinyTimeKeepsItsRelativeAccuracy) {
  // Gap 1e-9 closed at speed 1e6: t = 1e-15. The textbook root
  // (−b − √disc)/a would cancel to 0 or worse here.
  const auto t = time_of_impact({2 + 1e-9, 0, 0}, {-1e6, 0, 0}, 2, 1);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 1e-15, 1e-21);
  EXPECT_GT(*t, 0);
}

TEST(TimeOfImpact, FastAndSmallPassingThrough) {
  // A bullet of radius 0.5 moving 30 per step passes a target of radius 2
  // centred 15 ahead: it touches at t = (15 - 2.5) / 30.
  const auto t = time_of_impact({15, 0, 0}, {-30, 0, 0}, 2.5, 1);
  ASSERT_TRUE(t.has_value());
  EXPECT_DOUBLE_EQ(*t, 12.5 / 30);
}

TEST(SweptShape, CoversBothEndsAndThePathBetween) {
  const Shape s = Shape::sphere({1, 2, 3}, 0.5);
  const Vec3 v{30, -4, 0};
  const Shape sw = swept_shape(s, v, 1);
  EXPECT_FALSE(sw.is_sphere());
  const Aabb box = bounds(sw);
  EXPECT_TRUE(box.contains(bounds(s)));
  EXPECT_TRUE(box.contains(bounds(Shape::sphere({31, -2, 3}, 0.5))));
  // A target in the middle of the path that neither end touches.
  const Shape target = Shape::sphere({16, 0, 3}, 0.6);
  EXPECT_FALSE(overlaps(s, target));
  EXPECT_FALSE(overlaps(Shape::sphere({31, -2, 3}, 0.5), target));
  EXPECT_TRUE(overlaps(sw, target));
}

TEST(SweptShape, FarFromTheOrigin) {
  const Shape s = Shape::sphere({1e7, -1e7, 1e7}, 0.25);
  const Shape sw = swept_shape(s, {1e-3, 0, -7}, 1);
  EXPECT_TRUE(bounds(sw).contains(bounds(s)));
  EXPECT_TRUE(bounds(sw).contains(bounds(Shape::sphere({1e7 + 1e-3, -1e7, 1e7 - 7}, 0.25))));
}

struct Tally {
  std::uint64_t missed = 0, truth = 0, contacts = 0;
};

Tally run(const Scene& scene, Ccd ccd, int frames, const std::string& algo = "naive") {
  SimConfig c;
  c.ccd = ccd;
  Simulation sim(scene, make_structure(algo), c);
  Tally t;
  for (int f = 0; f < frames; ++f) {
    const StepStats st = sim.step();
    t.missed += st.missed;
    t.truth += st.true_contacts;
    t.contacts += st.contacts;
  }
  return t;
}

TEST(Tunneling, DiscreteMissesSweptDoesNot) {
  const Scene scene = make_tunnel_scene(150, 7);
  const Tally off = run(scene, Ccd::off, 150);
  const Tally sub = run(scene, Ccd::substep, 150);
  const Tally swept = run(scene, Ccd::swept, 150);
  // The scene is made so that most contacts fall between two frames.
  EXPECT_GT(off.truth, 50u);
  EXPECT_GT(off.missed, off.truth / 2);
  EXPECT_LT(sub.missed, off.missed / 4);
  EXPECT_GT(swept.truth, 50u);
  EXPECT_EQ(swept.missed, 0u);
}

TEST(Tunneling, SingleBulletThroughThinTarget) {
  Scene s;
  s.world = 100;
  s.objects = {Shape::sphere({50, 50, 50}, 1), Shape::sphere({40, 50, 50}, 0.5)};
  s.velocity = {{0, 0, 0}, {20, 0, 0}};
  // Off: after one step the bullet is at 60, past the target, never seen.
  SimConfig c;
  Simulation off(s, make_structure("naive"), c);
  const StepStats a = off.step();
  EXPECT_EQ(a.true_contacts, 1u);
  EXPECT_EQ(a.missed, 1u);
  EXPECT_EQ(off.scene().velocity[1].x, 20);
  // Swept: the bullet bounces back at t = 8.5/20 and ends at 48.5 - 11.5.
  c.ccd = Ccd::swept;
  Simulation swept(s, make_structure("naive"), c);
  const StepStats b = swept.step();
  EXPECT_EQ(b.missed, 0u);
  EXPECT_EQ(b.contacts, 1u);
  EXPECT_EQ(swept.scene().velocity[1].x, -20);
  EXPECT_NEAR(swept.scene().objects[1].center.x, 37, 1e-12);
  // Substep: 20 / (0.5 * 0.5) = 80 → 64 ticks of 0.3125: seen inside the target.
  c.ccd = Ccd::substep;
  Simulation sub(s, make_structure("naive"), c);
  const StepStats d = sub.step();
  EXPECT_EQ(d.missed, 0u);
  EXPECT_EQ(sub.scene().velocity[1].x, -20);
}

TEST(Tunneling, EveryStructureGivesTheSameSweptTrajectories) {
  const Scene scene = make_tunnel_scene(60, 3);
  for (const Ccd ccd : {Ccd::substep, Ccd::swept}) {
    SimConfig c;
    c.ccd = ccd;
    Simulation ref(scene, make_structure("naive"), c);
    for (int f = 0; f < 40; ++f) ref.step();
    for (const std::string& name : testing::library_structures()) {
      SCOPED_TRACE(name + " " + std::string(to_string(ccd)));
      Simulation sim(scene, make_structure(name), c);
      for (int f = 0; f < 40; ++f) sim.step();
      for (std::size_t i = 0; i < scene.size(); ++i) {
        ASSERT_EQ(sim.scene().objects[i].center, ref.scene().objects[i].center) << i;
        ASSERT_EQ(sim.scene().velocity[i], ref.scene().velocity[i]) << i;
      }
    }
  }
}

}  // namespace
}  // namespace broadphase
