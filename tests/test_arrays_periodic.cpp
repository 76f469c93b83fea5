// The lean path's periodic pairs (arrays/periodic.hpp): the one-shot call
// and the wrapping tracker against a brute force written from the
// contract's text (every i < j, every S in {-1, 0, 1}^3 on the periodic
// axes, j's centre moved by S_a·L_a in double, `overlaps()`), on random
// worlds with their seeds printed: bulk, slabs and tubes with a length per
// axis, spheres, boxes and both, sizes up to just below L/2, objects
// exactly on the faces (at 0 and at L) and corners, clusters, filters,
// float columns; the tracker moving and wrapping objects frame after
// frame. In a cube the contract's own oracle (brute_force_pairs) agrees
// too, and the reference scenes replay to their expected lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <broadphase/arrays/periodic.hpp>
#include <broadphase/scenes/array_caller.hpp>
#include <broadphase/scenes/brute_force.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

using arrays::Objects;

bool less(const ShiftedPair& p, const ShiftedPair& q) {
  if (p.i != q.i) return p.i < q.i;
  if (p.j != q.j) return p.j < q.j;
  return p.shift.code() < q.shift.code();
}

// The contract, written out: sorted by (i, j, code).
std::vector<ShiftedPair> oracle(const std::vector<Shape>& s, const PeriodicCell& cell,
                                const std::vector<std::uint32_t>& groups = {},
                                const std::vector<std::uint32_t>& masks = {}) {
  std::vector<ShiftedPair> out;
  const int lo[3] = {cell.periodic[0] ? -1 : 0, cell.periodic[1] ? -1 : 0,
                     cell.periodic[2] ? -1 : 0};
  for (std::uint32_t i = 0; i < s.size(); ++i)
    for (std::uint32_t j = i + 1; j < s.size(); ++j) {
      if (!groups.empty() && !((groups[i] & masks[j]) != 0 && (groups[j] & masks[i]) != 0))
        continue;
      for (int sz = lo[2]; sz <= -lo[2]; ++sz)
        for (int sy = lo[1]; sy <= -lo[1]; ++sy)
          for (int sx = lo[0]; sx <= -lo[0]; ++sx) {
            Shape m = s[j];
            m.center.x = s[j].center.x + sx * cell.length.x;
            m.center.y = s[j].center.y + sy * cell.length.y;
            m.center.z = s[j].center.z + sz * cell.length.z;
            if (overlaps(s[i], m))
              out.push_back({i,
                             j,
                             {static_cast<std::int8_t>(sx), static_cast<std::int8_t>(sy),
                              static_cast<std::int8_t>(sz)}});
          }
    }
  return out;
}

// The caller's columns of a set of shapes, doubles or floats.
struct Columns {
  std::vector<double> x, y, z, r, hx, hy, hz;
  std::vector<float> fx, fy, fz, fr, fhx, fhy, fhz;
  std::vector<std::uint8_t> kind;
  std::vector<std::uint32_t> groups, masks;
  bool floats = false;

  Objects objects() const {
    Objects o;
    o.count = x.size();
    if (floats) {
      o.x = arrays::Column::of(fx.data()), o.y = arrays::Column::of(fy.data()),
      o.z = arrays::Column::of(fz.data());
      o.radius = arrays::Column::of(fr.data());
      o.half_x = arrays::Column::of(fhx.data()), o.half_y = arrays::Column::of(fhy.data()),
      o.half_z = arrays::Column::of(fhz.data());
    } else {
      o.x = arrays::Column::of(x.data()), o.y = arrays::Column::of(y.data()),
      o.z = arrays::Column::of(z.data());
      o.radius = arrays::Column::of(r.data());
      o.half_x = arrays::Column::of(hx.data()), o.half_y = arrays::Column::of(hy.data()),
      o.half_z = arrays::Column::of(hz.data());
    }
    o.kind = kind.data();
    o.groups = groups;
    o.masks = masks;
    return o;
  }
  void set(std::size_t i, const Shape& s) {
    x[i] = s.center.x, y[i] = s.center.y, z[i] = s.center.z;
    r[i] = s.half.x, hx[i] = s.half.x, hy[i] = s.half.y, hz[i] = s.half.z;
    kind[i] = s.is_sphere() ? 0 : 1;
    if (floats) {
      fx[i] = static_cast<float>(x[i]), fy[i] = static_cast<float>(y[i]),
      fz[i] = static_cast<float>(z[i]), fr[i] = static_cast<float>(r[i]);
      fhx[i] = static_cast<float>(hx[i]), fhy[i] = static_cast<float>(hy[i]),
      fhz[i] = static_cast<float>(hz[i]);
    }
  }
  void resize(std::size_t n) {
    for (auto* v : {&x, &y, &z, &r, &hx, &hy, &hz}) v->resize(n);
    for (auto* v : {&fx, &fy, &fz, &fr, &fhx, &fhy, &fhz}) v->resize(n);
    kind.resize(n);
  }
  // The shapes as the lean path reads them (floats widened).
  std::vector<Shape> shapes() const {
    const Objects o = objects();
    std::vector<Shape> s;
    for (std::size_t i = 0; i < o.count; ++i) s.push_back(o.shape(i));
    return s;
  }
};

// A random world: the periodic axes, a length each, what the objects are
// like and where they sit.
struct World {
  PeriodicCell cell;
  int kinds = 0;       // 0 spheres, 1 boxes, 2 both
  int placement = 0;   // 0 uniform, 1 on faces and corners, 2 clusters, 3 a few large
  double largest = 0;  // share of L/2
  bool filters = false;
  bool floats = false;

  std::string describe(std::uint64_t seed) const {
    std::string axes;
    for (int a = 0; a < 3; ++a)
      if (cell.periodic[static_cast<std::size_t>(a)]) axes += static_cast<char>('x' + a);
    return "seed " + std::to_string(seed) + ", periodic " + axes + ", L (" +
           std::to_string(cell.length.x) + ", " + std::to_string(cell.length.y) + ", " +
           std::to_string(cell.length.z) + "), kinds " + std::to_string(kinds) + ", placement " +
           std::to_string(placement) + ", largest " + std::to_string(largest) +
           (filters ? ", filters" : "") + (floats ? ", floats" : "");
  }
};

World random_world(Rng& rng) {
  World w;
  do {
    for (std::size_t a = 0; a < 3; ++a) w.cell.periodic[a] = rng.below(3) != 0;
  } while (!(w.cell.periodic[0] || w.cell.periodic[1] || w.cell.periodic[2]));
  const bool cube = rng.below(3) == 0;
  const double base = std::ldexp(1.0, static_cast<int>(rng.below(8)) - 2) * 10;
  for (int a = 0; a < 3; ++a) w.cell.length[a] = cube ? base : base * rng.uniform(0.3, 3);
  w.kinds = static_cast<int>(rng.below(3));
  w.placement = static_cast<int>(rng.below(4));
  const double sizes[] = {0.01, 0.1, 0.3, 0.999};
  w.largest = sizes[rng.below(4)];
  w.filters = rng.below(4) == 0;
  w.floats = rng.below(5) == 0;
  return w;
}

// The largest half-extent allowed on axis a (below L_a / 2 on a periodic
// axis; the smallest periodic half-length bounds a sphere).
double half_room(const PeriodicCell& c, int a) {
  return c.periodic[static_cast<std::size_t>(a)] ? c.length[a] / 2 : HUGE_VAL;
}
double sphere_room(const PeriodicCell& c) {
  return std::min({half_room(c, 0), half_room(c, 1), half_room(c, 2), c.length.x / 2,
                   c.length.y / 2, c.length.z / 2});
}

double coordinate(Rng& rng, const World& w, int a, const Vec3& cluster) {
  const double L = w.cell.length[a];
  const bool p = w.cell.periodic[static_cast<std::size_t>(a)];
  double c = 0;
  switch (w.placement) {
    case 1: {  // the faces and corners, exactly, and next to them
      const double at[] = {
          0, L, std::nextafter(L, 0), std::nextafter(0.0, 1.0), L / 2, rng.uniform(0, L)};
      c = at[rng.below(6)];
      break;
    }
    case 2:
      c = cluster[a] + rng.uniform(-0.05, 0.05) * L;
      break;
    default:
      c = rng.uniform(0, L);
  }
  if (p) {
    if (c < 0) c += L;
    if (c > L) c -= L;
    c = std::clamp(c, 0.0, L);
  } else if (rng.below(10) == 0) {
    c = rng.uniform(-0.2, 1.2) * L;  // walls do not hold centres
  }
  return c;
}

// A size below the room, often the largest the world allows, sometimes
// exactly the largest double below L/2 or zero.
double size(Rng& rng, const World& w, double room) {
  const double top = std::min(room, 1e6) * w.largest;
  switch (rng.below(8)) {
    case 0:
      return 0;
    case 1:
      return w.largest > 0.9 ? std::nextafter(std::min(room, 1e6), 0) : top;
    default:
      return rng.uniform(0, top);
  }
}

Shape random_shape(Rng& rng, const World& w, const Vec3& cluster) {
  const Vec3 c{coordinate(rng, w, 0, cluster), coordinate(rng, w, 1, cluster),
               coordinate(rng, w, 2, cluster)};
  const bool sphere = w.kinds == 0 || (w.kinds == 2 && rng.below(2) == 0);
  if (sphere) return Shape::sphere(c, size(rng, w, sphere_room(w.cell)));
  return Shape::box(c, {size(rng, w, half_room(w.cell, 0)), size(rng, w, half_room(w.cell, 1)),
                        size(rng, w, half_room(w.cell, 2))});
}

Columns random_columns(Rng& rng, const World& w, std::size_t n) {
  Columns c;
  c.floats = w.floats;
  c.resize(n);
  const Vec3 cluster{rng.uniform(0, w.cell.length.x), rng.uniform(0, w.cell.length.y),
                     rng.uniform(0, w.cell.length.z)};
  for (std::size_t i = 0; i < n; ++i) {
    Shape s = random_shape(rng, w, cluster);
    if (w.placement == 3 && i % 8 != 0) {  // a few large among many small
      s.half = {s.half.x / 64, s.half.y / 64, s.half.z / 64};
    }
    c.set(i, s);
  }
  // Floats widened may land a hair past L or round a size up to L/2: keep
  // the columns valid as read.
  if (w.floats)
    for (std::size_t i = 0; i < n; ++i) {
      for (int a = 0; a < 3; ++a) {
        if (!w.cell.periodic[static_cast<std::size_t>(a)]) continue;
        std::vector<float>* col[] = {&c.fx, &c.fy, &c.fz};
        std::vector<float>* half[] = {&c.fhx, &c.fhy, &c.fhz};
        const double L = w.cell.length[a];
        float& v = (*col[a])[i];
        while (static_cast<double>(v) > L) v = std::nextafter(v, 0.0f);
        for (std::vector<float>* h : {half[a], &c.fr}) {
          float& e = (*h)[i];
          if (!(static_cast<double>(e) < L / 2)) e = static_cast<float>(L / 2);
          while (!(static_cast<double>(e) < L / 2)) e = std::nextafter(e, 0.0f);
        }
      }
    }
  if (w.filters) {
    for (std::size_t i = 0; i < n; ++i) {
      c.groups.push_back(1u << rng.below(3));
      c.masks.push_back(static_cast<std::uint32_t>(rng.below(8)));
    }
  }
  return c;
}

TEST(ArraysPeriodic, OneShotMatchesTheContractOnRandomWorlds) {
  const int worlds = testing::repeats(150);
  for (int k = 0; k < worlds; ++k) {
    const std::uint64_t seed = 4400 + static_cast<std::uint64_t>(k);
    Rng rng(seed);
    const World w = random_world(rng);
    const std::size_t n = 1 + rng.below(k % 5 == 0 ? 400 : 90);
    const Columns c = random_columns(rng, w, n);
    const Objects o = c.objects();
    SCOPED_TRACE(w.describe(seed) + ", n " + std::to_string(n));
    const std::vector<ShiftedPair> expected = oracle(c.shapes(), w.cell, c.groups, c.masks);
    std::vector<ShiftedPair> got;
    arrays::ArrayOptions sorted;
    sorted.sorted = true;
    const ArrayCallStats stats = arrays::find_pairs(o, w.cell, got, sorted);
    ASSERT_EQ(got, expected);
    EXPECT_EQ(stats.pairs, expected.size());
    // Unsorted: the same pairs, each pair's shifts in increasing code.
    std::vector<ShiftedPair> loose;
    arrays::find_pairs(o, w.cell, loose);
    std::stable_sort(loose.begin(), loose.end(), less);
    ASSERT_EQ(loose, expected);
  }
}

TEST(ArraysPeriodic, AgreesWithTheSceneOracleInACube) {
  // brute_force_pairs (the contract's oracle of `run --oracle`) in cubes.
  for (int k = 0; k < testing::repeats(30); ++k) {
    const std::uint64_t seed = 7100 + static_cast<std::uint64_t>(k);
    Rng rng(seed);
    SCOPED_TRACE("seed " + std::to_string(seed));
    Scene scene;
    scene.world = 20;
    for (std::size_t a = 0; a < 3; ++a) scene.periodic[a] = rng.below(2) == 0;
    scene.periodic[rng.below(3)] = true;
    const std::size_t n = 50 + rng.below(200);
    for (std::size_t i = 0; i < n; ++i) {
      Vec3 c{rng.uniform(0, 20), rng.uniform(0, 20), rng.uniform(0, 20)};
      if (rng.below(4) == 0) c.x = rng.below(2) * 20.0;
      scene.objects.push_back(
          rng.below(2) == 0
              ? Shape::sphere(c, rng.uniform(0, 9.99))
              : Shape::box(c, {rng.uniform(0, 3), rng.uniform(0, 9.99), rng.uniform(0, 1)}));
      scene.velocity.push_back({});
    }
    ArrayCaller caller(scene);
    FrameDigest d;
    arrays::find_pairs(caller.objects(), scene.cell(), [&](std::span<const ShiftedPair> ps) {
      for (const ShiftedPair& p : ps) d.add(p.i, p.j, p.shift);
      return true;
    });
    EXPECT_EQ(d, brute_force_pairs(scene));
  }
}

TEST(ArraysPeriodic, TwoShiftsOfOnePairNearHalfTheCell) {
  // Two spheres of radius just below L/4... and just below L/2 apart from
  // each other on a tube of length 10: both shifts 0 and -1 overlap.
  const std::vector<double> xyz = {1, 0, 0, 6, 0, 0};
  const std::vector<double> r = {2.5, 2.5};
  const Objects o = Objects::spheres(xyz.data(), r.data(), 2);
  const PeriodicCell tube{{10, 10, 10}, {true, false, false}};
  std::vector<ShiftedPair> got;
  arrays::find_pairs(o, tube, got);
  const std::vector<ShiftedPair> expected = {{0, 1, {-1, 0, 0}}, {0, 1, {0, 0, 0}}};
  EXPECT_EQ(got, expected);
  EXPECT_EQ(got, oracle({Shape::sphere({1, 0, 0}, 2.5), Shape::sphere({6, 0, 0}, 2.5)}, tube));
}

TEST(ArraysPeriodic, ObjectsAtZeroAndAtLPairAcrossTheFace) {
  // The same point at 0 and at L: one object moved by -L is the other.
  const std::vector<double> xyz = {0, 5, 5, 100, 5, 5, 100, 100, 100, 0, 0, 0};
  const std::vector<double> r = {0, 0, 0, 0};
  const Objects o = Objects::spheres(xyz.data(), r.data(), 4);
  std::vector<ShiftedPair> got;
  arrays::ArrayOptions sorted;
  sorted.sorted = true;
  const PeriodicCell cube = PeriodicCell::cube(100, {true, true, true});
  arrays::find_pairs(o, cube, got, sorted);
  std::vector<Shape> s;
  for (std::size_t i = 0; i < 4; ++i) s.push_back(o.shape(i));
  const std::vector<ShiftedPair> expected = oracle(s, cube);
  EXPECT_EQ(got, expected);
  EXPECT_EQ(expected.size(), 2u);  // (0, 1, -1 0 0) and (2, 3, 1 1 1)
}

TEST(ArraysPeriodic, RefusesWhatTheContractRefuses) {
  std::vector<double> xyz = {1, 2, 3, 4, 5, 6};
  std::vector<double> r = {1, 1};
  const Objects o = Objects::spheres(xyz.data(), r.data(), 2);
  const PeriodicCell slab{{10, 10, 10}, {true, true, false}};
  std::vector<ShiftedPair> out;
  auto message = [&](const PeriodicCell& c) -> std::string {
    try {
      arrays::find_pairs(o, c, out);
    } catch (const arrays::InvalidObjects& e) {
      return e.what();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(message(slab), "");
  xyz[3] = 10.5;
  EXPECT_EQ(message(slab),
            "objects[1]: x (10.5) is outside [0, L] = [0, 10] on the periodic axis x");
  xyz[3] = -0.0;  // -0 lies in [0, L]
  EXPECT_EQ(message(slab), "");
  xyz[5] = -4;  // z is not periodic: anywhere
  EXPECT_EQ(message(slab), "");
  r[0] = 5;
  EXPECT_EQ(message(slab), "objects[0]: radius (5) is not below L/2 = 5 on the periodic axis x");
  r[0] = std::nextafter(5.0, 0);
  EXPECT_EQ(message(slab), "");
  EXPECT_EQ(message({{10, 0, 10}, {true, true, false}}),
            "periodic cell: the length of the periodic axis y (0) is not finite and positive");
  EXPECT_EQ(message({{10, NAN, 10}, {true, false, false}}), "");  // y not periodic: not read
  std::vector<double> c = {5, 5, 5}, h = {1, 6, 1};
  const Objects box = Objects::boxes(c.data(), h.data(), 1);
  try {
    arrays::find_pairs(box, slab, out);
    ADD_FAILURE() << "a half-extent of L/2 or more must be refused";
  } catch (const arrays::InvalidObjects& e) {
    EXPECT_EQ(std::string(e.what()),
              "objects[0]: half_y (6) is not below L/2 = 5 on the periodic axis y");
    EXPECT_EQ(e.index(), 0u);
  }
  xyz[0] = NAN;
  EXPECT_NE(message(slab).find("objects[0]"), std::string::npos);
  EXPECT_THROW(PeriodicPairTracker(PeriodicCell{{-1, 1, 1}, {true, false, false}}),
               std::invalid_argument);
}

TEST(ArraysPeriodic, StopsWhenTheSinkSaysSo) {
  std::vector<double> xyz;
  for (int i = 0; i < 50; ++i) xyz.insert(xyz.end(), {0.5 * i, 0, 0});
  const std::vector<double> r = {3};
  const Objects o = Objects::spheres(xyz.data(), r.data(), 50, 0);
  int chunks = 0;
  const ArrayCallStats s = arrays::find_pairs(o, PeriodicCell::cube(25, {true, false, false}),
                                              [&](std::span<const ShiftedPair>) {
                                                ++chunks;
                                                return false;
                                              });
  EXPECT_TRUE(s.stopped);
  EXPECT_EQ(chunks, 1);
}

// The tracker, frame after frame: movers step and wrap (as the contract's
// motion), some frames resize or re-kind a few objects, list everything,
// grow or shrink the count; every frame's pairs are the oracle's, sorted.
TEST(ArraysPeriodic, TrackerStaysExactAsObjectsMoveAndWrap) {
  const int runs = testing::repeats(40);
  for (int k = 0; k < runs; ++k) {
    const std::uint64_t seed = 9100 + static_cast<std::uint64_t>(k);
    Rng rng(seed);
    World w = random_world(rng);
    w.floats = false;
    std::size_t n = 2 + rng.below(120);
    Columns c = random_columns(rng, w, n);
    SCOPED_TRACE(w.describe(seed) + ", n " + std::to_string(n));
    arrays::ArrayOptions options;
    if (rng.below(3) == 0) options.skin = rng.uniform(0.05, 2);
    PeriodicPairTracker tracker(w.cell, options);
    const double speed = std::ldexp(1.0, -static_cast<int>(rng.below(8))) *
                         std::min({w.cell.length.x, w.cell.length.y, w.cell.length.z});
    std::vector<Vec3> v(n);
    for (Vec3& x : v) x = rng.direction() * rng.uniform(0, speed);
    const std::size_t movers = 1 + rng.below(n);
    for (int frame = 0; frame < 30; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      std::vector<std::uint32_t> listed;
      bool everything = frame == 0 || rng.below(8) == 0;
      if (frame > 0) {
        for (std::uint32_t i = 0; i < movers && i < n; ++i) {
          Shape s = c.shapes()[i];
          for (int a = 0; a < 3; ++a) {
            double p = s.center[a];
            double va = v[i][a];
            if (w.cell.periodic[static_cast<std::size_t>(a)])
              step_axis_periodic(p, va, w.cell.length[a]);
            else
              step_axis(p, va, w.cell.length[a]);
            s.center[a] = p;
            v[i][a] = va;
          }
          // Now and then onto a face exactly.
          if (rng.below(20) == 0) {
            const int a = static_cast<int>(rng.below(3));
            if (w.cell.periodic[static_cast<std::size_t>(a)])
              s.center[a] = rng.below(2) == 0 ? 0.0 : w.cell.length[a];
          }
          c.set(i, s);
          listed.push_back(i);
        }
        if (rng.below(6) == 0) {  // a few resize or change kind
          const std::uint32_t i = static_cast<std::uint32_t>(rng.below(n));
          const Vec3 cluster{w.cell.length.x / 2, w.cell.length.y / 2, w.cell.length.z / 2};
          Shape s = random_shape(rng, w, cluster);
          s.center = c.shapes()[i].center;
          c.set(i, s);
          listed.push_back(i);
        }
        if (rng.below(15) == 0) {  // the count grows or shrinks
          const std::size_t m = std::max<std::size_t>(1, n + rng.below(9) - 4);
          Columns d = random_columns(rng, w, m);
          for (std::size_t i = 0; i < std::min(n, m); ++i) d.set(i, c.shapes()[i]);
          if (w.filters) {
            d.groups.resize(m, 1), d.masks.resize(m, 1);
            for (std::size_t i = 0; i < std::min(n, m); ++i)
              d.groups[i] = c.groups[i], d.masks[i] = c.masks[i];
          }
          c = d;
          n = m;
          v.resize(n, {0, 0, 0});
          everything = true;
        }
      }
      const Objects o = c.objects();
      std::vector<ShiftedPair> got;
      tracker.find_pairs(o, got, everything ? Changes::everything() : Changes::only(listed));
      ASSERT_EQ(got, oracle(c.shapes(), w.cell, c.groups, c.masks));
      ASSERT_NO_THROW(tracker.validate(o));
    }
  }
}

TEST(ArraysPeriodic, TrackerKeepsItsCandidatesWhileObjectsStayInTheSkin) {
  // 200 spheres drifting slowly in a bulk cell: few rebuilds, exact pairs.
  Rng rng(31);
  const PeriodicCell cell = PeriodicCell::cube(40, {true, true, true});
  std::vector<double> xyz(600), r(200);
  for (double& x : xyz) x = rng.uniform(0, 40);
  for (double& q : r) q = rng.uniform(0.5, 2);
  const Objects o = Objects::spheres(xyz.data(), r.data(), 200);
  PeriodicPairTracker tracker(cell);
  std::vector<std::uint32_t> all(200);
  for (std::uint32_t i = 0; i < 200; ++i) all[i] = i;
  int rebuilds = 0;
  for (int frame = 0; frame < 40; ++frame) {
    for (std::size_t k = 0; k < 600; ++k) {
      double p = xyz[k];
      step_axis_periodic(p, 0.02, 40);
      xyz[k] = p;
    }
    std::vector<ShiftedPair> got;
    const ArrayCallStats s = tracker.find_pairs(o, got, Changes::only(all));
    rebuilds += s.rebuilt ? 1 : 0;
    std::vector<Shape> shapes;
    for (std::size_t i = 0; i < 200; ++i) shapes.push_back(o.shape(i));
    ASSERT_EQ(got, oracle(shapes, cell)) << "frame " << frame;
  }
  EXPECT_LE(rebuilds, 10);
  EXPECT_GT(tracker.memory_bytes(), 0u);
}

// The expected lines of a reference scene: `frame pairs hash` (and the
// rays' figures, not read here).
std::vector<FrameDigest> expected_lines(const std::string& path) {
  std::vector<FrameDigest> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    int frame = 0;
    FrameDigest d;
    std::string hash;
    fields >> frame >> d.pairs >> hash;
    d.hash = std::stoull(hash, nullptr, 16);
    out.push_back(d);
  }
  return out;
}

TEST(ArraysPeriodic, ReferenceScenesReplayToTheirExpectedLines) {
  int seen = 0;
  for (const char* name : {"periodic-all-300", "periodic-xy-boxes-300", "periodic-xyz-300"}) {
    const std::string base = std::string(BROADPHASE_TEST_DATA) + "/scenes/v3/" + name;
    Scene scene = read_scene(base + ".scene");
    ASSERT_TRUE(scene.is_periodic());
    ++seen;
    SCOPED_TRACE(name);
    const std::vector<FrameDigest> expected = expected_lines(base + ".expected");
    ArrayCaller caller(scene);
    PeriodicPairTracker tracker(scene.cell());
    const int frames = static_cast<int>(expected.size());
    ASSERT_GT(frames, 0);
    for (int f = 0; f < frames; ++f) {
      if (f > 0) caller.step();
      FrameDigest d;
      tracker.find_pairs(
          caller.objects(),
          [&](std::span<const ShiftedPair> ps) {
            for (const ShiftedPair& p : ps) d.add(p.i, p.j, p.shift);
            return true;
          },
          f == 0 ? Changes::everything() : Changes::only(caller.movers()));
      ASSERT_EQ(d, expected[static_cast<std::size_t>(f)]) << "frame " << f;
    }
  }
  EXPECT_EQ(seen, 3);
}

}  // namespace
}  // namespace broadphase
