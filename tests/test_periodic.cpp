// The periodic adapter (periodic.hpp) on its own: random inserts, removes,
// bulk updates (a handle named twice included), filters changed and
// objects growing past the reach, over a few structures, against the
// brute-force oracle of the scene contract (brute_force.hpp) after every
// step; bad input refused with nothing changed; rays see originals only.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <broadphase/periodic.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/brute_force.hpp>
#include <broadphase/scenes/scene.hpp>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

namespace broadphase {
namespace {

constexpr double kL = 50;

struct Live {
  Handle handle;
  Shape shape;
  Filter filter;
};

// The contract's digest of the adapter's pairs: ids are the ranks of the
// objects' user data (the scene the oracle is given lists them in that order).
FrameDigest digest_of(const PeriodicBroadPhase& p, const std::map<std::uint64_t, Live>& live) {
  std::map<std::uint64_t, std::uint32_t> rank;
  for (const auto& [user, o] : live) rank.emplace(user, static_cast<std::uint32_t>(rank.size()));
  std::vector<PeriodicPair> pairs;
  p.find_pairs(pairs);
  FrameDigest d;
  for (const PeriodicPair& q : pairs) {
    const std::uint32_t i = rank.at(p.user_data(q.a)), j = rank.at(p.user_data(q.b));
    EXPECT_LT(i, j) << "a pair's first object must be the one with the smaller user data";
    d.add(i, j, q.shift);
  }
  return d;
}

FrameDigest oracle_of(const std::map<std::uint64_t, Live>& live, std::array<bool, 3> axes) {
  Scene s;
  s.world = kL;
  s.periodic = axes;
  for (const auto& [user, o] : live) {
    s.objects.push_back(o.shape);
    s.velocity.push_back({});
    s.filters.push_back(o.filter);
  }
  return brute_force_pairs(s);
}

Shape random_shape(Rng& rng, double largest) {
  Vec3 c{rng.uniform(0, kL), rng.uniform(0, kL), rng.uniform(0, kL)};
  for (int a = 0; a < 3; ++a)
    if (rng.below(4) == 0) c[a] = rng.below(2) ? kL : rng.uniform(0, 1);
  const double size = rng.uniform(0, largest);
  return rng.below(2) ? Shape::sphere(c, size)
                      : Shape::box(c, {size, rng.uniform(0, size), rng.uniform(0, size)});
}

class PeriodicAdapter : public ::testing::TestWithParam<std::string> {};

TEST_P(PeriodicAdapter, MatchesTheOracleThroughRandomOperations) {
  const std::array<bool, 3> kAxes[] = {
      {true, true, true}, {true, true, false}, {false, true, false}};
  for (std::uint64_t seed = 1; seed <= 3; ++seed)
    for (const auto& axes : kAxes) {
      SCOPED_TRACE(::testing::Message()
                   << "seed " << seed << " periodic " << periodic_axes_text(axes));
      Rng rng(seed);
      Config config;
      config.world = {{0, 0, 0}, {kL, kL, kL}};
      auto inner = make_structure(GetParam(), config);
      PeriodicBroadPhase p(*inner, PeriodicCell::cube(kL, axes));
      std::map<std::uint64_t, Live> live;
      std::uint64_t next_user = 1000;
      // Small objects first: the later large ones grow the reach.
      double largest = 2;
      for (int step = 0; step < 60; ++step) {
        if (step == 30) largest = kL / 2 * 0.999;
        const std::uint64_t op = rng.below(10);
        if (op < 4 || live.size() < 5) {
          const int count = 1 + static_cast<int>(rng.below(6));
          for (int k = 0; k < count; ++k) {
            const Shape s = random_shape(rng, largest);
            const Filter f{1u << rng.below(3), rng.below(4) == 0 ? 0x3u : 0xffffffffu};
            // User data in no particular order: the pair's orientation follows it.
            const std::uint64_t user = rng.below(2) ? next_user++ : 999 - live.size();
            if (live.count(user)) continue;
            live[user] = {p.insert(s, user, Motion::dynamic, f), s, f};
          }
        } else if (op < 6) {
          auto it = live.begin();
          std::advance(it, static_cast<long>(rng.below(live.size())));
          p.remove(it->second.handle);
          EXPECT_FALSE(p.contains(it->second.handle));
          EXPECT_THROW(p.remove(it->second.handle), InvalidHandle);
          live.erase(it);
        } else if (op < 9) {
          std::vector<Move> moves;
          for (auto& [user, o] : live) {
            if (rng.below(3) != 0) continue;
            o.shape = rng.below(4) == 0 ? random_shape(rng, largest) : o.shape;
            for (int a = 0; a < 3; ++a) {
              double c = o.shape.center[a];
              step_axis_periodic(c, rng.uniform(-kL / 3, kL / 3), kL);
              o.shape.center[a] = c;
            }
            moves.push_back({o.handle, o.shape});
            if (rng.below(8) == 0) {  // named twice: the last move wins
              moves.back().shape.center.x = kL - o.shape.center.x;
              moves.push_back({o.handle, o.shape});
            }
          }
          p.update(moves);
        } else {
          auto it = live.begin();
          std::advance(it, static_cast<long>(rng.below(live.size())));
          it->second.filter = {2, 2};
          p.set_filter(it->second.handle, it->second.filter);
        }
        p.validate();
        ASSERT_EQ(p.size(), live.size());
        ASSERT_EQ(digest_of(p, live), oracle_of(live, axes)) << "step " << step;
      }
      for (const auto& [user, o] : live) {
        EXPECT_EQ(p.user_data(o.handle), user);
        EXPECT_EQ(p.shape(o.handle), o.shape);
        EXPECT_EQ(p.filter(o.handle), o.filter);
      }
    }
}

INSTANTIATE_TEST_SUITE_P(Some, PeriodicAdapter,
                         ::testing::Values("naive", "grid-verlet", "aabb-tree", "sap"),
                         [](const auto& info) {
                           std::string name = info.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// Cells with a length of their own per axis (the scenes are cubes): every
// (a, b, S) by brute force, b's centre moved by S_a L_a per axis, against
// the adapter over two structures, through a few frames of wrapping motion.
TEST(PeriodicAdapterCells, OrthorhombicCellsMatchABruteForce) {
  const Vec3 length{40, 70, 100};
  const std::array<bool, 3> kAxes[] = {
      {true, false, true}, {true, true, true}, {false, true, false}};
  for (const char* spec : {"grid-verlet", "kdtree"})
    for (const auto& axes : kAxes)
      for (std::uint64_t seed = 1; seed <= 3; ++seed) {
        SCOPED_TRACE(::testing::Message()
                     << spec << " seed " << seed << " periodic " << periodic_axes_text(axes));
        Rng rng(seed);
        auto inner = make_structure(spec);
        PeriodicBroadPhase p(*inner, PeriodicCell{length, axes});
        std::vector<Shape> shapes;
        std::vector<Handle> handles;
        for (std::uint64_t i = 0; i < 150; ++i) {
          Vec3 c;
          for (int a = 0; a < 3; ++a)
            c[a] = rng.below(5) == 0 ? (rng.below(2) ? length[a] : 0) : rng.uniform(0, length[a]);
          const double size = rng.uniform(0, rng.below(10) == 0 ? 19.9 : 4);
          shapes.push_back(rng.below(2) ? Shape::sphere(c, size)
                                        : Shape::box(c, {size, rng.uniform(0, 30), size / 2}));
          handles.push_back(p.insert(shapes.back(), i));
        }
        for (int frame = 0; frame < 4; ++frame) {
          std::set<std::tuple<std::uint64_t, std::uint64_t, int>> want, got;
          for (std::size_t i = 0; i < shapes.size(); ++i)
            for (std::size_t j = i + 1; j < shapes.size(); ++j)
              for (int code = 0; code < 27; ++code) {
                const Shift t = Shift::of_code(code);
                if ((t.x != 0 && !axes[0]) || (t.y != 0 && !axes[1]) || (t.z != 0 && !axes[2]))
                  continue;
                Shape moved = shapes[j];
                for (int a = 0; a < 3; ++a)
                  moved.center[a] = shapes[j].center[a] + t[a] * length[a];
                if (overlaps(shapes[i], moved)) want.insert({i, j, code});
              }
          std::vector<PeriodicPair> pairs;
          p.find_pairs(pairs);
          for (const PeriodicPair& q : pairs)
            EXPECT_TRUE(got.insert({p.user_data(q.a), p.user_data(q.b), q.shift.code()}).second)
                << "a pair reported twice";
          ASSERT_EQ(got, want) << "frame " << frame;
          std::vector<Move> moves;
          for (std::size_t i = 0; i < shapes.size(); i += 2) {
            for (int a = 0; a < 3; ++a) {
              double c = shapes[i].center[a];
              step_axis_periodic(c, rng.uniform(-length[a] / 3, length[a] / 3), length[a]);
              shapes[i].center[a] = c;
            }
            moves.push_back({handles[i], shapes[i]});
          }
          p.update(moves);
          p.validate();
        }
      }
}

TEST(PeriodicAdapterInput, RefusesBadShapesAndChangesNothing) {
  auto inner = make_structure("naive");
  PeriodicBroadPhase p(*inner, PeriodicCell{{10, 20, 30}, {true, false, true}});
  const Handle h = p.insert(Shape::sphere({10, -5, 0}, 4.9), 1);  // y is not periodic
  EXPECT_THROW(p.insert(Shape::sphere({10.5, 0, 0}, 1), 2), InvalidShape);
  EXPECT_THROW(p.insert(Shape::sphere({1, 0, -1e-300}, 1), 2), InvalidShape);
  EXPECT_THROW(p.insert(Shape::sphere({1, 0, 1}, 5), 2), InvalidShape);  // L_x / 2
  EXPECT_THROW(p.insert(Shape::box({1, 0, 1}, {1, 1, 15}), 2), InvalidShape);
  EXPECT_NO_THROW(p.insert(Shape::box({1, 0, 1}, {1, 100, 14.9}), 3));
  const Move bad[] = {{h, Shape::sphere({1, 1, 1}, 1)}, {h, Shape::sphere({11, 1, 1}, 1)}};
  EXPECT_THROW(p.update(bad), InvalidShape);
  EXPECT_EQ(p.shape(h), Shape::sphere({10, -5, 0}, 4.9));
  p.validate();
  EXPECT_THROW((void)PeriodicBroadPhase(*inner, PeriodicCell{}),
               std::invalid_argument);  // not empty
  auto other = make_structure("naive");
  EXPECT_THROW((void)PeriodicBroadPhase(*other, PeriodicCell{{1, 0, 1}, {true, true, true}}),
               std::invalid_argument);
}

TEST(PeriodicAdapterRays, SeeTheOriginalsOnly) {
  auto inner = make_structure("grid-verlet");
  PeriodicBroadPhase p(*inner, PeriodicCell::cube(100, {true, true, true}));
  const Handle h = p.insert(Shape::sphere({1, 50, 50}, 3), 7);  // an image near x = 101
  EXPECT_GT(p.image_count(), 0u);
  std::vector<std::pair<Handle, double>> hits;
  p.cast_ray(Ray{{200, 50, 50}, {-1, 0, 0}, kRayGoOn, 0xffffffffu}, [&](Handle g, double t) {
    hits.push_back({g, t});
    return kRayGoOn;
  });
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].first, h);
  EXPECT_EQ(hits[0].second, 196);  // the original at x = 1, not the image at 101
}

}  // namespace
}  // namespace broadphase
