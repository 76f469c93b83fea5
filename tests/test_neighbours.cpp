// Neighbour lists against a brute force that applies neighbours.hpp's exact
// rule to every pair and every shift in a range that holds them all: free
// space, orthorhombic and triclinic cells, mixed periodicity, cells smaller
// than the cutoff, points outside the cell, per-point cutoffs, float32,
// lattices whose neighbours lie exactly at the cutoff (both rules), half and
// full lists, and the two-set query. Seeds are printed on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <broadphase/neighbours.hpp>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "neighbours/frame.hpp"

namespace {

using namespace broadphase;
namespace rule = broadphase::neighbour_rule;

using Key = std::tuple<std::int64_t, std::int64_t, std::int64_t, std::int64_t, std::int64_t>;

Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// Shifts up to this many cells on periodic axis k cover every pair of points
// whose fractional coordinates differ by at most `spread` with a reach
// `reach` (3 for points in [-1, 2)).
std::array<std::int64_t, 3> shift_range(const NeighbourCell& cell, double reach,
                                        std::array<std::int64_t, 3> spread = {3, 3, 3}) {
  std::array<std::int64_t, 3> r{0, 0, 0};
  const auto& v = cell.vectors;
  const double det = dot(v[0], cross(v[1], v[2]));
  for (int k = 0; k < 3; ++k) {
    if (!cell.periodic[k]) continue;
    const Vec3 n = cross(v[(k + 1) % 3], v[(k + 2) % 3]);
    const double height = std::fabs(det) / std::sqrt(dot(n, n));
    r[k] =
        static_cast<std::int64_t>(std::ceil(reach / height)) + spread[static_cast<std::size_t>(k)];
  }
  return r;
}

struct Brute {
  std::vector<Key> half;  // canonical (i, j, S), sorted
};

Brute brute_force(const std::vector<Vec3>& x, const NeighbourCell& cell, double cutoff,
                  const std::vector<double>* cut, CutoffRule r, bool self_interaction,
                  std::array<std::int64_t, 3> spread = {3, 3, 3}) {
  double most = cutoff;
  if (cut) {
    most = 0;
    for (double c : *cut) most = std::max(most, c + c);
  }
  const auto range = shift_range(cell, most, spread);
  Brute b;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i; j < x.size(); ++j)
      for (std::int64_t s0 = -range[0]; s0 <= range[0]; ++s0)
        for (std::int64_t s1 = -range[1]; s1 <= range[1]; ++s1)
          for (std::int64_t s2 = -range[2]; s2 <= range[2]; ++s2) {
            if (i == j) {
              const bool zero = s0 == 0 && s1 == 0 && s2 == 0;
              if (zero ? !self_interaction : !rule::kept_self_shift(s0, s1, s2)) continue;
            }
            const Vec3 d = rule::pair_vector(x[i], x[j], rule::image_offset(cell, s0, s1, s2));
            const double s = cut ? (*cut)[i] + (*cut)[j] : cutoff;
            if (rule::within(rule::squared_length(d), s, r))
              b.half.emplace_back(static_cast<std::int64_t>(i), static_cast<std::int64_t>(j), s0,
                                  s1, s2);
          }
  std::sort(b.half.begin(), b.half.end());
  return b;
}

std::vector<Key> keys(const NeighbourList& l) {
  std::vector<Key> k;
  for (std::size_t e = 0; e < l.size(); ++e)
    k.emplace_back(l.first[e], l.second[e], l.shifts[3 * e], l.shifts[3 * e + 1],
                   l.shifts[3 * e + 2]);
  return k;
}

std::vector<Key> mirrored(const std::vector<Key>& half) {
  std::vector<Key> full;
  for (const auto& [i, j, a, b, c] : half) {
    full.emplace_back(i, j, a, b, c);
    if (!(i == j && a == 0 && b == 0 && c == 0)) full.emplace_back(j, i, -a, -b, -c);
  }
  std::sort(full.begin(), full.end());
  return full;
}

// Distances and vectors as the rule computes them in canonical orientation.
void check_quantities(const NeighbourList& l, const std::vector<Vec3>& x,
                      const NeighbourCell& cell) {
  ASSERT_EQ(l.distances.size(), l.size());
  ASSERT_EQ(l.vectors.size(), 3 * l.size());
  for (std::size_t e = 0; e < l.size(); ++e) {
    std::int64_t i = l.first[e], j = l.second[e];
    std::int64_t s[3] = {l.shifts[3 * e], l.shifts[3 * e + 1], l.shifts[3 * e + 2]};
    const bool mirror = i > j || (i == j && !rule::kept_self_shift(s[0], s[1], s[2]) &&
                                  (s[0] != 0 || s[1] != 0 || s[2] != 0));
    if (mirror) {
      std::swap(i, j);
      for (auto& v : s) v = -v;
    }
    Vec3 d = rule::pair_vector(x[static_cast<std::size_t>(i)], x[static_cast<std::size_t>(j)],
                               rule::image_offset(cell, s[0], s[1], s[2]));
    ASSERT_EQ(l.distances[e], std::sqrt(rule::squared_length(d))) << "pair " << e;
    if (mirror) d = Vec3{-d.x, -d.y, -d.z};
    for (int k = 0; k < 3; ++k) ASSERT_EQ(l.vectors[3 * e + k], d[k]) << "pair " << e;
  }
}

void check_offsets(const NeighbourList& l, std::size_t n) {
  ASSERT_EQ(l.offsets.size(), n + 1);
  EXPECT_EQ(l.offsets[0], 0);
  for (std::size_t i = 0; i < n; ++i)
    for (auto e = l.offsets[i]; e < l.offsets[i + 1]; ++e)
      ASSERT_EQ(l.first[static_cast<std::size_t>(e)], static_cast<std::int64_t>(i));
  EXPECT_EQ(static_cast<std::size_t>(l.offsets[n]), l.size());
}

NeighbourCell random_cell(std::mt19937_64& rng, int kind) {
  std::uniform_real_distribution<double> u(0, 1);
  NeighbourCell c;
  // kind 0 free, 1 orthorhombic, 2 triclinic, 3 small triclinic (cutoff
  // beyond half the cell), 4 mixed periodicity.
  const double size = kind == 3 ? 1.0 + u(rng) : 4.0 + 6.0 * u(rng);
  c.vectors[0] = {size * (0.8 + 0.4 * u(rng)), 0, 0};
  c.vectors[1] = {0, size * (0.8 + 0.4 * u(rng)), 0};
  c.vectors[2] = {0, 0, size * (0.8 + 0.4 * u(rng))};
  if (kind >= 2) {
    c.vectors[1].x = size * (u(rng) - 0.5);
    c.vectors[2].x = size * (u(rng) - 0.5);
    c.vectors[2].y = size * (u(rng) - 0.5);
  }
  if (kind == 0)
    c.periodic = {false, false, false};
  else if (kind == 4)
    c.periodic = {u(rng) < 0.5, u(rng) < 0.5, true};
  else
    c.periodic = {true, true, true};
  return c;
}

// Points with fractional coordinates in [-1, 2) (some outside the cell),
// some duplicated, some on the cell's faces.
// Points in and around the cell (fractional coordinates in [-1, 2), some
// on a face), or all in it when `inside` (on periodic axes): the search
// takes a path of its own when every wrap count is zero.
std::vector<Vec3> random_points(std::mt19937_64& rng, const NeighbourCell& cell, std::size_t n,
                                bool inside = false) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> x;
  for (std::size_t i = 0; i < n; ++i) {
    double f[3];
    for (int k = 0; k < 3; ++k) {
      const double t = u(rng);
      f[k] = t < 0.1 ? -1 + u(rng) : (t < 0.2 ? 1 + u(rng) : (t < 0.3 ? 0.0 : u(rng)));
      if (inside && cell.periodic[k]) f[k] -= std::floor(f[k]);
    }
    Vec3 p{};
    for (int k = 0; k < 3; ++k) {
      const Vec3 v = cell.periodic[k] ? cell.vectors[k]
                                      : Vec3{k == 0 ? 6.0 : 0, k == 1 ? 6.0 : 0, k == 2 ? 6.0 : 0};
      p = p + v * f[k];
    }
    if (i > 0 && u(rng) < 0.05) p = x[i - 1];
    x.push_back(p);
  }
  return x;
}

// The search's candidate passes this processor runs: the scalar one, and
// the AVX-512 one where the processor has it. Restores the default after.
struct EachSearch {
  std::vector<bool> vector;
  EachSearch() {
    vector.push_back(false);
    if (neighbours_detail::vector_search_available()) vector.push_back(true);
  }
  ~EachSearch() { neighbours_detail::allow_vector_search(true); }
};

TEST(Neighbours, RandomAgainstBruteForce) {
  EachSearch each;
  for (const bool vector : each.vector)
    for (std::uint64_t seed = 1; seed <= 200; ++seed) {
      neighbours_detail::allow_vector_search(vector);
      std::mt19937_64 rng(seed);
      std::uniform_real_distribution<double> u(0, 1);
      const int kind = static_cast<int>(seed % 5);
      const NeighbourCell cell = random_cell(rng, kind);
      const std::size_t n = 1 + static_cast<std::size_t>(u(rng) * 40);
      const bool inside = seed % 4 == 1;
      const std::vector<Vec3> x = random_points(rng, cell, n, inside);
      const bool per_point = seed % 3 == 0;
      const double cutoff = kind == 3 ? 0.5 + 2.0 * u(rng) : 0.5 + 3.0 * u(rng);
      std::vector<double> cut(n);
      for (double& c : cut) c = cutoff * (0.2 + 0.4 * u(rng));
      NeighbourOptions opt;
      opt.rule = seed % 2 ? CutoffRule::strict : CutoffRule::inclusive;
      opt.self_interaction = seed % 7 == 0;
      opt.distances = opt.vectors = opt.offsets = true;
      const auto points = NeighbourPoints::rows(&x[0].x, n);
      SCOPED_TRACE("seed " + std::to_string(seed) + " kind " + std::to_string(kind) + " n " +
                   std::to_string(n) + (per_point ? " per-point" : "") + (inside ? " inside" : "") +
                   (vector ? " vector search" : " scalar search"));
      const Brute b =
          brute_force(x, cell, cutoff, per_point ? &cut : nullptr, opt.rule, opt.self_interaction);
      const NeighbourList half =
          per_point ? neighbour_list(points, cell, arrays::Column::of(cut.data()), opt)
                    : neighbour_list(points, cell, cutoff, opt);
      ASSERT_EQ(keys(half), b.half);
      check_quantities(half, x, cell);
      check_offsets(half, n);
      opt.full = true;
      const NeighbourList full =
          per_point ? neighbour_list(points, cell, arrays::Column::of(cut.data()), opt)
                    : neighbour_list(points, cell, cutoff, opt);
      ASSERT_EQ(keys(full), mirrored(b.half));
      check_quantities(full, x, cell);
      check_offsets(full, n);
    }
}

// The two-set query against the brute force over every shift.
TEST(Neighbours, BetweenAgainstBruteForce) {
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const int kind = static_cast<int>(seed % 5);
    const NeighbourCell cell = random_cell(rng, kind);
    const std::vector<Vec3> q = random_points(rng, cell, 1 + static_cast<std::size_t>(u(rng) * 20));
    const std::vector<Vec3> p = random_points(rng, cell, static_cast<std::size_t>(u(rng) * 30));
    const double cutoff = 0.5 + 3.0 * u(rng);
    NeighbourOptions opt;
    opt.rule = seed % 2 ? CutoffRule::strict : CutoffRule::inclusive;
    opt.offsets = true;
    SCOPED_TRACE("seed " + std::to_string(seed) + " kind " + std::to_string(kind));
    const auto range = shift_range(cell, cutoff);
    std::vector<Key> expect;
    for (std::size_t i = 0; i < q.size(); ++i)
      for (std::size_t j = 0; j < p.size(); ++j)
        for (std::int64_t s0 = -range[0]; s0 <= range[0]; ++s0)
          for (std::int64_t s1 = -range[1]; s1 <= range[1]; ++s1)
            for (std::int64_t s2 = -range[2]; s2 <= range[2]; ++s2) {
              const Vec3 d = rule::pair_vector(q[i], p[j], rule::image_offset(cell, s0, s1, s2));
              if (rule::within(rule::squared_length(d), cutoff, opt.rule))
                expect.emplace_back(static_cast<std::int64_t>(i), static_cast<std::int64_t>(j), s0,
                                    s1, s2);
            }
    std::sort(expect.begin(), expect.end());
    const NeighbourList l = neighbour_list_between(
        NeighbourPoints::rows(&q[0].x, q.size()),
        NeighbourPoints::rows(p.empty() ? nullptr : &p[0].x, p.size()), cell, cutoff, opt);
    ASSERT_EQ(keys(l), expect);
    check_offsets(l, q.size());
  }
}

// A simple cubic lattice of spacing 1.5 (exact in binary) with the cutoff
// the spacing: the six nearest neighbours lie exactly at the cutoff, so the
// inclusive rule reports them and the strict rule does not.
TEST(Neighbours, TiesAtTheCutoff) {
  std::vector<Vec3> x;
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      for (int c = 0; c < 4; ++c) x.push_back({1.5 * a, 1.5 * b, 1.5 * c});
  const NeighbourCell cell = NeighbourCell::orthorhombic({6, 6, 6});
  const auto points = NeighbourPoints::rows(&x[0].x, x.size());
  NeighbourOptions opt;
  const NeighbourList in = neighbour_list(points, cell, 1.5, opt);
  EXPECT_EQ(in.size(), x.size() * 3);
  EXPECT_EQ(keys(in), brute_force(x, cell, 1.5, nullptr, opt.rule, false).half);
  opt.rule = CutoffRule::strict;
  EXPECT_EQ(neighbour_list(points, cell, 1.5, opt).size(), 0u);
}

// A cell smaller than the cutoff: one point sees its own images. In a cube
// of side 1 with cutoff 1 (inclusive) the half list keeps the three images
// whose first non-zero shift component is positive: (0,0,1), (0,1,0),
// (1,0,0); the full list all six.
TEST(Neighbours, SelfImagesKeptOnce) {
  const double p[3] = {0.25, 0.5, 0.75};
  const NeighbourCell cell = NeighbourCell::orthorhombic({1, 1, 1});
  NeighbourOptions opt;
  const NeighbourList half = neighbour_list(NeighbourPoints::rows(p, 1), cell, 1.0, opt);
  const std::vector<Key> expect = {{0, 0, 0, 0, 1}, {0, 0, 0, 1, 0}, {0, 0, 1, 0, 0}};
  EXPECT_EQ(keys(half), expect);
  opt.full = true;
  EXPECT_EQ(neighbour_list(NeighbourPoints::rows(p, 1), cell, 1.0, opt).size(), 6u);
  opt.self_interaction = true;
  EXPECT_EQ(neighbour_list(NeighbourPoints::rows(p, 1), cell, 1.0, opt).size(), 7u);
}

// float32 positions are widened exactly: the same list as their doubles.
TEST(Neighbours, Float32Input) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(0, 10);
  std::vector<float> f(3 * 300);
  for (float& v : f) v = u(rng);
  std::vector<double> d(f.begin(), f.end());
  const NeighbourCell cell = NeighbourCell::orthorhombic({10, 10, 10});
  const auto a = neighbour_list(NeighbourPoints::rows(f.data(), 300), cell, 1.25);
  const auto b = neighbour_list(NeighbourPoints::rows(d.data(), 300), cell, 1.25);
  EXPECT_GT(a.size(), 0u);
  EXPECT_EQ(keys(a), keys(b));
}

// A larger periodic system (many bins, the bins' path rather than the
// small-cell one) against the brute force.
TEST(Neighbours, ManyBinsTriclinic) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  NeighbourCell cell;
  cell.vectors = {Vec3{12, 0, 0}, Vec3{3, 11, 0}, Vec3{-2, 4, 10}};
  cell.periodic = {true, true, true};
  std::vector<Vec3> x;
  for (int i = 0; i < 600; ++i)
    x.push_back(cell.vectors[0] * u(rng) + cell.vectors[1] * u(rng) + cell.vectors[2] * u(rng));
  const auto l = neighbour_list(NeighbourPoints::rows(&x[0].x, x.size()), cell, 1.5);
  // Points inside the cell: their fractional coordinates differ by < 1.
  EXPECT_EQ(keys(l),
            brute_force(x, cell, 1.5, nullptr, CutoffRule::inclusive, false, {1, 1, 1}).half);
}

// Points up to 200 cells away on one axis: shifts beyond the 8-bit ones of
// the engine's packed records (the wide records' path), and within them
// for the points near the cell. Coordinates are multiples of 1/64 and the
// cell's sides integers, so every image is computed exactly.
TEST(Neighbours, PointsManyCellsAwayKeepTheirShifts) {
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> frac(0, 63), far(-200, 200);
    NeighbourCell cell = NeighbourCell::orthorhombic({4, 5, 6});
    if (seed % 2 == 0) cell.vectors[1].x = 2;  // triclinic
    const int reach = seed <= 3 ? 200 : 60;    // 60: every shift fits 8 bits
    std::vector<Vec3> x;
    for (int i = 0; i < 24; ++i) {
      Vec3 p{};
      for (int k = 0; k < 3; ++k) p = p + cell.vectors[k] * (frac(rng) / 64.0);
      if (i % 3 == 0) p = p + cell.vectors[0] * static_cast<double>(far(rng) * reach / 200);
      x.push_back(p);
    }
    SCOPED_TRACE("seed " + std::to_string(seed));
    NeighbourOptions opt;
    opt.rule = seed % 2 ? CutoffRule::strict : CutoffRule::inclusive;
    const auto points = NeighbourPoints::rows(&x[0].x, x.size());
    const auto expect =
        brute_force(x, cell, 2.5, nullptr, opt.rule, false, {2 * reach + 1, 1, 1}).half;
    ASSERT_EQ(keys(neighbour_list(points, cell, 2.5, opt)), expect);
    opt.full = true;
    ASSERT_EQ(keys(neighbour_list(points, cell, 2.5, opt)), mirrored(expect));
    // The two-set query: the first points against the others.
    opt.full = false;
    const std::size_t split = 8;
    std::vector<Key> between;
    for (const auto& [i, j, a, b, c] : mirrored(expect))
      if (i < static_cast<std::int64_t>(split) && j >= static_cast<std::int64_t>(split))
        between.emplace_back(i, j - static_cast<std::int64_t>(split), a, b, c);
    ASSERT_EQ(keys(neighbour_list_between(NeighbourPoints::rows(&x[0].x, split),
                                          NeighbourPoints::rows(&x[split].x, x.size() - split),
                                          cell, 2.5, opt)),
              between);
  }
}

// The list on 2, 3 and every thread is the list on one, array for array:
// 50 000 points (three parts of at least 16 384), one cutoff and per-point ones,
// half and full, all quantities, free space, orthorhombic, triclinic and
// mixed cells, and the two-set query.
TEST(Neighbours, ThreadsGiveTheSameList) {
  const auto same = [](const NeighbourList& a, const NeighbourList& b) {
    EXPECT_EQ(a.first, b.first);
    EXPECT_EQ(a.second, b.second);
    EXPECT_EQ(a.shifts, b.shifts);
    EXPECT_EQ(a.distances, b.distances);
    EXPECT_EQ(a.vectors, b.vectors);
    EXPECT_EQ(a.offsets, b.offsets);
  };
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    // 0 free space, 1 orthorhombic, 2 triclinic, 3 periodic on z alone;
    // side 80: 0.1 points a unit volume.
    const int kind = static_cast<int>(seed - 1);
    NeighbourCell cell = NeighbourCell::orthorhombic({80, 80, 80});
    if (kind == 0) cell.periodic = {false, false, false};
    if (kind == 2) cell.vectors[1].x = cell.vectors[2].y = 20;
    if (kind == 3) cell.periodic = {false, false, true};
    const std::size_t n = 50000;
    std::vector<Vec3> x(n);
    for (Vec3& p : x)  // some outside the cell
      p = cell.vectors[0] * (1.1 * u(rng) - 0.05) + cell.vectors[1] * u(rng) +
          cell.vectors[2] * u(rng);
    std::vector<double> cut(n);
    for (double& c : cut) c = 0.8 + 0.6 * u(rng);
    NeighbourOptions opt;
    opt.full = seed % 2 == 0;
    opt.distances = opt.vectors = opt.offsets = true;
    SCOPED_TRACE("seed " + std::to_string(seed) + " kind " + std::to_string(kind));
    const auto points = NeighbourPoints::rows(&x[0].x, n);
    const auto half = NeighbourPoints::rows(&x[n / 2].x, n - n / 2);
    const auto lists = [&](unsigned threads) {
      opt.threads = threads;
      return std::array<NeighbourList, 3>{
          neighbour_list(points, cell, 2.5, opt),
          neighbour_list(points, cell, arrays::Column::of(cut.data()), opt),
          neighbour_list_between(points, half, cell, 2.5, opt)};
    };
    const auto one = lists(1);
    EXPECT_GT(one[0].size(), n);
    for (unsigned threads : {2u, 3u, 0u}) {
      SCOPED_TRACE("threads " + std::to_string(threads));
      const auto many = lists(threads);
      for (int k = 0; k < 3; ++k)
        same(many[static_cast<std::size_t>(k)], one[static_cast<std::size_t>(k)]);
    }
  }
}

// The AVX-512 candidate passes give the scalar pass's list, array for
// array, where the processor has them (skipped elsewhere): 20 000 points at
// liquid density, all in the cell or some outside, some on one another, one
// cutoff and per-point ones, half and full, free space, orthorhombic,
// triclinic and mixed cells.
TEST(Neighbours, VectorSearchGivesTheScalarList) {
  if (!neighbours_detail::vector_search_available())
    GTEST_SKIP() << "this processor has no AVX-512: only the scalar search runs here";
  EachSearch each;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    const int kind = static_cast<int>(seed % 4);
    NeighbourCell cell = NeighbourCell::orthorhombic({58, 58, 58});
    if (kind == 0) cell.periodic = {false, false, false};
    if (kind == 2) cell.vectors[1].x = cell.vectors[2].y = 15;
    if (kind == 3) cell.periodic = {true, false, true};
    const std::size_t n = 20000;
    // Seeds 1 to 4 keep every point in the cell (the search's own path when
    // all wrap counts are zero), 5 to 8 put some outside.
    const double out = seed <= 4 ? 0.0 : 0.05;
    std::vector<Vec3> x(n);
    for (std::size_t i = 0; i < n; ++i)
      x[i] = i > 0 && u(rng) < 0.02 ? x[i - 1]
                                    : cell.vectors[0] * ((1 + 2 * out) * u(rng) - out) +
                                          cell.vectors[1] * u(rng) + cell.vectors[2] * u(rng);
    std::vector<double> cut(n);
    for (double& c : cut) c = 0.8 + 0.8 * u(rng);
    NeighbourOptions opt;
    opt.full = seed % 2 == 0;
    opt.self_interaction = seed % 3 == 0;
    opt.rule = seed % 5 < 2 ? CutoffRule::strict : CutoffRule::inclusive;
    opt.distances = opt.vectors = opt.offsets = true;
    SCOPED_TRACE("seed " + std::to_string(seed) + " kind " + std::to_string(kind));
    const auto points = NeighbourPoints::rows(&x[0].x, n);
    const auto lists = [&](bool vector) {
      neighbours_detail::allow_vector_search(vector);
      return std::array<NeighbourList, 2>{
          neighbour_list(points, cell, 3.0, opt),
          neighbour_list(points, cell, arrays::Column::of(cut.data()), opt)};
    };
    const auto scalar = lists(false);
    const auto vector = lists(true);
    EXPECT_GT(scalar[0].size(), n);
    for (std::size_t k = 0; k < 2; ++k) {
      EXPECT_EQ(vector[k].first, scalar[k].first);
      EXPECT_EQ(vector[k].second, scalar[k].second);
      EXPECT_EQ(vector[k].shifts, scalar[k].shifts);
      EXPECT_EQ(vector[k].distances, scalar[k].distances);
      EXPECT_EQ(vector[k].offsets, scalar[k].offsets);
    }
  }
}

TEST(Neighbours, BadInput) {
  const double good[6] = {0, 0, 0, 1, 1, 1};
  const double nan[6] = {0, 0, 0, 1, std::nan(""), 1};
  const auto cell = NeighbourCell::orthorhombic({5, 5, 5});
  const auto expect_message = [](auto call, const std::string& part) {
    try {
      call();
      ADD_FAILURE() << "no exception, expected one naming " << part;
    } catch (const InvalidNeighbourInput& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_message([&] { neighbour_list(NeighbourPoints::rows(nan, 2), cell, 1.0); },
                 "positions[1, 1]");
  expect_message([&] { neighbour_list(NeighbourPoints::rows(good, 2), cell, -1.0); }, "cutoff");
  expect_message([&] { neighbour_list(NeighbourPoints::rows(good, 2), cell, INFINITY); }, "cutoff");
  const double cuts[2] = {1, -2};
  expect_message(
      [&] { neighbour_list(NeighbourPoints::rows(good, 2), cell, arrays::Column::of(cuts)); },
      "cutoffs[1]");
  NeighbourCell flat = cell;
  flat.vectors[2] = {1, 1, 0};
  flat.vectors[1] = {2, 2, 0};
  expect_message([&] { neighbour_list(NeighbourPoints::rows(good, 2), flat, 1.0); }, "cell");
  NeighbourCell zero = cell;
  zero.vectors[1] = {0, 0, 0};
  expect_message([&] { neighbour_list(NeighbourPoints::rows(good, 2), zero, 1.0); }, "cell");
  // On three threads (three parts of 50 000 points), the first bad row is
  // named, not a later part's.
  std::vector<double> many(3 * 50000, 1.0);
  many[3 * 40000] = many[3 * 20000 + 1] = std::nan("");
  NeighbourOptions three;
  three.threads = 3;
  expect_message(
      [&] { neighbour_list(NeighbourPoints::rows(many.data(), 50000), cell, 1.0, three); },
      "positions[20000, 1]");
  const double far[3] = {1e12, 0, 0};
  expect_message([&] { neighbour_list(NeighbourPoints::rows(far, 1), cell, 1.0); }, "2^28");
  expect_message([&] { neighbour_list(NeighbourPoints::rows(good, 2), cell, 1e9); }, "2^20");
}

}  // namespace
