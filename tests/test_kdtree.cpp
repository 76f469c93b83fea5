// The k-d tree: refitting, the rebuild policies, collapsing emptied leaves,
// coincident centres, failed bulk updates, and bulk updates on trees whose
// node numbering the refit's order can and cannot use.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/kdtree.hpp>
#include <broadphase/ray.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

std::size_t count_pairs(const KdTree& t) {
  std::size_t n = 0;
  t.for_each_pair([&](Handle, Handle) { ++n; });
  return n;
}

struct Filled {
  KdTree tree;
  std::vector<Handle> handles;
  std::vector<Shape> shapes;
};

Filled filled(const char* policy, int n) {
  Config c;
  c.options["rebuild"] = policy;
  Filled f{KdTree(c), {}, {}};
  Rng rng(21);
  for (int i = 0; i < n; ++i) {
    f.shapes.push_back(
        Shape::sphere({rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, 2));
    f.handles.push_back(f.tree.insert(f.shapes.back(), static_cast<std::uint64_t>(i)));
  }
  return f;
}

// Scatters every object to a fresh random place, as one bulk update.
void scatter(Filled& f, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Move> moves;
  for (std::size_t i = 0; i < f.handles.size(); ++i)
    moves.push_back(
        {f.handles[i],
         Shape::sphere({rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, 2)});
  f.tree.update(moves);
}

TEST(KdTree, RefitOnlyNeverRebuildsForMotionAndDecays) {
  Filled f = filled("refit", 500);
  const std::uint64_t built = f.tree.rebuilds();
  scatter(f, 1);
  f.tree.validate();
  EXPECT_EQ(f.tree.rebuilds(), built);
  EXPECT_GT(f.tree.surface_sum(), 2 * f.tree.built_surface_sum());
}

TEST(KdTree, DecayPolicyRebuildsWhenSurfaceGrows) {
  Filled f = filled("decay", 500);
  const std::uint64_t built = f.tree.rebuilds();
  scatter(f, 1);
  f.tree.validate();
  EXPECT_EQ(f.tree.rebuilds(), built + 1);
  EXPECT_LE(f.tree.surface_sum(), 1.5 * f.tree.built_surface_sum());
  // A tiny move keeps the tree.
  f.tree.update(f.handles[0], Shape::sphere(f.shapes[0].center + Vec3{0.001, 0, 0}, 2));
  EXPECT_EQ(f.tree.rebuilds(), built + 1);
}

TEST(KdTree, AlwaysPolicyRebuildsOnEveryUpdateCall) {
  Filled f = filled("always", 200);
  const std::uint64_t built = f.tree.rebuilds();
  scatter(f, 2);
  f.tree.update(f.handles[3], Shape::sphere({1, 2, 3}, 4));
  f.tree.validate();
  EXPECT_EQ(f.tree.rebuilds(), built + 2);
}

TEST(KdTree, RebuildsWhenTheCountDoublesOrHalves) {
  Filled f = filled("refit", 1000);
  const std::uint64_t built = f.tree.rebuilds();
  EXPECT_EQ(built, 7u);  // at 9, 19, 39, ... 639 objects
  for (int i = 0; i < 700; ++i) f.tree.remove(f.handles[static_cast<std::size_t>(i)]);
  f.tree.validate();
  EXPECT_EQ(f.tree.rebuilds(), built + 1);
}

TEST(KdTree, EmptiedLeavesCollapseIntoTheirSibling) {
  Config c;
  c.options["leaf"] = "1";
  KdTree t(c);
  std::vector<Handle> hs;
  for (int i = 0; i < 64; ++i)
    hs.push_back(t.insert(Shape::sphere({10.0 * i, 10.0 * (i % 7), 5}, 8), i));
  const std::size_t pairs = count_pairs(t);
  EXPECT_GT(pairs, 50u);
  for (int i = 0; i < 64; i += 2) {
    t.remove(hs[static_cast<std::size_t>(i)]);
    t.validate();
  }
  for (int i = 1; i < 64; i += 2) {
    t.remove(hs[static_cast<std::size_t>(i)]);
    t.validate();
  }
  EXPECT_EQ(t.size(), 0u);
  EXPECT_EQ(count_pairs(t), 0u);
}

TEST(KdTree, CoincidentCentresMakeOneBigLeaf) {
  KdTree t;
  for (int i = 0; i < 1500; ++i) t.insert(Shape::sphere({7, 7, 7}, i % 3), i);
  t.validate();
  EXPECT_EQ(count_pairs(t), 1500u * 1499u / 2);
}

TEST(KdTree, SplitsCentresWhoseSpreadIsSubnormal) {
  // Centres spread over less than 16 / DBL_MAX: the bins' scale overflows,
  // and the split falls back to the median.
  KdTree t;
  Rng rng(5);
  std::vector<Shape> shapes;
  for (int i = 0; i < 200; ++i) {
    shapes.push_back(Shape::sphere({rng.uniform(-1, 1) * 1e-310, rng.uniform(-1, 1) * 1e-310, 0},
                                   rng.uniform(0, 1) * 1e-312));
    t.insert(shapes.back(), static_cast<std::uint64_t>(i));
  }
  t.validate();
  FrameDigest d;
  t.for_each_pair([&](Handle a, Handle b) {
    d.add(static_cast<std::uint32_t>(t.user_data(a)), static_cast<std::uint32_t>(t.user_data(b)));
  });
  EXPECT_EQ(d, testing::brute_force(shapes));
}

TEST(KdTree, FailedBulkUpdateLeavesAValidTree) {
  Filled f = filled("decay", 100);
  std::vector<Move> moves{{f.handles[0], Shape::sphere({5, 5, 5}, 1)},
                          {Handle{12345, 1}, Shape::sphere({5, 5, 5}, 1)}};
  const Shape before = f.tree.shape(f.handles[0]);
  EXPECT_THROW(f.tree.update(moves), InvalidHandle);
  f.tree.validate();
  EXPECT_EQ(f.tree.shape(f.handles[0]), before);  // all-or-nothing: the first move is not kept
}

// Bulk updates (random subsets, repeated handles, every object, none)
// between inserts that split leaves onto recycled low node indices and
// removes that collapse leaves: the refit's order is the kept one, a fresh
// one by index, or the breadth-first fallback. After every step the tree
// validates (boxes, ray records), and its pairs and closest hits equal
// brute force over the live objects.
TEST(KdTree, BulkUpdatesMatchBruteForceWhateverTheNodeNumbering) {
  for (std::uint64_t seed : {3u, 17u, 40u}) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    Config c;
    c.options["rebuild"] = "refit";  // no rebuild renumbers the nodes
    c.options["leaf"] = "2";         // a deep tree: many nodes per object
    KdTree t(c);
    Rng rng(seed);
    std::vector<Shape> shapes;  // by id (user data)
    std::vector<Handle> handles;
    std::vector<bool> alive;
    auto random_shape = [&] {
      const Vec3 p{rng.uniform(0, 200), rng.uniform(0, 200), rng.uniform(0, 200)};
      return Shape::sphere(p, rng.uniform(0.5, 12));
    };
    auto insert = [&] {
      shapes.push_back(random_shape());
      handles.push_back(t.insert(shapes.back(), shapes.size() - 1));
      alive.push_back(true);
    };
    for (int i = 0; i < 300; ++i) insert();
    for (int step = 0; step < testing::repeats(60); ++step) {
      SCOPED_TRACE(::testing::Message() << "step " << step);
      const double action = rng.uniform();
      if (action < 0.25) {
        for (int i = 0; i < 20; ++i) insert();
      } else if (action < 0.5) {
        for (int i = 0; i < 20; ++i) {
          const auto id = static_cast<std::size_t>(rng.uniform() * double(shapes.size()));
          if (!alive[id]) continue;
          t.remove(handles[id]);
          alive[id] = false;
        }
      } else {
        // All objects, about a third, or none; a fifth of the movers are
        // moved twice, the first move far from the last (the last counts).
        const double share = action < 0.6 ? 1.0 : action < 0.95 ? 0.35 : 0.0;
        std::vector<Move> decoys, moves;
        for (std::size_t id = 0; id < shapes.size(); ++id) {
          if (!alive[id] || rng.uniform() >= share) continue;
          if (rng.uniform() < 0.2) decoys.push_back({handles[id], random_shape()});
          shapes[id] = random_shape();
          moves.push_back({handles[id], shapes[id]});
        }
        decoys.insert(decoys.end(), moves.begin(), moves.end());
        t.update(decoys);
        if (share > 0) {
          // The refit summed the surface of the live nodes, and only those.
          double sum = 0;
          t.visit_cells([&](const Aabb& b, int, std::size_t) {
            if (b.lo.x > b.hi.x) return;
            const double x = b.hi.x - b.lo.x, y = b.hi.y - b.lo.y, z = b.hi.z - b.lo.z;
            sum += x * y + y * z + z * x;
          });
          ASSERT_NEAR(t.surface_sum(), sum, 1e-9 * sum);
        }
      }
      t.validate();

      FrameDigest want, got;
      for (std::uint32_t i = 0; i < shapes.size(); ++i)
        for (std::uint32_t j = i + 1; j < shapes.size(); ++j)
          if (alive[i] && alive[j] && overlaps(shapes[i], shapes[j])) want.add(i, j);
      t.for_each_pair([&](Handle a, Handle b) {
        const auto i = static_cast<std::uint32_t>(t.user_data(a));
        const auto j = static_cast<std::uint32_t>(t.user_data(b));
        got.add(std::min(i, j), std::max(i, j));
      });
      ASSERT_EQ(got, want);

      for (int k = 0; k < 20; ++k) {
        Ray r;
        r.origin = {rng.uniform(-20, 220), rng.uniform(-20, 220), rng.uniform(-20, 220)};
        r.dir = {rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
        double want_t = std::numeric_limits<double>::infinity(), tt = 0;
        std::uint64_t want_id = ~std::uint64_t{0};
        for (std::size_t id = 0; id < shapes.size(); ++id)
          if (alive[id] && ray_hit(r, shapes[id], tt) &&
              (tt < want_t || (tt == want_t && id < want_id))) {
            want_t = tt;
            want_id = id;
          }
        double got_t = std::numeric_limits<double>::infinity();
        std::uint64_t got_id = ~std::uint64_t{0};
        t.cast_ray(r, [&](Handle h, double at) {
          const std::uint64_t id = t.user_data(h);
          if (at < got_t || (at == got_t && id < got_id)) {
            got_t = at;
            got_id = id;
          }
          return at;  // clips the cast; ties at `at` are still reported
        });
        ASSERT_EQ(got_id, want_id) << "ray " << k;
        if (want_id != ~std::uint64_t{0}) {
          ASSERT_EQ(got_t, want_t) << "ray " << k;
        }
      }
    }
  }
}

TEST(KdTree, RejectsBadOptions) {
  EXPECT_THROW(make_structure("kdtree:rebuild=sometimes"), InvalidConfig);
  EXPECT_THROW(make_structure("kdtree:decay=0.5"), InvalidConfig);
  EXPECT_THROW(make_structure("kdtree:leaf=0"), InvalidConfig);
}

TEST(KdTree, MatchesNaiveUnderEveryPolicy) {
  for (const char* spec :
       {"kdtree:rebuild=refit", "kdtree:rebuild=always,leaf=1", "kdtree:leaf=64,decay=1"}) {
    for (auto w : {testing::World::mixed, testing::World::touching, testing::World::huge}) {
      testing::differential(spec, w, 19, 500);
      if (HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace broadphase
