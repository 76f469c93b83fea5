// Rays over the caller's arrays (arrays/rays.hpp) against brute force (the
// contract's ray_hit over every object the ray's mask sees): a moving
// PairTracker's caster while objects move, resize, change kind and filters,
// appear and go, with rays and masks new at every call; every hit (index and
// t bit for bit, each once), the closest, any hit and a clipping visitor;
// the batches on 1 and 3 threads and the one-shot calls; the contract's
// nasty rays. Seeds are printed on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/arrays/rays.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "ray_testing.hpp"
#include "testing.hpp"

namespace broadphase {
namespace {

using arrays::IndexHit;
using arrays::IndexHitRows;
using arrays::RayCaster;

using ray_testing::HitSet;
using ray_testing::Kind;
using ray_testing::kInf;

// The caller's arrays: struct of arrays, a kind byte, filter columns.
class Model : public ray_testing::RandomRays {
 public:
  Model(Kind kind, std::uint64_t seed) : RandomRays(kind, seed) {}

  // Object i becomes a new random shape.
  void reshape(std::size_t i) {
    const Shape s = shape();
    x_[i] = s.center.x;
    y_[i] = s.center.y;
    z_[i] = s.center.z;
    kind_of_[i] = s.kind == ShapeKind::box ? 1 : 0;
    r_[i] = s.half.x;
    hx_[i] = s.half.x;
    hy_[i] = s.half.y;
    hz_[i] = s.half.z;
  }
  void refilter(std::size_t i) {
    groups_[i] = coin(0.7) ? 1u : static_cast<std::uint32_t>(1u << (bits() % 4));
    masks_[i] = 0xffffffffu;
  }
  void append() {
    const std::size_t i = x_.size();
    for (auto* v : {&x_, &y_, &z_, &r_, &hx_, &hy_, &hz_}) v->push_back(0);
    kind_of_.push_back(0);
    groups_.push_back(1);
    masks_.push_back(0xffffffffu);
    reshape(i);
    refilter(i);
  }

  // One step of the caller: some objects moved a little, some anew, some
  // refiltered, appended or removed (the last moved into its place).
  // Returns the changes to tell the tracker.
  arrays::Changes step(std::vector<std::uint32_t>& changed) {
    changed.clear();
    const std::size_t before = x_.size();
    const int moves = static_cast<int>(bits() % 12);
    for (int k = 0; k < moves && !x_.empty(); ++k) {
      const std::size_t i = bits() % x_.size();
      if (coin()) {
        reshape(i);
      } else {
        x_[i] += u(-1, 1) * scale() / 50;
        y_[i] += u(-1, 1) * scale() / 50;
      }
      changed.push_back(static_cast<std::uint32_t>(i));
    }
    for (int k = 0; k < 3 && !x_.empty(); ++k)
      if (coin(0.2)) refilter(bits() % x_.size());  // filters need not be listed
    if (coin(0.3)) append();
    if (coin(0.2) && x_.size() > 1) {
      const std::size_t i = bits() % x_.size();
      for (auto* v : {&x_, &y_, &z_, &r_, &hx_, &hy_, &hz_}) {
        (*v)[i] = v->back();
        v->pop_back();
      }
      kind_of_[i] = kind_of_.back();
      kind_of_.pop_back();
      groups_[i] = groups_.back();
      groups_.pop_back();
      masks_[i] = masks_.back();
      masks_.pop_back();
      if (i < x_.size()) changed.push_back(static_cast<std::uint32_t>(i));
    }
    for (std::size_t i = std::min(before, x_.size()); i < x_.size(); ++i)
      changed.push_back(static_cast<std::uint32_t>(i));
    std::sort(changed.begin(), changed.end());
    changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
    while (!changed.empty() && changed.back() >= x_.size()) changed.pop_back();  // gone
    return coin(0.1) ? arrays::Changes::everything() : arrays::Changes::only(changed);
  }

  arrays::Objects objects(bool filters = true) const {
    arrays::Objects o;
    o.count = x_.size();
    o.x = arrays::Column::of(x_.data());
    o.y = arrays::Column::of(y_.data());
    o.z = arrays::Column::of(z_.data());
    o.radius = arrays::Column::of(r_.data());
    o.half_x = arrays::Column::of(hx_.data());
    o.half_y = arrays::Column::of(hy_.data());
    o.half_z = arrays::Column::of(hz_.data());
    o.kind = kind_of_.data();
    if (filters) {
      o.groups = groups_;
      o.masks = masks_;
    }
    return o;
  }

  Ray ray() {
    const arrays::Objects o = objects();
    return RandomRays::ray(o.count, [&](std::size_t i) { return o.shape(i); });
  }

  HitSet brute(const Ray& r, double tmax) const {
    const arrays::Objects o = objects();
    HitSet hits;
    for (std::size_t i = 0; i < o.count; ++i) {
      double t;
      if ((groups_[i] & r.mask) != 0 && ray_hit(r.origin, r.dir, tmax, o.shape(i), t))
        hits.insert({static_cast<std::uint32_t>(i), std::bit_cast<std::uint64_t>(t)});
    }
    return hits;
  }

  static IndexHit closest_of(const HitSet& hits) {
    IndexHit best;
    for (const auto& [i, b] : hits) {
      const double t = std::bit_cast<double>(b);
      if (!best.hit() || t < best.t || (t == best.t && i < best.index)) best = {i, t};
    }
    return best;
  }

  // Every way of casting `r` into `c`, against brute force.
  void check(const RayCaster& c, const Ray& r) const {
    const HitSet want = brute(r, r.tmax);
    HitSet got;
    std::size_t reports = 0;
    c.cast(r, [&](std::uint32_t i, double t) {
      ++reports;
      got.insert({i, std::bit_cast<std::uint64_t>(t)});
      return kRayGoOn;
    });
    ASSERT_EQ(got, want) << describe(r);
    ASSERT_EQ(reports, want.size()) << "an object reported twice " << describe(r);
    const IndexHit best = closest_of(want);
    const IndexHit h = c.closest(r);
    ASSERT_EQ(h.index, best.index) << describe(r);
    ASSERT_EQ(std::bit_cast<std::uint64_t>(h.t), std::bit_cast<std::uint64_t>(best.t));
    ASSERT_EQ(c.any(r), !want.empty()) << describe(r);

    // A visitor clipping the ray to 1.5 times its nearest hit so far: every
    // report is a true hit within the clip in force, every true hit within
    // the final clip is reported.
    double clip = r.tmax;
    HitSet clipped;
    c.cast(r, [&](std::uint32_t i, double t) {
      EXPECT_LE(t, clip);
      EXPECT_EQ(want.count({i, std::bit_cast<std::uint64_t>(t)}), 1u) << describe(r);
      clipped.insert({i, std::bit_cast<std::uint64_t>(t)});
      clip = std::min(clip, t * 1.5);
      return clip;
    });
    for (const auto& hit : brute(r, clip))
      ASSERT_EQ(clipped.count(hit), 1u) << "a hit within the clip missed " << describe(r);
    // A visitor stopping at its first hit is called once.
    int calls = 0;
    c.cast(r, [&](std::uint32_t, double) {
      ++calls;
      return kStopRay;
    });
    ASSERT_EQ(calls, want.empty() ? 0 : 1) << describe(r);
  }

  // The batches against brute force on 1 and 3 threads.
  void check_batches(const RayCaster& c, const std::vector<Ray>& rays) const {
    std::vector<IndexHit> want_closest;
    std::vector<HitSet> want;
    for (const Ray& r : rays) {
      want.push_back(brute(r, r.tmax));
      want_closest.push_back(closest_of(want.back()));
    }
    for (unsigned threads : {1u, 3u}) {
      SCOPED_TRACE(::testing::Message() << "threads " << threads);
      std::vector<IndexHit> closest(rays.size());
      c.closest(rays, closest, threads);
      std::vector<std::uint8_t> any(rays.size());
      c.any(rays, any, threads);
      IndexHitRows rows;
      c.all(rays, rows, threads);
      ASSERT_EQ(rows.offsets.size(), rays.size() + 1);
      for (std::size_t k = 0; k < rays.size(); ++k) {
        ASSERT_EQ(closest[k].index, want_closest[k].index) << "ray " << k;
        ASSERT_EQ(std::bit_cast<std::uint64_t>(closest[k].t),
                  std::bit_cast<std::uint64_t>(want_closest[k].t));
        ASSERT_EQ(any[k] != 0, !want[k].empty()) << "ray " << k;
        HitSet row;
        for (std::size_t j = rows.offsets[k]; j < rows.offsets[k + 1]; ++j) {
          row.insert({rows.hits[j].index, std::bit_cast<std::uint64_t>(rows.hits[j].t)});
          if (j > rows.offsets[k]) {
            const IndexHit& a = rows.hits[j - 1];
            const IndexHit& b = rows.hits[j];
            ASSERT_TRUE(a.t < b.t || (a.t == b.t && a.index < b.index)) << "row " << k;
          }
        }
        ASSERT_EQ(row, want[k]) << "ray " << k;
      }
    }
  }

  std::string describe(const Ray& r) const { return ray_testing::describe(r, x_.size()); }

  std::size_t size() const { return x_.size(); }

 private:
  std::vector<double> x_, y_, z_, r_, hx_, hy_, hz_;
  std::vector<std::uint8_t> kind_of_;
  std::vector<std::uint32_t> groups_, masks_;
};

const Kind kKinds[] = {Kind::spheres, Kind::boxes,         Kind::mixed,
                       Kind::far,     Kind::huge_and_tiny, Kind::lattice};

// A moving tracker's caster, frame after frame: objects change between
// calls, rays and masks are new at every call.
TEST(ArraysRays, MovingTrackerMatchesBruteForce) {
  for (const Kind kind : kKinds)
    for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(4)); ++seed) {
      SCOPED_TRACE(::testing::Message()
                   << "kind " << ray_testing::kind_name(kind) << " seed " << seed);
      Model m(kind, seed * 7717 + static_cast<std::uint64_t>(kind));
      const std::size_t n = seed % 2 ? 1 + m.bits() % 40 : 200 + m.bits() % 600;
      for (std::size_t i = 0; i < n; ++i) m.append();
      arrays::PairTracker tracker;
      std::vector<std::uint32_t> changed;
      std::vector<arrays::IndexPair> pairs;
      for (int frame = 0; frame < 12; ++frame) {
        SCOPED_TRACE(::testing::Message() << "frame " << frame);
        const arrays::Changes changes =
            frame == 0 ? arrays::Changes::everything() : m.step(changed);
        pairs.clear();
        tracker.find_pairs(m.objects(), pairs, changes);
        const RayCaster& c = tracker.ray_caster(m.objects());
        ASSERT_EQ(c.size(), m.size());
        std::vector<Ray> rays;
        for (int k = 0; k < 40; ++k) {
          rays.push_back(m.ray());
          m.check(c, rays.back());
          if (::testing::Test::HasFatalFailure()) return;
        }
        // Asked again within the frame: the same caster, no build.
        ASSERT_EQ(&tracker.ray_caster(m.objects()), &c);
        m.check_batches(c, rays);
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
}

// The one-shot calls, with and without filter columns.
TEST(ArraysRays, OneShotMatchesBruteForce) {
  for (const Kind kind : kKinds)
    for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(3)); ++seed) {
      SCOPED_TRACE(::testing::Message()
                   << "kind " << ray_testing::kind_name(kind) << " seed " << seed);
      Model m(kind, seed * 104729 + static_cast<std::uint64_t>(kind));
      const std::size_t n = seed == 1 ? 0 : 1 + m.bits() % 1500;
      for (std::size_t i = 0; i < n; ++i) m.append();
      std::vector<Ray> rays;
      for (int k = 0; k < 300; ++k) rays.push_back(m.ray());
      for (unsigned threads : {1u, 2u}) {
        arrays::ArrayOptions options;
        options.threads = threads;
        std::vector<IndexHit> closest(rays.size());
        arrays::cast_rays(m.objects(), rays, closest, options);
        IndexHitRows rows;
        arrays::cast_rays_all(m.objects(), rays, rows, options);
        for (std::size_t k = 0; k < rays.size(); ++k) {
          const HitSet want = m.brute(rays[k], rays[k].tmax);
          const IndexHit best = Model::closest_of(want);
          ASSERT_EQ(closest[k], best) << m.describe(rays[k]);
          ASSERT_EQ(rows.offsets[k + 1] - rows.offsets[k], want.size()) << m.describe(rays[k]);
        }
      }
    }
}

// The contract's nasty rays, written out, into a lattice of spheres on
// cell faces and corners, with and without a sphere wider than every level.
TEST(ArraysRays, NastyRays) {
  std::vector<double> c, r;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j)
      for (int k = 0; k < 8; ++k) {
        c.insert(c.end(), {i * 8.0, j * 8.0, k * 8.0});
        r.push_back((i + j + k) % 3 == 1 ? 4.0 : 1.0);  // touching neighbours, and gaps
      }
  c.insert(c.end(), {32, 32, 32});
  r.push_back(1e4);  // wider than every level of the lattice: tested on every ray
  const std::size_t n = r.size();
  const arrays::Objects with_huge = arrays::Objects::spheres(c.data(), r.data(), n);
  const arrays::Objects lattice = arrays::Objects::spheres(c.data(), r.data(), n - 1);
  auto brute = [](const arrays::Objects& o, const Ray& ray) {
    IndexHit best;
    for (std::uint32_t i = 0; i < o.count; ++i) {
      double t;
      if (ray_hit(ray, o.shape(i), t) && (t < best.t || (t == best.t && i < best.index)))
        best = {i, t};
    }
    return best;
  };
  const std::vector<Ray> rays = {
      {{-100, 0, 0}, {1, 0, 0}, kInf},                    // along a row of centres, from outside
      {{-100, 4, 4}, {1, 0, 0}, kInf},                    // along cell faces
      {{-100, -100, -100}, {1, 1, 1}, kInf},              // through cell corners
      {{-100, -100, -100}, {-1, 0, 0}, kInf},             // never entering
      {{0, 0, 0}, {0, 0, 0}, kInf},                       // all-zero direction, inside
      {{1, 0, 0}, {0, 0, 0}, 0},                          // all-zero, tmax 0, on a surface
      {{-3, 0, 0}, {1, 0, 0}, 0},                         // tmax 0 outside
      {{-3, 0, 0}, {1, 0, 0}, 2},                         // a hit exactly at tmax: t = 2
      {{-3, 0, 0}, {1, 0, 0}, std::nextafter(2.0, 0.0)},  // just short of it
      {{8.5, 0, 0}, {0, 1, 0}, kInf},                     // starting inside: t = 0
      {{1e15, 1e15, 1e15}, {-1, -1, -1}, kInf},           // from far away, into the world
      {{1e15, 0, 0}, {-1, 0, 1e-300}, kInf},              // far, a subnormal component
  };
  for (const arrays::Objects& o : {lattice, with_huge}) {
    const RayCaster caster(o);
    for (std::size_t k = 0; k < rays.size(); ++k) {
      SCOPED_TRACE(::testing::Message() << "objects " << o.count << " ray " << k);
      const IndexHit want = brute(o, rays[k]);
      const IndexHit got = caster.closest(rays[k]);
      EXPECT_EQ(got.index, want.index);
      EXPECT_EQ(std::bit_cast<std::uint64_t>(got.t), std::bit_cast<std::uint64_t>(want.t));
      EXPECT_EQ(caster.any(rays[k]), want.hit());
    }
  }
  const RayCaster caster(lattice);
  EXPECT_EQ(caster.closest(rays[7]), (IndexHit{0, 2.0}));
  EXPECT_EQ(caster.closest(rays[5]), (IndexHit{0, 0.0}));
  EXPECT_EQ(caster.closest(rays[9]).t, 0.0);
  EXPECT_FALSE(caster.any(rays[8]));
  EXPECT_FALSE(caster.any(rays[3]));
  EXPECT_FALSE(caster.any(rays[6]));
  EXPECT_TRUE(caster.any(rays[10]));
}

// The grid culls: a short ray into 20 000 spread spheres tests a handful,
// not all of them (counts, not time), and a long one far fewer than all.
TEST(ArraysRays, TheGridCulls) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1000);
  std::vector<double> c, r;
  for (int i = 0; i < 20000; ++i) {
    c.insert(c.end(), {u(rng), u(rng), u(rng)});
    r.push_back(0.5 + u(rng) / 200);
  }
  const RayCaster caster(arrays::Objects::spheres(c.data(), r.data(), r.size()));
  std::uint64_t short_tests = 0, long_tests = 0;
  for (int k = 0; k < 100; ++k) {
    const Ray ray{{u(rng), u(rng), u(rng)}, {u(rng) - 500, u(rng) - 500, u(rng) - 500}, 0.02};
    short_tests += caster.cast(ray, [](std::uint32_t, double) { return kRayGoOn; });
    const Ray far{ray.origin, ray.dir, kInf};
    long_tests += caster.cast(far, [](std::uint32_t, double) { return kRayGoOn; });
  }
  EXPECT_LT(short_tests, 100u * 20);
  EXPECT_LT(long_tests, 100u * 2000);
}

TEST(ArraysRays, BadInputIsRefused) {
  const double c[3] = {0, 0, 0}, r[1] = {1};
  const arrays::Objects o = arrays::Objects::spheres(c, r, 1);
  const RayCaster caster(o);
  std::vector<Ray> rays(3, Ray{{0, 0, 0}, {1, 0, 0}, 1});
  rays[2].tmax = -1;
  std::vector<IndexHit> out(3);
  try {
    caster.closest(rays, out);
    FAIL() << "a negative tmax was cast";
  } catch (const InvalidRay& e) {
    EXPECT_NE(std::string(e.what()).find("ray 2"), std::string::npos) << e.what();
  }
  std::vector<IndexHit> short_out(2);
  EXPECT_THROW(caster.closest(rays, short_out), std::invalid_argument);
  rays[2].tmax = 1;
  rays[1].dir = {std::nan(""), 0, 0};
  EXPECT_THROW(caster.closest(rays[1]), InvalidRay);
  const double bad[3] = {0, std::nan(""), 0};
  EXPECT_THROW(RayCaster(arrays::Objects::spheres(bad, r, 1)), arrays::InvalidObjects);

  arrays::PairTracker tracker;
  std::vector<arrays::IndexPair> pairs;
  tracker.find_pairs(o, pairs);
  const double two_c[6] = {0, 0, 0, 1, 1, 1}, two_r[2] = {1, 1};
  tracker.ray_caster(o);
  EXPECT_THROW(tracker.ray_caster(arrays::Objects::spheres(two_c, two_r, 2)),
               std::invalid_argument);
  EXPECT_EQ(RayCaster().closest(rays[0]), IndexHit{});
}

}  // namespace
}  // namespace broadphase
