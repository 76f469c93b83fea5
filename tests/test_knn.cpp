// knn and within (knn.hpp) against a brute force over every point with the
// same arithmetic, on random sets with printed seeds: uniform, clustered,
// duplicated points on a lattice (ties of distance everywhere), flat and
// thin sets, far from the origin, tiny, float input, periodic boxes with
// their own lengths per axis; k beyond n, empty sets, threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/knn.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "testing.hpp"

namespace bp = broadphase;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

enum class Kind { uniform, clustered, lattice, flat, line, far, tiny };
const char* name(Kind k) {
  switch (k) {
    case Kind::uniform:
      return "uniform";
    case Kind::clustered:
      return "clustered";
    case Kind::lattice:
      return "lattice";
    case Kind::flat:
      return "flat";
    case Kind::line:
      return "line";
    case Kind::far:
      return "far";
    case Kind::tiny:
      return "tiny";
  }
  return "?";
}
constexpr Kind kKinds[] = {Kind::uniform, Kind::clustered, Kind::lattice, Kind::flat,
                           Kind::line,    Kind::far,       Kind::tiny};

// n rows of xyz of the kind, inside [0, side]^3 for the first four kinds
// (the box of the periodic tests).
std::vector<double> make(Kind kind, std::size_t n, double side, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, side);
  std::normal_distribution<double> g(0, side / 50);
  std::uniform_int_distribution<int> lattice(0, 4);
  std::vector<double> xyz(3 * n);
  std::vector<double> centres;
  for (int c = 0; c < 6; ++c) centres.push_back(u(rng));
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      double v = u(rng);
      switch (kind) {
        case Kind::uniform:
          break;
        case Kind::clustered:
          v = std::clamp(centres[(i % 2) * 3 + a] + g(rng), 0.0, side);
          break;
        case Kind::lattice:
          v = lattice(rng) * (side / 4);
          break;  // 0 and side included
        case Kind::flat:
          if (a == 2) v = side / 2;
          break;
        case Kind::line:
          if (a != 0) v = lattice(rng) == 0 ? 1.0 : 1.0 + 0x1p-40;
          break;
        case Kind::far:
          v = 1e12 + std::floor(u(rng) * 4) * 0x1p-12;
          break;
        case Kind::tiny:
          v = u(rng) * 1e-300;
          break;
      }
      xyz[3 * i + static_cast<std::size_t>(a)] = v;
    }
  }
  return xyz;
}

// The rule of knn.hpp, the images written out: the smallest d2 over the 27
// shifts S (0 on closed axes), each dx = q - (p + S*L).
double rule_d2(const bp::Vec3& q, const bp::Vec3& p, const std::optional<bp::PeriodicCell>& box) {
  if (!box) {
    const double dx = q.x - p.x, dy = q.y - p.y, dz = q.z - p.z;
    return dx * dx + dy * dy + dz * dz;
  }
  double best = kInf;
  bool first = true;
  for (int sz = -1; sz <= 1; ++sz)
    for (int sy = -1; sy <= 1; ++sy)
      for (int sx = -1; sx <= 1; ++sx) {
        const int s[3] = {sx, sy, sz};
        double d[3];
        bool skip = false;
        for (int a = 0; a < 3; ++a) {
          const bool per = box && box->periodic[a];
          if (!per && s[a] != 0) skip = true;
          d[a] = s[a] == 0 ? q[a] - p[a] : q[a] - (p[a] + s[a] * box->length[a]);
        }
        if (skip) continue;
        const double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if (first || d2 < best) best = d2;
        first = false;
      }
  return best;
}

using Ranked = std::vector<std::pair<double, std::int64_t>>;

Ranked brute(const bp::Points& pts, const bp::Vec3& q, const std::optional<bp::PeriodicCell>& box,
             std::int64_t self) {
  Ranked all;
  for (std::size_t j = 0; j < pts.count; ++j) {
    if (static_cast<std::int64_t>(j) == self) continue;
    all.emplace_back(rule_d2(q, pts.at(j), box), static_cast<std::int64_t>(j));
  }
  std::sort(all.begin(), all.end());
  return all;
}

// Compares every row of knn and within with the brute force.
void check_all(const bp::Points& pts, const std::optional<bp::Points>& queries,
               const std::optional<bp::PeriodicCell>& box, std::size_t k, double r,
               bool exclude_self, unsigned threads) {
  bp::KnnConfig config;
  config.box = box;
  const bp::KnnResult got = bp::knn(pts, queries, k, config, exclude_self, threads);
  const bp::Neighbours in = bp::within(pts, queries, r, config, exclude_self, threads);
  const std::size_t rows = queries ? queries->count : pts.count;
  ASSERT_EQ(got.d2.size(), rows * k);
  ASSERT_EQ(in.offsets.size(), rows + 1);
  const double r2 = r * r;
  for (std::size_t i = 0; i < rows; ++i) {
    const bp::Vec3 q = queries ? queries->at(i) : pts.at(i);
    const Ranked want =
        brute(pts, q, box, (!queries && exclude_self) ? static_cast<std::int64_t>(i) : -1);
    for (std::size_t c = 0; c < k; ++c) {
      const double d = c < want.size() ? want[c].first : kInf;
      const std::int64_t id =
          c < want.size() ? want[c].second : static_cast<std::int64_t>(pts.count);
      ASSERT_EQ(got.d2[i * k + c], d) << "knn row " << i << " column " << c;
      ASSERT_EQ(got.index[i * k + c], id) << "knn row " << i << " column " << c;
    }
    std::size_t at = static_cast<std::size_t>(in.offsets[i]);
    for (const auto& [d, id] : want) {
      if (!(d <= r2)) break;
      ASSERT_LT(at, static_cast<std::size_t>(in.offsets[i + 1]))
          << "within row " << i << " misses " << id;
      ASSERT_EQ(in.index[at], id) << "within row " << i;
      ASSERT_EQ(in.d2[at], d) << "within row " << i;
      ++at;
    }
    ASSERT_EQ(at, static_cast<std::size_t>(in.offsets[i + 1]))
        << "within row " << i << " has extra";
  }
}

}  // namespace

TEST(Knn, MatchesBruteForceOnRandomSets) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(bp::testing::repeats(6));
       ++seed) {
    for (Kind kind : kKinds) {
      std::mt19937_64 rng(seed * 100 + static_cast<std::uint64_t>(kind));
      const std::size_t n = std::uniform_int_distribution<std::size_t>(0, seed % 2 ? 40 : 400)(rng);
      const std::vector<double> xyz = make(kind, n, 10, rng);
      const std::vector<double> qxyz = make(Kind::uniform, 40, 14, rng);  // some outside the set
      const bp::Points pts = bp::Points::rows(xyz.data(), n);
      const std::size_t ks[] = {1, 3, 8, n + 2};
      const std::size_t k = ks[seed % 4];
      const double r = kind == Kind::lattice ? 2.5 : (kind == Kind::tiny ? 1e-300 : 1.7);
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " kind " << name(kind) << " n " << n
                                        << " k " << k << " r " << r);
      check_all(pts, std::nullopt, std::nullopt, k, r, false, 1);
      check_all(pts, std::nullopt, std::nullopt, k, r, true, 1);
      check_all(pts, bp::Points::rows(qxyz.data(), 40), std::nullopt, k, r, false, 1);
    }
  }
}

TEST(Knn, PeriodicBoxesMatchBruteForce) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(bp::testing::repeats(8));
       ++seed) {
    for (Kind kind : {Kind::uniform, Kind::clustered, Kind::lattice, Kind::flat}) {
      std::mt19937_64 rng(seed * 7919 + static_cast<std::uint64_t>(kind));
      const std::size_t n = std::uniform_int_distribution<std::size_t>(0, seed % 2 ? 30 : 600)(rng);
      std::vector<double> xyz = make(kind, n, 10, rng);
      std::vector<double> qxyz = make(Kind::uniform, 50, 10, rng);
      // Lengths of their own per axis (points scaled into them), each axis
      // periodic or not: slabs, tubes and bulk.
      bp::PeriodicCell box{{10, 10, 10}, {seed % 2 == 1, seed % 4 < 2, seed % 3 != 0}};
      const double scale[3] = {1.0, 0.75, seed % 2 ? 1.5 : 0.25};
      for (int a = 0; a < 3; ++a) {
        box.length[a] = 10 * scale[a];
        for (std::size_t i = 0; i < n; ++i) xyz[3 * i + a] *= scale[a];
        for (std::size_t i = 0; i < 50; ++i) qxyz[3 * i + a] *= scale[a];
      }
      const std::size_t ks[] = {1, 4, 16, n + 1};
      const std::size_t k = ks[seed % 4];
      const double r = seed % 3 == 0 ? 6.0 : 2.5;  // 6: beyond half the box
      SCOPED_TRACE(::testing::Message()
                   << "seed " << seed << " kind " << name(kind) << " n " << n << " k " << k << " r "
                   << r << " periodic " << box.periodic[0] << box.periodic[1] << box.periodic[2]);
      const bp::Points pts = bp::Points::rows(xyz.data(), n);
      check_all(pts, std::nullopt, box, k, r, seed % 2 == 0, 1);
      check_all(pts, bp::Points::rows(qxyz.data(), 50), box, k, r, false, 1);
    }
  }
}

TEST(Knn, FloatInputIsWidenedExactly) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<float> u(0, 3);
  std::vector<float> xyz(3 * 500);
  for (float& v : xyz) v = std::round(u(rng) * 8) / 8;  // duplicates and ties
  std::vector<double> wide(xyz.begin(), xyz.end());
  SCOPED_TRACE("seed 42");
  check_all(bp::Points::rows(xyz.data(), 500), std::nullopt, std::nullopt, 6, 0.5, true, 1);
  const bp::KnnResult f = bp::knn(bp::Points::rows(xyz.data(), 500), std::nullopt, 6);
  const bp::KnnResult d = bp::knn(bp::Points::rows(wide.data(), 500), std::nullopt, 6);
  EXPECT_EQ(f.d2, d.d2);
  EXPECT_EQ(f.index, d.index);
}

// More than one chunk of queries (4096), on 1 and 3 threads: the same rows.
TEST(Knn, ThreadsGiveTheSameOutput) {
  std::mt19937_64 rng(5);
  const std::size_t n = 9000;
  const std::vector<double> xyz = make(Kind::uniform, n, 10, rng);
  const bp::Points pts = bp::Points::rows(xyz.data(), n);
  SCOPED_TRACE("seed 5");
  const bp::KnnResult one = bp::knn(pts, std::nullopt, 5, {}, true, 1);
  const bp::KnnResult three = bp::knn(pts, std::nullopt, 5, {}, true, 3);
  EXPECT_EQ(one.d2, three.d2);
  EXPECT_EQ(one.index, three.index);
  const bp::Neighbours w1 = bp::within(pts, std::nullopt, 0.5, {}, false, 1);
  const bp::Neighbours w3 = bp::within(pts, std::nullopt, 0.5, {}, false, 3);
  EXPECT_EQ(w1.offsets, w3.offsets);
  EXPECT_EQ(w1.index, w3.index);
  EXPECT_EQ(w1.d2, w3.d2);
  // A sample of rows against the brute force.
  for (std::size_t i = 0; i < n; i += 1499) {
    const Ranked want = brute(pts, pts.at(i), std::nullopt, static_cast<std::int64_t>(i));
    for (std::size_t c = 0; c < 5; ++c) {
      ASSERT_EQ(three.d2[i * 5 + c], want[c].first) << "row " << i;
      ASSERT_EQ(three.index[i * 5 + c], want[c].second) << "row " << i;
    }
  }
}

TEST(Knn, EmptyAndSmallSets) {
  const double one[3] = {1, 2, 3};
  const bp::Points none = bp::Points::rows(one, 0);
  const bp::Points single = bp::Points::rows(one, 1);
  bp::KnnResult r = bp::knn(none, single, 3);
  ASSERT_EQ(r.d2.size(), 3u);
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_EQ(r.d2[c], kInf);
    EXPECT_EQ(r.index[c], 0);  // n = 0 fills the missing
  }
  r = bp::knn(single, std::nullopt, 2, {}, true);
  EXPECT_EQ(r.index, (std::vector<std::int64_t>{1, 1}));
  r = bp::knn(single, none, 2);
  EXPECT_TRUE(r.d2.empty());
  const bp::Neighbours w = bp::within(none, single, 1.0);
  EXPECT_EQ(w.offsets, (std::vector<std::int64_t>{0, 0}));
}

TEST(Knn, BadInputIsRefusedNamingTheRow) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double good[6] = {0, 0, 0, 1, 1, 1};
  const double bad[6] = {0, 0, 0, 1, nan, 1};
  const bp::Points pts = bp::Points::rows(good, 2);
  auto message = [](auto&& call) {
    try {
      call();
    } catch (const bp::InvalidPoints& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message([&] { bp::KnnIndex(bp::Points::rows(bad, 2)); }).find("points[1]"),
            std::string::npos);
  EXPECT_NE(message([&] { bp::knn(pts, bp::Points::rows(bad, 2), 1); }).find("queries[1]"),
            std::string::npos);
  EXPECT_NE(message([&] { bp::knn(pts, std::nullopt, 0); }).find("k must"), std::string::npos);
  EXPECT_NE(message([&] { bp::within(pts, std::nullopt, -1.0); }).find("r must"),
            std::string::npos);
  EXPECT_NE(message([&] { bp::within(pts, std::nullopt, nan); }).find("r must"), std::string::npos);
  bp::KnnConfig box;
  box.box = bp::PeriodicCell::cube(0.5, {true, false, false});
  EXPECT_NE(message([&] { bp::KnnIndex(pts, box); }).find("outside the periodic box on x"),
            std::string::npos);
  box.box = bp::PeriodicCell::cube(-1, {true, true, true});
  EXPECT_NE(message([&] { bp::KnnIndex(pts, box); }).find("length on axis x"), std::string::npos);
  bp::KnnConfig cells;
  cells.cell_points = 0;
  EXPECT_NE(message([&] { bp::KnnIndex(pts, cells); }).find("cell_points"), std::string::npos);
  const bp::KnnIndex index(pts);
  std::vector<double> d2(3);
  std::vector<std::int64_t> id(3);
  EXPECT_NE(message([&] { index.knn_self(2, false, d2, id); }).find("outputs"), std::string::npos);
}
