// The moving neighbour list against the one-shot neighbour_list on every
// frame of random walks: free space, orthorhombic and triclinic cells, mixed
// periodicity, cells smaller than the cutoff, one or per-point cutoffs, half
// and full lists, both cutoff rules, float32 points; small moves, big jumps,
// points wrapped back into the cell or left outside it, and lattices moved by
// whole cells with their neighbours exactly at the cutoff. Seeds are printed
// on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <broadphase/moving_neighbours.hpp>
#include <broadphase/neighbours.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "testing.hpp"

namespace {

using namespace broadphase;

Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// Every field, bit for bit (doubles compared by value: no NaN can occur).
void expect_same(const NeighbourList& got, const NeighbourList& want, const std::string& where) {
  ASSERT_EQ(got.size(), want.size()) << where;
  EXPECT_EQ(got.first, want.first) << where;
  EXPECT_EQ(got.second, want.second) << where;
  EXPECT_EQ(got.shifts, want.shifts) << where;
  EXPECT_EQ(got.distances, want.distances) << where;
  EXPECT_EQ(got.vectors, want.vectors) << where;
  EXPECT_EQ(got.offsets, want.offsets) << where;
}

struct Case {
  NeighbourCell cell;
  double cutoff = 0;
  std::vector<double> cutoffs;  // per point when not empty
  double skin = 0;
  NeighbourOptions options;
  bool f32 = false;
  std::vector<Vec3> x;
};

// A random cell: free, orthorhombic or triclinic, periodic on a random
// subset of the axes, sometimes thinner than the cutoff.
Case random_case(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  Case c;
  const int kind = static_cast<int>(rng() % 4);
  const bool small = rng() % 4 == 0;
  const double l = small ? 2.5 : 8.0 + 4 * u(rng);
  if (kind == 0) {
    c.cell = NeighbourCell::free_space();
  } else if (kind == 1) {
    c.cell = NeighbourCell::orthorhombic({l, l * (0.8 + 0.4 * u(rng)), l * (0.8 + 0.4 * u(rng))});
  } else {
    c.cell.vectors = {Vec3{l, 0, 0}, Vec3{0.3 * l * (u(rng) - 0.5), l, 0},
                      Vec3{0.3 * l * (u(rng) - 0.5), 0.3 * l * (u(rng) - 0.5), l}};
    c.cell.periodic = {true, true, true};
  }
  if (kind != 0 && rng() % 3 == 0)
    for (auto& p : c.cell.periodic) p = rng() % 2 == 0;
  const std::size_t n = 20 + rng() % 100;
  c.cutoff = small ? 1.5 + u(rng) : 1.0 + 1.5 * u(rng);
  if (rng() % 3 == 0) {
    c.cutoffs.resize(n);
    for (double& v : c.cutoffs) v = (0.3 + 0.5 * u(rng)) * c.cutoff;
  }
  c.skin = (0.05 + 0.4 * u(rng)) * c.cutoff;
  c.options.full = rng() % 2 == 0;
  c.options.rule = rng() % 2 == 0 ? CutoffRule::strict : CutoffRule::inclusive;
  c.options.self_interaction = rng() % 4 == 0;
  c.options.distances = true;
  c.options.vectors = true;
  c.options.offsets = true;
  c.f32 = rng() % 4 == 0;
  // Points over the cell (or a box of its size), some just outside it.
  const Vec3 a = c.cell.vectors[0], b = c.cell.vectors[1], cc = c.cell.vectors[2];
  for (std::size_t i = 0; i < n; ++i) {
    const double f0 = 1.2 * u(rng) - 0.1, f1 = 1.2 * u(rng) - 0.1, f2 = 1.2 * u(rng) - 0.1;
    if (kind == 0)
      c.x.push_back(Vec3{f0, f1, f2} * 8.0);
    else
      c.x.push_back(a * f0 + b * f1 + cc * f2);
  }
  return c;
}

// The fractional coordinates' columns of the cell (the periodic axes).
std::array<Vec3, 3> duals(const NeighbourCell& cell) {
  const auto& v = cell.vectors;
  const double det = dot(v[0], cross(v[1], v[2]));
  return {cross(v[1], v[2]) * (1 / det), cross(v[2], v[0]) * (1 / det),
          cross(v[0], v[1]) * (1 / det)};
}

// Moves a random walk one frame: every point a little (up to `step`), one
// in 20 frames a few points jump anywhere, and on periodic axes points are
// wrapped back into the cell (some frames) or left where they went.
void step(Case& c, std::mt19937_64& rng, double step_len, std::size_t& jumps) {
  std::normal_distribution<double> g(0, step_len);
  std::uniform_real_distribution<double> u(0, 1);
  for (auto& p : c.x) p = p + Vec3{g(rng), g(rng), g(rng)};
  if (rng() % 20 == 0) {
    ++jumps;
    for (int k = 0; k < 3; ++k) {
      Vec3& p = c.x[rng() % c.x.size()];
      p = p + Vec3{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5} * 6.0;
    }
  }
  const bool any = c.cell.periodic[0] || c.cell.periodic[1] || c.cell.periodic[2];
  if (any && rng() % 2 == 0) {
    const auto d = duals(c.cell);
    for (auto& p : c.x)
      for (int k = 0; k < 3; ++k)
        if (c.cell.periodic[k]) {
          const double w = std::floor(dot(p, d[static_cast<std::size_t>(k)]));
          p = p - c.cell.vectors[static_cast<std::size_t>(k)] * w;
        }
  }
}

// The one-shot list and the moving list's update of the same points.
struct Frame {
  NeighbourList want, got;
};

Frame both(const Case& c, MovingNeighbourList& m, std::vector<float>& f32) {
  std::vector<double> rows;
  for (const Vec3& p : c.x) rows.insert(rows.end(), {p.x, p.y, p.z});
  NeighbourPoints pts = NeighbourPoints::rows(rows.data(), c.x.size());
  if (c.f32) {
    f32.assign(rows.begin(), rows.end());
    pts = NeighbourPoints::rows(f32.data(), c.x.size());
  }
  Frame f;
  f.want = c.cutoffs.empty()
               ? neighbour_list(pts, c.cell, c.cutoff, c.options)
               : neighbour_list(pts, c.cell, arrays::Column::of(c.cutoffs.data()), c.options);
  f.got = m.update(pts);
  return f;
}

MovingNeighbourList make_list(const Case& c) {
  if (c.cutoffs.empty()) return MovingNeighbourList(c.cell, c.cutoff, c.skin, c.options);
  return MovingNeighbourList(c.cell, arrays::Column::of(c.cutoffs.data()), c.cutoffs.size(), c.skin,
                             c.options);
}

TEST(MovingNeighbours, RandomWalksMatchTheOneShotListOnEveryFrame) {
  std::size_t frames = 0, rebuilds = 0, jumps = 0, pairs = 0;
  // A third of the seeds under ASan (19 s there for all 40).
  const auto seeds = static_cast<std::uint64_t>(broadphase::testing::repeats(40));
  for (std::uint64_t seed = 1; seed <= seeds; ++seed) {
    std::mt19937_64 rng(seed);
    Case c = random_case(rng);
    MovingNeighbourList m = make_list(c);
    std::vector<float> f32;
    const double step_len = c.skin * 0.03;
    for (int frame = 0; frame < 30; ++frame) {
      if (frame > 0) step(c, rng, step_len, jumps);
      const Frame f = both(c, m, f32);
      expect_same(f.got, f.want,
                  "seed " + std::to_string(seed) + " frame " + std::to_string(frame));
      if (::testing::Test::HasFailure()) return;
      pairs += f.want.size();
      ++frames;
    }
    rebuilds += m.rebuilds();
  }
  // The walks must reuse lists most of the time, and rebuild too.
  EXPECT_LT(rebuilds * 3, frames) << rebuilds << " rebuilds in " << frames << " frames";
  EXPECT_GT(rebuilds, seeds + jumps / 2);
  EXPECT_GT(pairs, frames * 10);
}

// On two and three threads, the list of every frame is the one-shot list:
// 50 000 points (three parts of at least 16 384 points), small steps and wraps,
// one cutoff and per-point ones, half and full, all the quantities.
TEST(MovingNeighbours, ThreadsGiveTheOneShotListOnEveryFrame) {
  for (std::uint64_t seed = 1; seed <= 2; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    Case c;
    c.cell = NeighbourCell::orthorhombic({80, 80, 80});
    if (seed == 2) c.cell.vectors[1].x = 15;  // triclinic
    c.x.resize(50000);
    for (Vec3& p : c.x)
      p = c.cell.vectors[0] * u(rng) + c.cell.vectors[1] * u(rng) + c.cell.vectors[2] * u(rng);
    c.cutoff = 2.5;
    if (seed == 2) {
      c.cutoffs.resize(c.x.size());
      for (double& v : c.cutoffs) v = 0.8 + 0.5 * u(rng);
    }
    c.skin = 0.6;
    c.options.full = seed == 2;
    c.options.distances = c.options.vectors = c.options.offsets = true;
    c.options.threads = seed == 1 ? 2 : 3;
    MovingNeighbourList m = make_list(c);
    std::vector<float> f32;
    std::size_t jumps = 0;
    for (int frame = 0; frame < 4; ++frame) {
      if (frame > 0) step(c, rng, 0.02, jumps);
      const Frame f = both(c, m, f32);
      expect_same(f.got, f.want,
                  "seed " + std::to_string(seed) + " frame " + std::to_string(frame));
      if (::testing::Test::HasFailure()) return;
    }
    EXPECT_LT(m.rebuilds(), 4u);
  }
}

// Two streams of points moving against each other: pairs close in at twice
// the speed of a point, the case the skin's halving is for. A list that
// waited for a point to move the whole skin would miss pairs here.
TEST(MovingNeighbours, CounterMovingStreamsAreCaughtBeforeTheSkinRunsOut) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 10);
    Case c;
    c.cell = NeighbourCell::orthorhombic({10, 10, 10});
    c.cutoff = 1.5;
    c.skin = 0.3;
    c.options.full = seed == 2;
    for (int i = 0; i < 300; ++i) c.x.push_back(Vec3{u(rng), u(rng), u(rng)});
    MovingNeighbourList m = make_list(c);
    std::vector<float> f32;
    for (int frame = 0; frame < 40; ++frame) {
      for (std::size_t i = 0; i < c.x.size() && frame > 0; ++i) {
        c.x[i].x += i % 2 ? 0.04 : -0.04;
        c.x[i].x -= 10 * std::floor(c.x[i].x / 10);
      }
      const Frame f = both(c, m, f32);
      expect_same(f.got, f.want,
                  "seed " + std::to_string(seed) + " frame " + std::to_string(frame));
      if (::testing::Test::HasFailure()) return;
    }
    // 0.04 a frame against half a skin of 0.15: rebuilt every 4 frames.
    EXPECT_EQ(m.rebuilds(), 10u);
  }
}

// A cubic lattice whose neighbours lie exactly at the cutoff, moved by whole
// cells (every point's shifts change) and by nothing: the ties decide the
// same way as the one-shot list, under both rules, without a rebuild.
TEST(MovingNeighbours, LatticeMovedByWholeCellsKeepsItsTiesAndShifts) {
  for (const CutoffRule r : {CutoffRule::inclusive, CutoffRule::strict}) {
    for (const bool full : {false, true}) {
      Case c;
      const double a = 1.25;  // exact in binary: the ties are exact
      c.cell = NeighbourCell::orthorhombic({5 * a, 5 * a, 5 * a});
      c.cutoff = a;
      c.skin = 0.25;
      c.options.rule = r;
      c.options.full = full;
      c.options.distances = true;
      for (int i = 0; i < 5; ++i)
        for (int j = 0; j < 5; ++j)
          for (int k = 0; k < 5; ++k) c.x.push_back(Vec3{i * a, j * a, k * a});
      MovingNeighbourList m = make_list(c);
      std::vector<float> f32;
      std::mt19937_64 rng(7);
      for (int frame = 0; frame < 6; ++frame) {
        if (frame > 0)
          for (auto& p : c.x) {
            const int axis = static_cast<int>(rng() % 3);
            const double by = (rng() % 2 ? 1.0 : -1.0) * 5 * a;
            p[axis] += by;
          }
        const Frame f = both(c, m, f32);
        expect_same(f.got, f.want, "frame " + std::to_string(frame));
        EXPECT_EQ(f.want.size(), (r == CutoffRule::inclusive ? 375u : 0u) * (full ? 2 : 1));
      }
      EXPECT_EQ(m.rebuilds(), 1u);
    }
  }
}

TEST(MovingNeighbours, ACountChangeRebuildsAndTheDefaultSkinIsAFraction) {
  MovingNeighbourList m(NeighbourCell::orthorhombic({10, 10, 10}), 3.0);
  EXPECT_DOUBLE_EQ(m.skin(), 3.0 * MovingNeighbourList::kDefaultSkinFraction);
  std::vector<double> a = {1, 1, 1, 2, 1, 1, 9.5, 1, 1};
  NeighbourOptions o;
  EXPECT_EQ(m.update(NeighbourPoints::rows(a.data(), 3)).size(),
            neighbour_list(NeighbourPoints::rows(a.data(), 3),
                           NeighbourCell::orthorhombic({10, 10, 10}), 3.0, o)
                .size());
  EXPECT_EQ(m.update(NeighbourPoints::rows(a.data(), 2)).size(), 1u);
  EXPECT_EQ(m.rebuilds(), 2u);
  EXPECT_EQ(m.update(NeighbourPoints::rows(a.data(), 0)).size(), 0u);
  EXPECT_GT(m.memory_bytes(), 0u);
}

TEST(MovingNeighbours, BadInputIsRefusedAndTheListStaysUsable) {
  const NeighbourCell cell = NeighbourCell::orthorhombic({10, 10, 10});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)MovingNeighbourList(cell, nan), InvalidNeighbourInput);
  EXPECT_THROW((void)MovingNeighbourList(cell, -1.0), InvalidNeighbourInput);
  EXPECT_THROW((void)MovingNeighbourList(cell, 1.0, nan), InvalidNeighbourInput);
  EXPECT_THROW((void)MovingNeighbourList(cell, 1.0, HUGE_VAL), InvalidNeighbourInput);
  EXPECT_THROW((void)MovingNeighbourList(cell, 1e308, 1e308), InvalidNeighbourInput);
  NeighbourCell flat = cell;
  flat.vectors[2] = flat.vectors[1];
  EXPECT_THROW((void)MovingNeighbourList(flat, 1.0), InvalidNeighbourInput);
  const std::vector<double> bad_cuts = {1, -1};
  try {
    (void)MovingNeighbourList(cell, arrays::Column::of(bad_cuts.data()), 2);
    ADD_FAILURE() << "a negative per-point cutoff was accepted";
  } catch (const InvalidNeighbourInput& e) {
    EXPECT_NE(std::string(e.what()).find("cutoffs[1]"), std::string::npos) << e.what();
  }

  std::vector<double> x = {1, 1, 1, 2, 1, 1, 9.5, 1, 1};
  const NeighbourPoints pts = NeighbourPoints::rows(x.data(), 3);
  MovingNeighbourList m(cell, 2.0, 0.5);
  const NeighbourList first = m.update(pts);
  x[4] = nan;
  try {
    m.update(pts);
    ADD_FAILURE() << "a NaN position was accepted";
  } catch (const InvalidNeighbourInput& e) {
    EXPECT_NE(std::string(e.what()).find("positions[1, 1]"), std::string::npos) << e.what();
  }
  x[4] = 1;
  expect_same(m.update(pts), first, "after a refused frame");

  const std::vector<double> cuts = {1, 1, 1};
  MovingNeighbourList per(cell, arrays::Column::of(cuts.data()), 3, 0.5);
  EXPECT_THROW(per.update(NeighbourPoints::rows(x.data(), 2)), InvalidNeighbourInput);
  EXPECT_EQ(per.update(pts).size(), 2u);
}

}  // namespace
