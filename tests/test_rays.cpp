// Ray casts of every structure against brute force (the contract's ray_hit
// over every object the ray sees): random scenes and rays of every kind the
// contract names, masks and filters, the structure mutated between casts,
// validate() after every step, all hits (index and t bit for bit), the
// closest hit, any hit and a clipping visitor; and the batches against
// single casts on one and several threads. Seeds are printed on failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <broadphase/aabb_tree.hpp>
#include <broadphase/kdtree.hpp>
#include <broadphase/rays.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "ray_testing.hpp"
#include "testing.hpp"

namespace broadphase::testing {
namespace {

using ray_testing::HitSet;
using ray_testing::Kind;
using ray_testing::kInf;

struct Object {
  Handle h;
  Shape s;
  Filter f;
};

class Model : public ray_testing::RandomRays {
 public:
  Model(std::string spec, Kind kind, std::uint64_t seed)
      : RandomRays(kind, seed), spec_(std::move(spec)) {
    Config c;
    c.world = {{base(), base(), base()}, {base() + scale(), base() + scale(), base() + scale()}};
    bp_ = make_structure(spec_, c);
  }

  void insert() {
    const Shape s = shape();
    const Filter f = filter();
    const Handle h = bp_->insert(s, objects_.size(), coin(0.3) ? Motion::fixed : Motion::dynamic);
    if (!(f == Filter{})) bp_->set_filter(h, f);
    objects_.push_back({h, s, f});
  }

  // One random mutation (insert, remove, update, filter change, bulk).
  void mutate() {
    const double p = u(0, 1);
    if (objects_.empty() || p < 0.3) {
      insert();
    } else if (p < 0.45) {
      const std::size_t i = bits() % objects_.size();
      bp_->remove(objects_[i].h);
      objects_[i] = objects_.back();
      objects_.pop_back();
    } else if (p < 0.8) {
      Object& o = objects_[bits() % objects_.size()];
      o.s = coin(0.5) ? shape()
                      : Shape{o.s.center + Vec3{u(-1, 1), u(-1, 1), u(-1, 1)} * (scale() / 50),
                              o.s.half, o.s.kind};
      bp_->update(o.h, o.s);
    } else if (p < 0.9) {
      Object& o = objects_[bits() % objects_.size()];
      o.f = filter();
      bp_->set_filter(o.h, o.f);
    } else {
      std::vector<Move> moves;
      for (int k = 0; k < 8 && !objects_.empty(); ++k) {
        Object& o = objects_[bits() % objects_.size()];
        o.s = shape();
        moves.push_back({o.h, o.s});
      }
      bp_->update(moves);
    }
    if (coin(0.3)) bp_->settle();
    bp_->validate();
  }

  Ray ray() {
    return RandomRays::ray(objects_.size(), [&](std::size_t i) { return objects_[i].s; });
  }

  HitSet brute(const Ray& r, double tmax) const {
    HitSet hits;
    for (const Object& o : objects_) {
      double t;
      if (ray_sees(r.mask, o.f) && ray_hit(r.origin, r.dir, tmax, o.s, t))
        hits.insert({o.h.index, std::bit_cast<std::uint64_t>(t)});
    }
    return hits;
  }

  // Every way of casting `r`, against brute force.
  void check(const Ray& r) {
    const HitSet want = brute(r, r.tmax);
    HitSet got;
    std::size_t reports = 0;
    bp_->cast_ray(r, [&](Handle h, double t) {
      ++reports;
      EXPECT_TRUE(bp_->contains(h));
      got.insert({h.index, std::bit_cast<std::uint64_t>(t)});
      return kRayGoOn;
    });
    ASSERT_EQ(got, want) << describe(r);
    ASSERT_EQ(reports, want.size()) << "an object reported twice " << describe(r);

    expect_closest(bp_->closest_hit(r), want, r);
    if (::testing::Test::HasFatalFailure()) return;
    ASSERT_EQ(bp_->any_hit(r), !want.empty()) << describe(r);

    // A visitor clipping the ray to 1.5 times its nearest hit so far: every
    // report is a true hit within the clip in force, and every true hit
    // within the final clip is reported.
    double clip = r.tmax;
    HitSet clipped;
    bp_->cast_ray(r, [&](Handle h, double t) {
      EXPECT_LE(t, clip);
      EXPECT_TRUE(want.count({h.index, std::bit_cast<std::uint64_t>(t)}) == 1) << describe(r);
      clipped.insert({h.index, std::bit_cast<std::uint64_t>(t)});
      clip = std::min(clip, t * 1.5);
      return clip;
    });
    for (const auto& hit : brute(r, clip))
      ASSERT_EQ(clipped.count(hit), 1u) << "a hit within the clip missed " << describe(r);
  }

  // The batch calls, closest_hits (which a structure may serve walking
  // several rays at once) and cast_rays on three threads, against brute
  // force's closest hits.
  void check_batch(const std::vector<Ray>& rays) {
    // Filled with a hit no cast gives, so that a result left unwritten shows.
    const RayHit unwritten{Handle{12345, 6789}, -1};
    std::vector<RayHit> got(rays.size(), unwritten), shared(rays.size(), unwritten);
    std::vector<RayHit> flights(rays.size(), unwritten);
    bp_->closest_hits(rays, got);
    cast_rays(*bp_, rays, shared, 3);
    // The trees walk several rays at once only from thousands of objects
    // (detail::kRayFlightsFrom): here, from any number.
    bool flown = true;
    if (const auto* kd = dynamic_cast<const Erased<KdTree>*>(bp_.get()))
      kd->get().closest_hits(rays, flights, 0);
    else if (const auto* aabb = dynamic_cast<const Erased<AabbTree>*>(bp_.get()))
      aabb->get().closest_hits(rays, flights, 0);
    else
      flown = false;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      SCOPED_TRACE("ray " + std::to_string(i) + " of a batch of " + std::to_string(rays.size()));
      const HitSet want = brute(rays[i], rays[i].tmax);
      expect_closest(got[i], want, rays[i]);
      expect_closest(shared[i], want, rays[i]);
      if (flown) expect_closest(flights[i], want, rays[i]);
      if (::testing::Test::HasFatalFailure()) return;
    }
  }

  // `c` is the closest of `want` (smallest t, then smallest slot), bit for
  // bit, or null when `want` is empty.
  void expect_closest(const RayHit& c, const HitSet& want, const Ray& r) const {
    if (want.empty()) {
      ASSERT_TRUE(c.handle.is_null()) << describe(r);
      return;
    }
    RayHit best{Handle{}, kInf};
    for (const auto& [i, b] : want) {
      const RayHit x{Handle{i, 0}, std::bit_cast<double>(b)};
      if (best.handle.is_null() || closer(x, best)) best = x;
    }
    ASSERT_FALSE(c.handle.is_null()) << describe(r);
    ASSERT_EQ(c.handle.index, best.handle.index) << describe(r);
    ASSERT_EQ(std::bit_cast<std::uint64_t>(c.t), std::bit_cast<std::uint64_t>(best.t))
        << describe(r);
  }

  std::string describe(const Ray& r) const { return ray_testing::describe(r, objects_.size()); }

  AnyBroadPhase& bp() { return *bp_; }
  std::size_t size() const { return objects_.size(); }

 private:
  std::string spec_;
  std::unique_ptr<AnyBroadPhase> bp_;
  std::vector<Object> objects_;
};

class Rays : public ::testing::TestWithParam<std::string> {};

TEST_P(Rays, MatchBruteForceOnRandomScenesAndMutations) {
  for (Kind kind : {Kind::spheres, Kind::boxes, Kind::mixed, Kind::far, Kind::huge_and_tiny,
                    Kind::lattice, Kind::levels, Kind::line})
    for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(3)); ++seed) {
      const std::uint64_t s = seed * 1000003 + static_cast<std::uint64_t>(kind);
      SCOPED_TRACE("seed " + std::to_string(s) + " kind " + ray_testing::kind_name(kind));
      Model m(GetParam(), kind, s);
      std::vector<Ray> batch;
      for (int i = 0; i < 20; ++i) {  // empty structure
        batch.push_back(m.ray());
        m.check(batch.back());
      }
      m.check_batch(batch);
      const int n = 200 + static_cast<int>(s % 300);
      for (int i = 0; i < n; ++i) m.insert();
      m.bp().settle();
      m.bp().validate();
      // 30 steps under AddressSanitizer (105 s of CPU over the structures
      // with 60), 60 elsewhere.
      const int steps = kAddressSanitizer ? 30 : 60;
      for (int step = 0; step < steps; ++step) {
        for (int k = 0; k < 5; ++k) m.mutate();
        batch.clear();
        for (int k = 0; k < 8; ++k) {
          batch.push_back(m.ray());
          m.check(batch.back());
          if (HasFailure()) return;
        }
        // Every third step, with more rays than a batch walk keeps in
        // flight, so that it starts rays in slots other rays have left.
        if (step % 3 != 0) continue;
        for (int k = 0; k < 24; ++k) batch.push_back(m.ray());
        m.check_batch(batch);
        if (HasFailure()) return;
      }
    }
}

TEST_P(Rays, BatchesMatchSingleCastsOnAnyThreadCount) {
  Model m(GetParam(), Kind::mixed, 77);
  for (int i = 0; i < 600; ++i) m.insert();
  m.bp().settle();
  std::vector<Ray> rays;
  for (int i = 0; i < 700; ++i) rays.push_back(m.ray());
  std::vector<RayHit> one(rays.size()), two(rays.size());
  cast_rays(m.bp(), rays, one, 1);
  cast_rays(m.bp(), rays, two, 3);
  RayHitRows rows1, rows3;
  cast_rays_all(m.bp(), rays, rows1, 1);
  cast_rays_all(m.bp(), rays, rows3, 3);
  ASSERT_EQ(rows1.offsets, rows3.offsets);
  ASSERT_EQ(rows1.hits.size(), rows3.hits.size());
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const RayHit single = m.bp().closest_hit(rays[i]);
    ASSERT_EQ(one[i].handle, single.handle) << i;
    ASSERT_EQ(two[i].handle, single.handle) << i;
    ASSERT_EQ(std::bit_cast<std::uint64_t>(one[i].t), std::bit_cast<std::uint64_t>(single.t));
    ASSERT_EQ(std::bit_cast<std::uint64_t>(two[i].t), std::bit_cast<std::uint64_t>(single.t));
    const HitSet want = m.brute(rays[i], rays[i].tmax);
    ASSERT_EQ(rows1.offsets[i + 1] - rows1.offsets[i], want.size()) << i;
    for (std::size_t k = rows1.offsets[i]; k < rows1.offsets[i + 1]; ++k) {
      ASSERT_EQ(rows1.hits[k].handle, rows3.hits[k].handle);
      ASSERT_EQ(std::bit_cast<std::uint64_t>(rows1.hits[k].t),
                std::bit_cast<std::uint64_t>(rows3.hits[k].t));
      if (k > rows1.offsets[i]) {
        ASSERT_FALSE(closer(rows1.hits[k], rows1.hits[k - 1]));
      }
    }
    if (!want.empty()) {
      ASSERT_EQ(rows1.hits[rows1.offsets[i]].handle, single.handle);
    }
  }
  rays[5].tmax = -1;
  EXPECT_THROW(cast_rays(m.bp(), rays, one, 2), InvalidRay);
  EXPECT_THROW(cast_rays_all(m.bp(), rays, rows1, 2), InvalidRay);
}

TEST_P(Rays, RejectInvalidRays) {
  auto bp = make_structure(GetParam());
  bp->insert(Shape::sphere({5, 5, 5}, 1), 0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Ray& bad :
       {Ray{{nan, 0, 0}, {1, 0, 0}}, Ray{{0, 0, 0}, {kInf, 0, 0}}, Ray{{0, 0, 0}, {1, 0, 0}, -1},
        Ray{{0, 0, 0}, {1, 0, 0}, nan}, Ray{{0, 0, 0}, {1e-200, 0, 0}}})
    EXPECT_THROW(bp->cast_ray(bad, [](Handle, double) { return kRayGoOn; }), InvalidRay);
}

// The culling is conservative with respect to the exact test, on the rays
// where rounding decides: grazing a sphere's rim, entering through the
// point where the bounds touch the shape, parallel to a face just outside
// it, from near and afar, with zero and tiny direction components (the
// reciprocal's fallbacks). RayCull::enter and RayCull::Within (the trees'
// culling of boxes inside their root's) must accept the object's float
// bounds at a t not beyond the hit's. (It fails on a wrong face or offset
// of the reciprocal's slab; the bounds' outward rounding to float leaves
// slack enough that it passes even without the margin.)
TEST(RayCull, AcceptsEveryHitAtOrBeforeItsT) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(20)); ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937_64 rng(seed);
    auto u = [&](double lo, double hi) {
      return std::uniform_real_distribution<double>(lo, hi)(rng);
    };
    const double base = seed % 3 == 0 ? 1e15 : seed % 3 == 1 ? 0 : -3e6;
    const double scale = std::exp(u(std::log(1e-3), std::log(1e4)));
    int hits = 0;
    for (int k = 0; k < 20000; ++k) {
      Vec3 c{base + u(-1, 1) * scale, base + u(-1, 1) * scale, base + u(-1, 1) * scale};
      double size = scale * std::exp(u(std::log(1e-6), std::log(0.5)));
      if (rng() % 2) {
        // A power of two for the size, the centre on its quarters: the
        // float bounds are then exact, with no rounding slack of their own,
        // and only the margin covers the evaluation's.
        size = std::exp2(std::round(std::log2(size)));
        for (int a = 0; a < 3; ++a) c[a] = std::round(c[a] / (size / 4)) * (size / 4);
      }
      const bool sphere = rng() % 2 == 0;
      const Shape s =
          sphere ? Shape::sphere(c, size) : Shape::box(c, {size, size * 0.5, size * 0.25});
      Ray r;
      r.origin = {base + u(-2, 2) * scale, base + u(-2, 2) * scale, base + u(-2, 2) * scale};
      // Aimed at a point of the rim or the face: the rounding decides.
      Vec3 rim{u(-1, 1), u(-1, 1), u(-1, 1)};
      const double len = std::sqrt(rim.x * rim.x + rim.y * rim.y + rim.z * rim.z);
      for (int a = 0; a < 3; ++a)
        rim[a] = sphere ? c[a] + rim[a] / std::max(len, 1e-300) * size
                        : c[a] + (rng() % 2 ? 1 : -1) * s.half[a];
      r.dir = rim - r.origin;
      if (rng() % 2) {
        // Through the point where the bounds touch the shape (a sphere's
        // pole on axis a, a box's corner), nearly in the face's plane: the
        // hit lies on the bounds' face, where a missing margin shows.
        // Entering through that face (from outside it, towards the shape).
        const int a = static_cast<int>(rng() % 3);
        Vec3 p = c, side;
        for (int k = 0; k < 3; ++k) {
          side[k] = rng() % 2 ? 1 : -1;
          if (!sphere || k == a) p[k] += side[k] * (sphere ? size : s.half[k]);
        }
        for (int k = 0; k < 3; ++k) r.dir[k] = u(-1, 1);
        r.dir[a] =
            rng() % 4 == 0 ? 0 : -side[a] * u(0.1, 1) * std::exp(u(std::log(1e-12), std::log(1.0)));
        const bool parallel = rng() % 2;
        const double back =
            scale * (parallel ? std::exp(u(std::log(0.01), std::log(1e12))) : u(0.01, 3));
        for (int k = 0; k < 3; ++k) r.origin[k] = p[k] - back * r.dir[k];
        if (parallel) {
          // Or parallel to the face, just outside it, from afar: the bounds
          // miss the line, and the sphere's evaluation, rounding |origin -
          // centre| (a few ulps of it, beyond the float bounds' own slack
          // when the origin is far), may still report a hit. The margin
          // must cover that.
          r.dir[a] = rng() % 2 ? 0 : -side[a] * 1e-20;
          const double ulp = back * 0x1p-52;
          r.origin[a] = p[a] + side[a] * std::floor(std::exp(u(0, std::log(1e3)))) * ulp;
        }
      }
      const int kind = static_cast<int>(rng() % 8);
      if (kind == 0) r.dir[static_cast<int>(rng() % 3)] = 0;       // along a face
      if (kind == 1) r.dir[static_cast<int>(rng() % 3)] *= 1e-90;  // below the reciprocal's range
      if (kind == 2) r.dir = r.dir * 1e-100;
      if (!is_valid(r)) continue;
      r.tmax = rng() % 4 == 0 ? u(0, 2) : kInf;
      double t_hit;
      if (!ray_hit(r, s, t_hit)) continue;
      ++hits;
      const AabbF b = bounds_f(s);
      // The outer box: the object's bounds, sometimes within a larger world.
      AabbF outer = b;
      if (rng() % 2)
        for (int a = 0; a < 3; ++a) {
          outer.lo[a] = std::min(outer.lo[a], static_cast<float>(base - 3 * scale));
          outer.hi[a] = std::max(outer.hi[a], static_cast<float>(base + 3 * scale));
        }
      const detail::RayCull cull(r);
      const auto within = cull.within(outer);
      double t;
      ASSERT_TRUE(cull.enter(b, r.tmax, t)) << k;
      ASSERT_LE(t, t_hit) << k;
      ASSERT_TRUE(within.enter(b, r.tmax, t)) << k;
      ASSERT_LE(t, t_hit) << k;
    }
    EXPECT_GT(hits, 1000);  // the premise: many rays hit
  }
}

// A k-d tree of one object per leaf over a chain of growing spheres is a
// hundred levels deep: a ray along the chain keeps a pending sibling per
// level, past the walk's inline stack (64 entries), which must spill and
// lose none. Many identical objects (one leaf, every hit at the same
// t: the smallest slot wins) and rays along the nodes' faces and edges.
TEST(RayWalk, DeepChainsIdenticalObjectsAndNodeFaces) {
  for (const char* spec : {"kdtree:leaf=1", "kdtree", "aabb-tree"}) {
    SCOPED_TRACE(spec);
    for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(repeats(4)); ++seed) {
      SCOPED_TRACE("seed " + std::to_string(seed));
      const bool chain_alone = seed % 2 == 1;  // else the tree mixes all three
      std::mt19937_64 rng(seed);
      auto u = [&](double lo, double hi) {
        return std::uniform_real_distribution<double>(lo, hi)(rng);
      };
      Config c;
      c.world = {{-1, -1, -1}, {2, 2, 2}};
      auto bp = make_structure(spec, c);
      std::vector<Shape> shapes;
      auto add = [&](const Shape& s) {
        bp->insert(s, shapes.size());
        shapes.push_back(s);
      };
      // Radii growing along the chain: the surface area heuristic peels the
      // largest off at each level (115 levels at one object per leaf).
      for (int k = 0; k < 300; ++k)
        add(Shape::sphere({k / 300.0, 0.5, 0.5}, 1e-4 * std::pow(1.03, k)));
      if (!chain_alone) {
        for (int k = 0; k < 200; ++k) add(Shape::sphere({0.25, 0.75, 0.25}, 0.01));  // identical
        for (int k = 0; k < 100; ++k)
          add(Shape::box({u(0, 1), u(0, 1), u(0, 1)}, {u(0, 0.05), u(0, 0.05), u(0, 0.05)}));
      }
      bp->settle();
      bp->validate();
      int deepest = 0;
      std::vector<Aabb> cells;
      bp->visit_cells([&](const Aabb& b, int depth, std::size_t) {
        deepest = std::max(deepest, depth);
        cells.push_back(b);
      });
      if (chain_alone && std::string(spec) == "kdtree:leaf=1") {
        EXPECT_GT(deepest, 64);  // the premise: deeper than the inline stack
      }
      std::vector<Ray> rays;
      for (double y : {0.5, 0.5 + 5e-4, 0.5 + 1e-4})  // along the chain: centre, inside, rim
        rays.push_back({{-1, y, 0.5}, {1, 0, 0}});
      rays.push_back({{2, 0.5, 0.5}, {-1, 0, 0}});
      rays.push_back({{0.25, -1, 0.25}, {0, 1, 0}});  // through the identical ones
      for (int k = 0; k < 200; ++k) {
        // Along a node's face or edge, in the face's plane.
        const Aabb& b = cells[rng() % cells.size()];
        Ray r;
        for (int a = 0; a < 3; ++a) r.origin[a] = rng() % 2 ? b.lo[a] : b.hi[a];
        if (!std::isfinite(r.origin.x + r.origin.y + r.origin.z)) continue;
        const int a = static_cast<int>(rng() % 3);
        r.origin[a] = u(-1, 2);
        r.dir = {0, 0, 0};
        r.dir[a] = rng() % 2 ? 1 : -1;
        if (rng() % 2) r.dir[(a + 1) % 3] = u(-1, 1);
        rays.push_back(r);
      }
      for (const Ray& r : rays) {
        HitSet want;
        RayHit best{Handle{}, kInf};
        for (std::uint32_t i = 0; i < shapes.size(); ++i) {
          double t;
          if (!ray_hit(r, shapes[i], t)) continue;
          want.insert({i, std::bit_cast<std::uint64_t>(t)});
          if (best.handle.is_null() || closer({Handle{i, 0}, t}, best)) best = {Handle{i, 0}, t};
        }
        HitSet got;
        bp->cast_ray(r, [&](Handle h, double t) {
          got.insert(
              {static_cast<std::uint32_t>(bp->user_data(h)), std::bit_cast<std::uint64_t>(t)});
          return kRayGoOn;
        });
        ASSERT_EQ(got, want);
        const RayHit c = bp->closest_hit(r);
        ASSERT_EQ(c.handle.is_null(), best.handle.is_null());
        if (!c.handle.is_null()) {
          ASSERT_EQ(bp->user_data(c.handle), best.handle.index);
          ASSERT_EQ(std::bit_cast<std::uint64_t>(c.t), std::bit_cast<std::uint64_t>(best.t));
        }
      }
    }
  }
}

// Every structure, and octree-paper placing outside objects in its border
// nodes (whose cubes then reach out to infinity).
std::vector<std::string> ray_specs() {
  std::vector<std::string> specs = structure_specs();
  specs.push_back("octree-paper:outside=clamp");
  return specs;
}

INSTANTIATE_TEST_SUITE_P(All, Rays, ::testing::ValuesIn(ray_specs()), StructureParamName{});

}  // namespace
}  // namespace broadphase::testing
