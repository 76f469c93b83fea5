// The response formulas on exact cases, conservation and decay over many
// frames, positional correction, and identical trajectories on every
// structure.
#include <gtest/gtest.h>

#include <broadphase/registry.hpp>
#include <broadphase/scenes/ccd.hpp>
#include <broadphase/scenes/sim.hpp>
#include <cmath>

#include "testing.hpp"

namespace broadphase {
namespace {

constexpr Ccd kModes[] = {Ccd::off, Ccd::substep, Ccd::swept};

TEST(Collide, HeadOnEqualMassesExchangeVelocities) {
  Vec3 va{3, 0, 0}, vb{-1, 0, 0};
  EXPECT_TRUE(collide(va, vb, 1, 1, {1, 0, 0}, 1));
  EXPECT_EQ(va, (Vec3{-1, 0, 0}));
  EXPECT_EQ(vb, (Vec3{3, 0, 0}));
}

TEST(Collide, PlasticHeadOnMovesTogether) {
  Vec3 va{2, 0, 0}, vb{0, 0, 0};
  EXPECT_TRUE(collide(va, vb, 1, 1, {1, 0, 0}, 0));
  EXPECT_EQ(va, (Vec3{1, 0, 0}));
  EXPECT_EQ(vb, (Vec3{1, 0, 0}));
}

TEST(Collide, GlancingKeepsTheTangentialPart) {
  // Normal along x; only the x components take part.
  Vec3 va{2, 5, -1}, vb{0, -3, 4};
  EXPECT_TRUE(collide(va, vb, 1, 1, {1, 0, 0}, 1));
  EXPECT_EQ(va, (Vec3{0, 5, -1}));
  EXPECT_EQ(vb, (Vec3{2, -3, 4}));
  // At 45 degrees: a moving along x hits b at rest; b leaves along the
  // normal with the normal part, a keeps the tangential part (equal masses).
  const double h = std::sqrt(0.5);
  Vec3 a{1, 0, 0}, b{0, 0, 0};
  EXPECT_TRUE(collide(a, b, 1, 1, {h, h, 0}, 1));
  EXPECT_NEAR(a.x, 0.5, 1e-15);
  EXPECT_NEAR(a.y, -0.5, 1e-15);
  EXPECT_NEAR(b.x, 0.5, 1e-15);
  EXPECT_NEAR(b.y, 0.5, 1e-15);
}

TEST(Collide, UnequalMasses) {
  // m_a = 8 (r = 2), m_b = 1 (r = 1), b at rest, elastic:
  // va' = (8 - 1)/9 * 9 = 7, vb' = 2*8/9 * 9 = 16.
  Vec3 va{9, 0, 0}, vb{0, 0, 0};
  EXPECT_TRUE(collide(va, vb, 1.0 / 8, 1.0, {1, 0, 0}, 1));
  EXPECT_NEAR(va.x, 7, 1e-13);
  EXPECT_NEAR(vb.x, 16, 1e-13);
}

TEST(Collide, AgainstStaticObject) {
  Vec3 va{4, 1, 0}, vb{0, 0, 0};
  EXPECT_TRUE(collide(va, vb, 1, 0, {1, 0, 0}, 0.5));
  EXPECT_EQ(va, (Vec3{-2, 1, 0}));
  EXPECT_EQ(vb, (Vec3{0, 0, 0}));
}

TEST(Collide, SeparatingOrBothStaticDoNothing) {
  Vec3 va{-1, 0, 0}, vb{1, 0, 0};
  EXPECT_FALSE(collide(va, vb, 1, 1, {1, 0, 0}, 1));
  EXPECT_EQ(va, (Vec3{-1, 0, 0}));
  Vec3 sa{1, 0, 0}, sb{0, 0, 0};
  EXPECT_FALSE(collide(sa, sb, 0, 0, {1, 0, 0}, 1));
}

TEST(Bounce, GroundAndWall) {
  Vec3 v{3, -4, 0};
  EXPECT_TRUE(bounce(v, {0, 1, 0}, 0.5));
  EXPECT_EQ(v, (Vec3{3, 2, 0}));
  Vec3 w{3, -4, 0};
  EXPECT_TRUE(bounce(w, {-1, 0, 0}, 1));
  EXPECT_EQ(w, (Vec3{-3, -4, 0}));
  Vec3 away{3, 4, 0};
  EXPECT_FALSE(bounce(away, {0, 1, 0}, 1));
}

Scene two(Shape a, Vec3 va, Shape b, Vec3 vb, double world = 100) {
  Scene s;
  s.world = world;
  s.objects = {a, b};
  s.velocity = {va, vb};
  return s;
}

TEST(Simulation, BouncesOffTheGroundWithRestitution) {
  for (const Ccd ccd : kModes) {
    SCOPED_TRACE(std::string(to_string(ccd)));
    Scene s;
    s.world = 100;
    s.objects = {Shape::sphere({50, 3, 50}, 1)};
    s.velocity = {{0, -4, 0}};
    SimConfig c;
    c.ccd = ccd;
    c.restitution = 0.5;
    Simulation sim(s, make_structure("naive"), c);
    const StepStats st = sim.step();
    // Reaches y = 1 at t = 0.5, then rises at 2 for the remaining 0.5.
    EXPECT_EQ(st.wall_hits, 1u);
    EXPECT_DOUBLE_EQ(sim.scene().velocity[0].y, 2);
    EXPECT_DOUBLE_EQ(sim.scene().objects[0].center.y, 2);
  }
}

TEST(Simulation, BoxesBounceOffWallsWithTheirExtent) {
  Scene s;
  s.world = 100;
  s.objects = {Shape::box({97, 50, 50}, {2, 1, 1})};
  s.velocity = {{2, 0, 0}};
  Simulation sim(s, make_structure("naive"));
  sim.step();
  EXPECT_DOUBLE_EQ(sim.scene().objects[0].center.x, 97);
  EXPECT_DOUBLE_EQ(sim.scene().velocity[0].x, -2);
}

TEST(Simulation, HeadOnEqualSpheresExchangeVelocities) {
  for (const Ccd ccd : kModes) {
    SCOPED_TRACE(std::string(to_string(ccd)));
    SimConfig c;
    c.ccd = ccd;
    Simulation sim(
        two(Shape::sphere({40, 50, 50}, 2), {1, 0, 0}, Shape::sphere({50, 50, 50}, 2), {-1, 0, 0}),
        make_structure("naive"), c);
    StepStats total;
    for (int f = 0; f < 6; ++f) total.contacts += sim.step().contacts;
    EXPECT_EQ(total.contacts, 1u);
    EXPECT_DOUBLE_EQ(sim.scene().velocity[0].x, -1);
    EXPECT_DOUBLE_EQ(sim.scene().velocity[1].x, 1);
  }
}

TEST(Simulation, StaticObjectsNeverMove) {
  for (const Ccd ccd : kModes) {
    SCOPED_TRACE(std::string(to_string(ccd)));
    SimConfig c;
    c.ccd = ccd;
    Simulation sim(
        two(Shape::sphere({40, 50, 50}, 2), {3, 0, 0}, Shape::sphere({47, 50, 50}, 5), {0, 0, 0}),
        make_structure("naive"), c);
    for (int f = 0; f < 10; ++f) sim.step();
    EXPECT_EQ(sim.scene().objects[1].center, (Vec3{47, 50, 50}));
    EXPECT_EQ(sim.scene().velocity[1], (Vec3{0, 0, 0}));
    EXPECT_DOUBLE_EQ(sim.scene().velocity[0].x, -3);
  }
}

TEST(Simulation, PenetrationIsCorrected) {
  // A mover starts deep inside a static sphere; one step pushes it out.
  SimConfig c;
  c.restitution = 0;
  Simulation sim(
      two(Shape::sphere({50, 50, 50}, 5), {0, 0, 0}, Shape::sphere({52, 50, 50}, 1), {-1e-3, 0, 0}),
      make_structure("naive"), c);
  const StepStats st = sim.step();
  EXPECT_GT(st.max_penetration, 3);
  EXPECT_NEAR(sim.scene().objects[1].center.x, 56, 1e-12);
  EXPECT_EQ(sim.scene().objects[0].center.x, 50);
}

/// Movers only, crowded, far enough from each other's start to be valid.
Scene crowd(std::size_t n, double world, std::uint64_t seed, bool with_statics) {
  Rng rng(seed);
  Scene s;
  s.world = world;
  for (std::size_t i = 0; i < n; ++i) {
    s.objects.push_back(Shape::sphere(
        {rng.uniform(5, world - 5), rng.uniform(5, world - 5), rng.uniform(5, world - 5)},
        rng.uniform(1, 4)));
    const bool moving = !with_statics || i % 4 != 0;
    s.velocity.push_back(moving ? rng.direction() * rng.uniform(0.5, 3) : Vec3{});
  }
  return s;
}

TEST(Simulation, ElasticConservesKineticEnergy) {
  // k = 1: every impulse and wall bounce keeps |v| exactly in real
  // arithmetic; rounding leaves a relative drift below 1e-9 over 400 frames.
  const Scene s = crowd(150, 120, 11, true);
  for (const Ccd ccd : kModes) {
    SCOPED_TRACE(std::string(to_string(ccd)));
    SimConfig c;
    c.ccd = ccd;
    Simulation sim(s, make_structure("naive"), c);
    const double e0 = kinetic_energy(s);
    std::uint64_t contacts = 0;
    for (int f = 0; f < 400; ++f) {
      const StepStats st = sim.step();
      contacts += st.contacts;
      ASSERT_NEAR(st.kinetic_energy, e0, 1e-9 * e0) << "frame " << f;
    }
    EXPECT_GT(contacts, 100u);
  }
}

TEST(Simulation, InelasticEnergyDecays) {
  const Scene s = crowd(150, 120, 12, false);
  for (const Ccd ccd : kModes) {
    SCOPED_TRACE(std::string(to_string(ccd)));
    SimConfig c;
    c.ccd = ccd;
    c.restitution = 0.5;
    Simulation sim(s, make_structure("naive"), c);
    double last = kinetic_energy(s);
    const double e0 = last;
    for (int f = 0; f < 200; ++f) {
      const StepStats st = sim.step();
      ASSERT_LE(st.kinetic_energy, last * (1 + 1e-12)) << "frame " << f;
      last = st.kinetic_energy;
    }
    EXPECT_LT(last, 0.25 * e0);
  }
}

TEST(Simulation, FreeCollisionsConserveMomentum) {
  // A cluster in the middle of a huge world: no walls, no static objects.
  Scene s = crowd(60, 60, 13, false);
  for (Shape& o : s.objects) o.center = o.center + Vec3{1e4, 1e4, 1e4};
  s.world = 2e4 + 120;
  for (const Ccd ccd : kModes) {
    SCOPED_TRACE(std::string(to_string(ccd)));
    SimConfig c;
    c.ccd = ccd;
    c.restitution = 0.7;
    Simulation sim(s, make_structure("naive"), c);
    const Vec3 p0 = momentum(s);
    std::uint64_t contacts = 0;
    for (int f = 0; f < 40; ++f) {
      const StepStats st = sim.step();
      contacts += st.contacts;
      ASSERT_EQ(st.wall_hits, 0u);
      for (int a = 0; a < 3; ++a) ASSERT_NEAR(st.momentum[a], p0[a], 1e-9 * 64 * 60 * 3) << f;
    }
    EXPECT_GT(contacts, 10u);
  }
}

TEST(Simulation, NoSinkingFrameAfterFrame) {
  // Plastic, crowded: the deepest overlap a step finds stays of the order
  // of one step's motion instead of growing.
  const Scene s = crowd(300, 80, 14, true);
  SimConfig c;
  c.restitution = 0;
  Simulation sim(s, make_structure("naive"), c);
  for (int f = 0; f < 20; ++f) sim.step();
  for (int f = 0; f < 200; ++f) ASSERT_LT(sim.step().max_penetration, 6.0) << f;
}

TEST(Simulation, EveryStructureGivesIdenticalTrajectories) {
  const Scene s = crowd(200, 100, 15, true);
  for (const Ccd ccd : kModes) {
    SimConfig c;
    c.ccd = ccd;
    c.restitution = 0.8;
    Simulation ref(s, make_structure("naive"), c);
    for (int f = 0; f < 60; ++f) ref.step();
    for (const std::string& name : testing::library_structures()) {
      SCOPED_TRACE(name + " " + std::string(to_string(ccd)));
      Simulation sim(s, make_structure(name), c);
      for (int f = 0; f < 60; ++f) sim.step();
      for (std::size_t i = 0; i < s.size(); ++i) {
        ASSERT_EQ(sim.scene().objects[i].center, ref.scene().objects[i].center) << i;
        ASSERT_EQ(sim.scene().velocity[i], ref.scene().velocity[i]) << i;
      }
    }
  }
}

TEST(Simulation, RejectsBadConfiguration) {
  SimConfig c;
  c.restitution = 1.5;
  EXPECT_THROW(Simulation(Scene{}, make_structure("naive"), c), std::invalid_argument);
  c.restitution = 1;
  c.dt = 0;
  EXPECT_THROW(Simulation(Scene{}, make_structure("naive"), c), std::invalid_argument);
  EXPECT_THROW(parse_ccd("sometimes"), std::invalid_argument);
  EXPECT_EQ(parse_ccd("swept"), Ccd::swept);
}

}  // namespace
}  // namespace broadphase
