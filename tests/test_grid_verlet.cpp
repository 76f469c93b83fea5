// grid-verlet's (formerly fast-grid's) own invariants and edge cases,
// beyond the shared differential and reference-scene suites: the fixed-pair
// cache, the loose list and its rebuild threshold, held-back slots,
// candidate lists, threads, and the old names.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/fast_grid.hpp>  // the deprecated names, tested below
#include <broadphase/grid_verlet.hpp>
#include <broadphase/naive.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/sort_sweep.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

using IdPairs = std::set<std::pair<std::uint64_t, std::uint64_t>>;

template <class S>
IdPairs pairs_of(const S& s) {
  IdPairs out;
  s.for_each_pair([&](Handle a, Handle b) {
    std::uint64_t x = s.user_data(a), y = s.user_data(b);
    if (x > y) std::swap(x, y);
    EXPECT_TRUE(out.insert({x, y}).second) << "pair reported twice: " << x << ", " << y;
  });
  return out;
}

using IdList = std::vector<std::pair<std::uint64_t, std::uint64_t>>;

/// find_pairs' pairs as user data, in the order reported.
IdList found_in_order(const GridVerlet& g) {
  std::vector<HandlePair> out;
  g.find_pairs(out);
  IdList ids;
  for (const HandlePair& p : out) ids.push_back({g.user_data(p.a), g.user_data(p.b)});
  return ids;
}

/// for_each_pair's pairs as user data, in the order visited.
IdList visited_in_order(const GridVerlet& g) {
  IdList ids;
  g.for_each_pair([&](Handle a, Handle b) { ids.push_back({g.user_data(a), g.user_data(b)}); });
  return ids;
}

/// Inserts every object of `scene` (user data: its index), fixed or moving
/// as the scene says.
std::vector<Handle> insert_scene(GridVerlet& g, const Scene& scene) {
  std::vector<Handle> h;
  for (std::size_t i = 0; i < scene.size(); ++i)
    h.push_back(
        g.insert(scene.objects[i], i, scene.is_moving(i) ? Motion::dynamic : Motion::fixed));
  return h;
}

/// Removes, or inserts again, `count` objects of `scene` drawn by `rng`
/// (user data: the index), keeping `h` and `alive` up to date.
void toggle_some(GridVerlet& g, const Scene& scene, std::vector<Handle>& h,
                 std::vector<bool>& alive, Rng& rng, int count) {
  for (int k = 0; k < count; ++k) {
    const std::size_t i = rng.below(scene.size());
    if (alive[i])
      g.remove(h[i]);
    else
      h[i] = g.insert(scene.objects[i], i);
    alive[i] = !alive[i];
  }
}

/// Moves every live moving object of `scene` to where the scene has it.
void move_live(GridVerlet& g, const Scene& scene, const std::vector<Handle>& h,
               const std::vector<bool>& alive) {
  std::vector<Move> moves;
  for (std::size_t i = 0; i < scene.size(); ++i)
    if (alive[i] && scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
  g.update(moves);
}

Config with_option(const char* key, const char* value) {
  Config c;
  c.options[key] = value;
  return c;
}

/// The oracle's pairs of `shapes` (user data: the index).
IdPairs naive_pairs(const std::vector<Shape>& shapes) {
  Naive n;
  for (std::size_t i = 0; i < shapes.size(); ++i) n.insert(shapes[i], i);
  return pairs_of(n);
}

/// Whether the bulk-update tests on 32 000 objects ask the oracle. Under
/// the sanitizers they check races and memory and compare one thread with
/// two (on_one_and_two_threads), and the oracle's O(n^2) pass is left to
/// the Release build: it took most of their 120 s each under
/// ThreadSanitizer and most of their 50 s each under AddressSanitizer.
constexpr bool kOracleOnLargeScenes =
    !broadphase::testing::kThreadSanitizer && !broadphase::testing::kAddressSanitizer;

/// Runs body(grid, scene, handles, threads, pairs) on a copy of `start`
/// inserted into a grid with threads=1, then threads=2, and expects the
/// pairs the two runs leave in `pairs` to be equal.
template <class F>
void on_one_and_two_threads(const Scene& start, F body) {
  std::vector<IdPairs> results;
  for (const char* t : {"1", "2"}) {
    Scene scene = start;
    GridVerlet g(with_option("threads", t));
    const std::vector<Handle> h = insert_scene(g, scene);
    results.emplace_back();
    body(g, scene, h, t, results.back());
  }
  EXPECT_EQ(results[0], results[1]);
}

TEST(GridVerlet, RejectsUnknownAndBadOptions) {
  EXPECT_THROW(GridVerlet(with_option("cells", "2")), InvalidConfig);
  EXPECT_THROW(GridVerlet(with_option("threads", "1.5")), InvalidConfig);
  EXPECT_THROW(GridVerlet(with_option("threads", "-1")), InvalidConfig);
  EXPECT_GE(GridVerlet(with_option("threads", "0")).threads(), 1u);
  EXPECT_LE(GridVerlet(with_option("threads", "0")).threads(), 64u);
  EXPECT_THROW(GridVerlet(with_option("threads", "65")), InvalidConfig);
  EXPECT_EQ(GridVerlet(with_option("threads", "2")).threads(), 2u);
  EXPECT_THROW(GridVerlet(with_option("grain", "0")), InvalidConfig);
  EXPECT_THROW(GridVerlet(with_option("grain", "2.5")), InvalidConfig);
  EXPECT_NO_THROW(GridVerlet(with_option("grain", "1")));
}

TEST(GridVerlet, CachedFixedPairsFollowRemovalAndUpdate) {
  GridVerlet g;
  const Handle a = g.insert(Shape::sphere({0, 0, 0}, 1), 0, Motion::fixed);
  const Handle b = g.insert(Shape::sphere({1.5, 0, 0}, 1), 1, Motion::fixed);
  const Handle c = g.insert(Shape::sphere({3, 0, 0}, 1), 2, Motion::fixed);
  g.settle();  // folds the fixed objects into the cache
  g.validate();
  EXPECT_EQ(pairs_of(g), (IdPairs{{0, 1}, {1, 2}}));
  g.update(b, Shape::sphere({100, 0, 0}, 1));  // a fixed object moved: its cached pairs go
  g.validate();
  EXPECT_EQ(pairs_of(g), IdPairs{});
  g.update(b, Shape::sphere({0.5, 0, 0}, 1));
  g.remove(a);
  g.validate();
  EXPECT_EQ(pairs_of(g), IdPairs{});
  EXPECT_FALSE(g.contains(a));
  EXPECT_THROW(g.remove(a), InvalidHandle);
  EXPECT_THROW(g.update(a, Shape::sphere({0, 0, 0}, 1)), InvalidHandle);
  g.update(b, Shape::sphere({2, 0, 0}, 1));
  g.settle();
  g.validate();
  EXPECT_EQ(pairs_of(g), (IdPairs{{1, 2}}));
  EXPECT_TRUE(g.contains(c));
}

TEST(GridVerlet, HeldSlotsAreNotReusedBeforeARebuild) {
  GridVerlet g;
  std::vector<Handle> h;
  for (int i = 0; i < 10; ++i)
    h.push_back(g.insert(Shape::sphere({i * 10.0, 0, 0}, 6), static_cast<std::uint64_t>(i)));
  g.settle();  // all in the moving grid now
  g.remove(h[3]);
  const Handle fresh = g.insert(Shape::sphere({30, 0, 0}, 6), 99);
  EXPECT_NE(fresh.index, h[3].index) << "a slot still named by a grid entry was handed out";
  g.validate();
  IdPairs expect;
  for (int i = 0; i + 1 < 10; ++i)
    if (i != 2 && i != 3)
      expect.insert({static_cast<std::uint64_t>(i), static_cast<std::uint64_t>(i + 1)});
  expect.insert({2, 99});
  expect.insert({4, 99});
  expect.erase({3, 4});
  EXPECT_EQ(pairs_of(g), expect);
}

TEST(GridVerlet, ManyInsertsStayExactAcrossRebuilds) {
  // Crosses the loose-list threshold many times, with fixed and moving objects.
  GridVerlet g;
  Naive n;
  Rng rng(7);
  std::vector<std::pair<Handle, Handle>> live;
  for (int i = 0; i < 3000; ++i) {
    const Shape s = Shape::sphere({rng.uniform(0, 200), rng.uniform(0, 200), rng.uniform(0, 200)},
                                  rng.uniform(0, 6));
    const Motion m = i % 3 ? Motion::fixed : Motion::dynamic;
    live.push_back({g.insert(s, static_cast<std::uint64_t>(i), m),
                    n.insert(s, static_cast<std::uint64_t>(i), m)});
    if (i % 7 == 0) {
      const std::size_t k = rng.below(live.size());
      g.remove(live[k].first);
      n.remove(live[k].second);
      live[k] = live.back();
      live.pop_back();
    }
  }
  g.validate();
  EXPECT_EQ(pairs_of(g), pairs_of(n));
}

TEST(GridVerlet, CandidateListsStayCompleteForFastAndSlowMovers) {
  Scene scene = generate(Distribution::even, 1500, 3);
  GridVerlet g;
  const std::vector<Handle> h = insert_scene(g, scene);
  std::vector<Move> moves;
  for (int f = 0; f < 12; ++f) {
    // Every third frame the movers jump far: their lists must be rebuilt.
    for (std::size_t i = 0; i < scene.size(); ++i)
      if (scene.is_moving(i)) scene.velocity[i] = scene.velocity[i] * (f % 3 == 0 ? 40.0 : 0.025);
    step(scene);
    moves.clear();
    for (std::size_t i = 0; i < scene.size(); ++i)
      if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
    g.update(moves);
    g.validate();
    ASSERT_EQ(pairs_of(g), naive_pairs(scene.objects)) << "frame " << f;
  }
}

TEST(GridVerlet, NearListsStayExactWhileMoversComeAndGo) {
  // Movers renew their lists at different frames (speeds differ by 40x),
  // some leave and new ones take their slots between frames: every frame
  // must still match the naive oracle, and validate() checks that every two
  // movers with overlapping fat boxes are in the right near list.
  Scene scene = generate(Distribution::all_moving, 900, 11);
  scene.world *= 0.3;  // crowded: many pairs, many neighbours per list
  for (std::size_t i = 0; i < scene.size(); ++i) {
    scene.objects[i].center = scene.objects[i].center * 0.3;
    scene.velocity[i] = scene.velocity[i] * (i % 5 == 0 ? 20.0 : 0.5);
  }
  GridVerlet g(with_option("movers", "lists"));  // the lists under test, whatever the motion
  std::vector<Handle> h(scene.size());
  std::vector<bool> alive(scene.size(), true);
  for (std::size_t i = 0; i < scene.size(); ++i) h[i] = g.insert(scene.objects[i], i);
  Rng rng(5);
  std::size_t seen = 0;
  for (int f = 0; f < 40; ++f) {
    step(scene);
    toggle_some(g, scene, h, alive, rng, 6);
    move_live(g, scene, h, alive);
    g.validate();
    Naive n;
    for (std::size_t i = 0; i < scene.size(); ++i)
      if (alive[i]) n.insert(scene.objects[i], i);
    const IdPairs expect = pairs_of(n);
    seen += expect.size();
    ASSERT_EQ(pairs_of(g), expect) << "frame " << f;
  }
  EXPECT_GT(seen, 100u) << "the scene should have pairs to find";
}

/// The ids of every object `ray` hits in `s` (all hits, in no order).
template <class S>
std::set<std::uint64_t> ray_hits(const S& s, const Ray& ray) {
  std::set<std::uint64_t> out;
  s.cast_ray(ray, [&](Handle h, double) { out.insert(s.user_data(h)); });
  return out;
}

/// The ids of every object overlapping `q` in `s`.
template <class S>
std::set<std::uint64_t> query_ids(const S& s, const Shape& q) {
  std::set<std::uint64_t> out;
  s.query(q, [&](Handle h) { out.insert(s.user_data(h)); });
  return out;
}

TEST(GridVerlet, MoversSwitchBetweenListsAndTheDenseGridAndStayExact) {
  // Phases of fast and slow motion: with movers=auto the structure must take
  // the dense grid while most movers would renew their lists each frame and
  // go back to lists when they slow down, and every frame, query and ray in
  // between must match the naive oracle, through inserts, removes, single
  // moves, filter changes and fixed objects.
  for (const std::uint64_t seed : {3u, 17u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    Scene scene = generate(Distribution::all_moving, 700, seed);
    scene.world *= 0.3;  // crowded: pairs among movers and with fixed objects
    for (std::size_t i = 0; i < scene.size(); ++i)
      scene.objects[i].center = scene.objects[i].center * 0.3;
    Config c;
    c.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    GridVerlet g(c, GridVerletOptions{});
    Naive n;
    std::vector<Handle> h(scene.size()), hn(scene.size());
    std::vector<bool> alive(scene.size(), true);
    for (std::size_t i = 0; i < scene.size(); ++i) {
      const Motion m = i % 7 == 0 ? Motion::fixed : Motion::dynamic;  // a seventh stays
      h[i] = g.insert(scene.objects[i], i, m);
      hn[i] = n.insert(scene.objects[i], i);
    }
    Rng rng(seed);
    std::vector<Move> moves;
    for (int f = 0; f < 72; ++f) {
      SCOPED_TRACE("frame " + std::to_string(f));
      // Fast in frames 0-23 and 48-71 (beyond half the fixed grid's cells,
      // which bound the margins here), slow between.
      const double speed = f < 24 || f >= 48 ? 40.0 : 0.02;
      for (std::size_t i = 0; i < scene.size(); ++i) {
        if (i % 7 == 0) continue;
        const Vec3 v = scene.velocity[i];
        const double len = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
        if (len > 0) scene.velocity[i] = v * (speed / len);
      }
      step(scene);
      // Objects come and go on odd frames, filters change every fourth and
      // some objects move one at a time every sixth: the other frames run
      // in dense mode without a rebuild. Each change is checked at once.
      auto check_rays = [&] {
        for (int k = 0; k < 8; ++k) {
          const Vec3 o = scene.objects[rng.below(scene.size())].center;
          const Vec3 d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
          const Ray ray{o, d, k % 2 == 0 ? 1e9 : 40, k % 4 < 2 ? 0x5u : 0xffffffffu};
          ASSERT_EQ(ray_hits(g, ray), ray_hits(n, ray)) << "ray " << k;
        }
      };
      for (int k = 0; f % 2 == 1 && k < 5; ++k) {
        const std::size_t i = rng.below(scene.size());
        if (i % 7 == 0) continue;
        if (alive[i]) {
          g.remove(h[i]);
          n.remove(hn[i]);
        } else {
          h[i] = g.insert(scene.objects[i], i);
          hn[i] = n.insert(scene.objects[i], i);
        }
        alive[i] = !alive[i];
      }
      if (f % 2 == 1) {
        g.validate();
        ASSERT_EQ(pairs_of(g), pairs_of(n)) << "after inserts and removes";
      }
      for (int k = 0; f % 4 == 0 && k < 20; ++k) {  // filter changes on live movers
        const std::size_t i = 1 + 7 * rng.below(scene.size() / 7 - 1);
        if (alive[i]) {
          const Filter fl{1u << rng.below(3), 0x3u};
          g.set_filter(h[i], fl);
          n.set_filter(hn[i], fl);
        }
      }
      if (f % 4 == 0) {
        g.validate();
        check_rays();
        ASSERT_EQ(pairs_of(g), pairs_of(n)) << "after filter changes";
      }
      moves.clear();
      for (std::size_t i = 0; i < scene.size(); ++i) {
        if (!alive[i] || i % 7 == 0) continue;
        if (f % 6 == 5 && i % 50 == 1) {  // some move one at a time, by the loose list
          g.update(h[i], scene.objects[i]);
        } else {
          moves.push_back({h[i], scene.objects[i]});
        }
        n.update(hn[i], scene.objects[i]);
      }
      g.update(moves);
      g.validate();
      // The mode is looked at every eighth bulk update from the second
      // (frames 1, 9, 17, ...): by then each phase has shown its speeds.
      if ((f >= 10 && f < 24) || f >= 58) {
        EXPECT_TRUE(g.dense_movers()) << "fast movers";
      }
      if (f >= 34 && f < 48) {
        EXPECT_FALSE(g.dense_movers()) << "slow movers";
      }
      ASSERT_EQ(pairs_of(g), pairs_of(n));
      const Shape q = Shape::sphere(scene.objects[rng.below(scene.size())].center, 4);
      ASSERT_EQ(query_ids(g, q), query_ids(n, q));
      check_rays();
    }
  }
}

TEST(GridVerlet, TheMoverModeCanBeForced) {
  Scene scene = generate(Distribution::explosion, 600, 9);
  for (const char* mode : {"lists", "dense"}) {
    SCOPED_TRACE(mode);
    GridVerlet g(with_option("movers", mode));
    const std::vector<Handle> h = insert_scene(g, scene);
    const std::vector<bool> alive(scene.size(), true);
    Scene s = scene;
    for (int f = 0; f < 20; ++f) {
      step(s);
      move_live(g, s, h, alive);
      g.validate();
      EXPECT_EQ(g.dense_movers(), std::string(mode) == "dense");
      ASSERT_EQ(pairs_of(g), naive_pairs(s.objects));
    }
  }
  EXPECT_THROW(GridVerlet(with_option("movers", "sometimes")), InvalidConfig);
}

TEST(GridVerlet, ListPoolsAreReusedInPlace) {
  // Over many frames every mover renews its lists again and again; renewed
  // lists are appended to the pools, and the lists that stay are moved to
  // the front when the pools are full. The pairs must stay exact across
  // those moves and the memory must stop growing.
  Scene scene = generate(Distribution::even, 2000, 17);
  scene.world *= 0.3;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    scene.objects[i].center = scene.objects[i].center * 0.3;
    scene.velocity[i] = scene.velocity[i] * 3.0;
  }
  GridVerlet g;
  const std::vector<Handle> h = insert_scene(g, scene);
  std::vector<Move> moves;
  std::size_t memory_at_20 = 0;
  for (int f = 0; f < 120; ++f) {
    step(scene);
    moves.clear();
    for (std::size_t i = 0; i < scene.size(); ++i)
      if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
    g.update(moves);
    if (f % 6 == 0) {
      g.validate();
      ASSERT_EQ(pairs_of(g), naive_pairs(scene.objects)) << "frame " << f;
    }
    if (f == 20) memory_at_20 = g.memory_bytes();
  }
  EXPECT_LE(g.memory_bytes(), memory_at_20 + memory_at_20 / 2)
      << "the candidate pools kept growing";
}

TEST(GridVerlet, TwoThreadsStayExactThroughInsertsAndRemoves) {
  // 24 000 objects give 4 800 moving ones: two shares in every split pass
  // (grid builds, list renewals, pair finding). Between frames objects are
  // inserted, removed and moved singly, so rebuilds take loose objects and
  // held slots; the pairs must match an independent exact structure and
  // one thread's, in the same order.
  Scene scene = generate(Distribution::scaled_even, 24000, 11);
  Config c2 = with_option("threads", "2");
  c2.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  Config c1 = c2;
  c1.options["threads"] = "1";
  GridVerlet two(c2), one(c1);
  SortSweep oracle;
  std::vector<Handle> h2 = insert_scene(two, scene), h1 = insert_scene(one, scene), ho;
  for (std::size_t i = 0; i < scene.size(); ++i) ho.push_back(oracle.insert(scene.objects[i], i));
  std::vector<bool> alive(scene.size(), true);
  Rng rng(7);
  std::vector<Move> m2, m1;
  for (int f = 0; f < 8; ++f) {
    if (f > 0) {
      for (std::size_t i = 0; i < scene.size(); ++i)
        if (scene.is_moving(i)) scene.velocity[i] = scene.velocity[i] * (f == 2 ? 20.0 : 1.0);
      step(scene);
    }
    for (int k = 0; k < 300; ++k) {
      const std::size_t i = rng.below(scene.size());
      if (alive[i] && k % 3 == 0) {  // removed
        two.remove(h2[i]);
        one.remove(h1[i]);
        oracle.remove(ho[i]);
        alive[i] = false;
      } else if (!alive[i]) {  // back, where the scene has it now
        h2[i] = two.insert(scene.objects[i], i, Motion::dynamic);
        h1[i] = one.insert(scene.objects[i], i, Motion::dynamic);
        ho[i] = oracle.insert(scene.objects[i], i);
        alive[i] = true;
      } else if (!scene.is_moving(i)) {  // a fixed object nudged singly
        Shape s = scene.objects[i];
        s.center.y += 0.25;
        two.update(h2[i], s);
        one.update(h1[i], s);
        oracle.update(ho[i], s);
      }
    }
    m2.clear();
    m1.clear();
    for (std::size_t i = 0; i < scene.size(); ++i)
      if (alive[i] && scene.is_moving(i)) {
        m2.push_back({h2[i], scene.objects[i]});
        m1.push_back({h1[i], scene.objects[i]});
        oracle.update(ho[i], scene.objects[i]);
      }
    two.update(m2);
    one.update(m1);
    two.validate();
    std::vector<HandlePair> p2, p1;
    two.find_pairs(p2);
    one.find_pairs(p1);
    ASSERT_EQ(p2.size(), p1.size()) << "frame " << f;
    for (std::size_t k = 0; k < p2.size(); ++k)
      ASSERT_TRUE(two.user_data(p2[k].a) == one.user_data(p1[k].a) &&
                  two.user_data(p2[k].b) == one.user_data(p1[k].b))
          << "frame " << f << ", pair " << k << ": the order depends on the threads";
    EXPECT_EQ(pairs_of(two), pairs_of(oracle)) << "frame " << f;
  }
}

TEST(GridVerlet, PairsOnThreadsComeWholeAndInOrderEveryTime) {
  // find_pairs on threads appends the chunks' pairs in order while later
  // chunks are still being found, on whichever thread is free: repeated
  // many times with more threads than cores (so that the threads are
  // preempted at every point), each call must give one thread's list.
  // The study's crowded placement with every object moving: 12 000 movers
  // make four shares, 32 chunks.
  Scene scene = generate(Distribution::uneven, 12000, 3);
  for (Vec3& v : scene.velocity)
    if (v.x == 0 && v.y == 0 && v.z == 0) v = {0.5, 0, 0};
  GridVerlet one(with_option("threads", "1"));
  GridVerlet four(with_option("threads", "4"));
  const std::vector<Handle> h1 = insert_scene(one, scene), h4 = insert_scene(four, scene);
  std::vector<Move> m1, m4;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    m1.push_back({h1[i], scene.objects[i]});
    m4.push_back({h4[i], scene.objects[i]});
  }
  one.update(m1);
  four.update(m4);
  const IdList expect = found_in_order(one);
  ASSERT_GT(expect.size(), 10000u);
  for (int k = 0; k < broadphase::testing::repeats(200); ++k)
    ASSERT_EQ(found_in_order(four), expect) << "call " << k;
}

TEST(GridVerlet, PairOrderDoesNotDependOnThreads) {
  // 32 000 objects give 6400 moving ones: enough for three threads to split
  // both the candidate lists and the pair finding.
  const Scene start = generate(Distribution::scaled_even, 32000, 5);
  std::vector<IdList> orders;
  for (const char* t : {"1", "2", "3"}) {
    Scene scene = start;
    GridVerlet g(with_option("threads", t));
    const std::vector<Handle> h = insert_scene(g, scene);
    IdList ids;
    std::vector<Move> moves;
    for (int f = 0; f < 3; ++f) {
      if (f > 0) {
        for (std::size_t i = 0; i < scene.size(); ++i)
          if (scene.is_moving(i)) scene.velocity[i] = scene.velocity[i] * (f == 1 ? 30.0 : 1.0);
        step(scene);
      }
      moves.clear();
      for (std::size_t i = 0; i < scene.size(); ++i)
        if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
      g.update(moves);
      g.validate();
      const IdList frame = found_in_order(g);
      const IdList visited = visited_in_order(g);
      EXPECT_EQ(frame, visited) << "find_pairs and for_each_pair disagree with threads=" << t;
      ids.insert(ids.end(), frame.begin(), frame.end());
    }
    orders.push_back(std::move(ids));
  }
  EXPECT_FALSE(orders[0].empty());
  EXPECT_EQ(orders[0], orders[1]);
  EXPECT_EQ(orders[0], orders[2]);
}

TEST(GridVerlet, DenseModePairOrderDoesNotDependOnThreads) {
  // Everything moves fast: the movers take the dense grid, whose moves are
  // staged on the threads and relinked after them, and whose pairs are
  // found by chunks of its cells. Pairs and their order must be those of
  // one thread, frame after frame, with objects coming and going.
  const Scene start = generate(Distribution::explosion, 12000, 8);
  std::vector<IdList> orders;
  for (const char* t : {"1", "2", "3"}) {
    SCOPED_TRACE(std::string("threads=") + t);
    Scene scene = start;
    Config c = with_option("threads", t);
    c.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    GridVerlet g(c);
    std::vector<Handle> h = insert_scene(g, scene);
    std::vector<bool> alive(scene.size(), true);
    Rng rng(3);
    IdList ids;
    for (int f = 0; f < 14; ++f) {
      step(scene);
      if (f % 3 == 2) toggle_some(g, scene, h, alive, rng, 40);
      move_live(g, scene, h, alive);
      g.validate();
      const IdList frame = found_in_order(g);
      const IdList visited = visited_in_order(g);
      ASSERT_EQ(frame, visited) << "find_pairs and for_each_pair disagree, frame " << f;
      ids.insert(ids.end(), frame.begin(), frame.end());
    }
    EXPECT_TRUE(g.dense_movers()) << "an explosion should take the dense grid";
    orders.push_back(std::move(ids));
  }
  EXPECT_GT(orders[0].size(), 1000u);
  EXPECT_EQ(orders[0], orders[1]);
  EXPECT_EQ(orders[0], orders[2]);
}

TEST(GridVerlet, ParallelBulkUpdateKeepsOrderAndChecks) {
  // A bulk update split over two threads: a handle named twice (the later
  // move wins), fixed objects that start moving, and moves that must be
  // refused whole (a stale handle, a NaN) after a valid prefix.
  on_one_and_two_threads(
      generate(Distribution::scaled_even, 32000, 9),
      [](GridVerlet& g, Scene& scene, const std::vector<Handle>& h, const char* t,
         IdPairs& before) {
        std::vector<Move> moves;
        for (std::size_t i = 0; i < scene.size(); ++i)
          if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
        g.update(moves);
        step(scene);
        std::vector<Shape> now = scene.objects;
        moves.clear();
        constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
        std::size_t first_moving = kNone, fixed_a = kNone, fixed_b = kNone;
        for (std::size_t i = 0; i < scene.size(); ++i) {
          if (scene.is_moving(i)) {
            if (moves.empty()) first_moving = i;
            moves.push_back({h[i], scene.objects[i]});
          } else if (fixed_a == kNone) {
            fixed_a = i;
          } else if (fixed_b == kNone) {
            fixed_b = i;
          }
        }
        ASSERT_NE(fixed_b, kNone);
        // Twice the same mover: first far away, then onto a fixed object.
        moves.insert(moves.begin() + 5, {h[first_moving], Shape::sphere({-5e3, 0, 0}, 1)});
        now[first_moving] = Shape::sphere(scene.objects[fixed_b].center, 1);
        moves.push_back({h[first_moving], now[first_moving]});
        // A fixed object that moves onto another.
        now[fixed_a] = Shape::sphere(scene.objects[fixed_b].center, 2);
        moves.push_back({h[fixed_a], now[fixed_a]});
        g.update(moves);
        g.validate();
        auto same_shapes = [&] {
          for (std::size_t i = 0; i < now.size(); ++i) {
            if (!g.contains(h[i])) continue;
            const Shape& s = g.shape(h[i]);
            if (!(s.center == now[i].center && s.half == now[i].half)) return false;
          }
          return true;
        };
        EXPECT_TRUE(same_shapes()) << "threads=" << t;
        before = pairs_of(g);
        if (kOracleOnLargeScenes) {
          EXPECT_EQ(before, naive_pairs(now)) << "threads=" << t;
        }
        auto has = [&](std::size_t a, std::size_t b) {
          return before.count({std::min(a, b), std::max(a, b)}) == 1;
        };
        EXPECT_TRUE(has(first_moving, fixed_b) && has(fixed_a, fixed_b) &&
                    has(first_moving, fixed_a));
        // Refused whole: nothing moves, not even the valid moves before the bad one.
        std::vector<Move> bad = moves;
        for (Move& m : bad) m.shape = Shape::sphere(m.shape.center + Vec3{50, 0, 0}, 40);
        const Handle stale = h[fixed_b];
        g.remove(stale);
        bad.push_back({stale, Shape::sphere({0, 0, 0}, 1)});
        EXPECT_THROW(g.update(bad), InvalidHandle) << "threads=" << t;
        bad.back() = {h[first_moving], Shape::sphere({std::nan(""), 0, 0}, 1)};
        EXPECT_THROW(g.update(bad), InvalidShape) << "threads=" << t;
        g.validate();
        EXPECT_TRUE(same_shapes()) << "threads=" << t;
        IdPairs expect;
        for (const auto& p : before)
          if (p.first != fixed_b && p.second != fixed_b) expect.insert(p);
        EXPECT_EQ(pairs_of(g), expect) << "threads=" << t;
      });
}

TEST(GridVerlet, BulkUpdateNamingEveryMoverTwiceKeepsTheLaterMoves) {
  // Every mover named twice, first with a decoy far away, then with its
  // place, in several layouts: all decoys first; blocks of decoys and
  // places taking turns (blocks about as long as a thread's piece of the
  // moves, so that a decoy and its place would be moved at the same time);
  // each mover's two moves at random places. Split over two threads by the
  // moves, decoys and places would race: every later move must still win,
  // with the same pairs as on one thread.
  on_one_and_two_threads(
      generate(Distribution::scaled_even, 32000, 4),
      [](GridVerlet& g, Scene& scene, const std::vector<Handle>& h, const char* t, IdPairs& pairs) {
        std::vector<std::size_t> movers;
        for (std::size_t i = 0; i < scene.size(); ++i)
          if (scene.is_moving(i)) movers.push_back(i);
        const std::size_t m = movers.size();
        Rng rng(17);
        // Under ThreadSanitizer, two of the layouts: blocks about a thread's
        // piece, and random places.
        std::vector<std::size_t> blocks{m, m / 8, m / 16, m / 5, 0};
        if (broadphase::testing::kThreadSanitizer) blocks = {m / 8, 0};
        for (std::size_t block : blocks) {
          step(scene);
          // Where each mover's two moves go: tokens, a mover's first one its decoy.
          std::vector<std::size_t> tokens;
          if (block > 0) {
            for (std::size_t b = 0; b < m; b += block)
              for (int pass = 0; pass < 2; ++pass)
                for (std::size_t k = b; k < std::min(m, b + block); ++k) tokens.push_back(k);
          } else {
            for (std::size_t k = 0; k < 2 * m; ++k) tokens.push_back(k / 2);
            for (std::size_t k = tokens.size(); k > 1; --k)
              std::swap(tokens[k - 1], tokens[rng.below(k)]);
          }
          std::vector<bool> seen(m, false);
          std::vector<Move> moves;
          for (std::size_t k : tokens) {
            const std::size_t i = movers[k];
            if (seen[k])
              moves.push_back({h[i], scene.objects[i]});
            else
              moves.push_back({h[i], Shape::sphere(scene.objects[i].center + Vec3{0, 9e3, 0}, 1)});
            seen[k] = true;
          }
          g.update(moves);
          g.validate();
          for (std::size_t i = 0; i < scene.size(); ++i)
            ASSERT_EQ(g.shape(h[i]).center, scene.objects[i].center)
                << "object " << i << ", blocks of " << block << ", threads=" << t;
        }
        pairs = pairs_of(g);
        if (kOracleOnLargeScenes) {
          EXPECT_EQ(pairs, naive_pairs(scene.objects)) << "threads=" << t;
        }
      });
}

TEST(GridVerlet, UnboundedAndHugeObjects) {
  GridVerlet g;
  const double big = 1e300;
  g.insert(Shape::sphere({big, 0, 0}, 1), 0, Motion::fixed);
  g.insert(Shape::sphere({big, 0, 0}, 0), 1, Motion::fixed);
  g.insert(Shape::sphere({-big, 0, 0}, big), 2);
  g.insert(Shape::sphere({500, 500, 500}, 1e6), 3);
  g.insert(Shape::box({0, 0, 0}, {0, 0, 0}), 4, Motion::fixed);
  g.settle();
  g.validate();
  Naive n;
  n.insert(Shape::sphere({big, 0, 0}, 1), 0);
  n.insert(Shape::sphere({big, 0, 0}, 0), 1);
  n.insert(Shape::sphere({-big, 0, 0}, big), 2);
  n.insert(Shape::sphere({500, 500, 500}, 1e6), 3);
  n.insert(Shape::box({0, 0, 0}, {0, 0, 0}), 4);
  EXPECT_EQ(pairs_of(g), pairs_of(n));
  int hits = 0, expect = 0;
  g.query(Shape::sphere({big, 0, 0}, 0), [&](Handle) { ++hits; });
  n.query(Shape::sphere({big, 0, 0}, 0), [&](Handle) { ++expect; });
  EXPECT_EQ(hits, expect);
  EXPECT_GE(hits, 2);
}

TEST(GridVerlet, VisitorCanStopEarly) {
  GridVerlet g;
  for (int i = 0; i < 50; ++i) g.insert(Shape::sphere({0, 0, 0}, 1), static_cast<std::uint64_t>(i));
  int seen = 0;
  const QueryCost c = g.for_each_pair([&](Handle, Handle) { return ++seen < 5; });
  EXPECT_TRUE(c.stopped);
  EXPECT_EQ(seen, 5);
  seen = 0;
  const QueryCost q = g.query(Shape::sphere({0, 0, 0}, 1), [&](Handle) { return ++seen < 3; });
  EXPECT_TRUE(q.stopped);
  EXPECT_EQ(seen, 3);
}

TEST(GridVerlet, MemoryIsReported) {
  GridVerlet g;
  const std::size_t empty = g.memory_bytes();
  for (int i = 0; i < 1000; ++i)
    g.insert(Shape::sphere({i * 1.0, 0, 0}, 1), static_cast<std::uint64_t>(i));
  EXPECT_GT(g.memory_bytes(), empty + 1000 * sizeof(Shape));
}

TEST(GridVerlet, MemoryAfterABuildDoesNotDependOnHowTheObjectsCameIn) {
  // Inserted in one go, the objects wait on the loose list (up to an eighth
  // of them) between rebuilds; in small batches, each followed by a bulk
  // update, the list stays short. Once the grids hold them all, the two
  // hold the same memory: the loose list's build-time room is let go.
  const Scene scene = generate(Distribution::even, 20000, 8);
  auto held_after = [&](std::size_t batch) {
    GridVerlet g;
    for (std::size_t i = 0; i < scene.size(); ++i) {
      g.insert(scene.objects[i], i, Motion::fixed);
      if ((i + 1) % batch == 0) g.settle();
    }
    g.settle();
    return g.memory_bytes();
  };
  const double one_go = static_cast<double>(held_after(scene.size()));
  const double batches = static_cast<double>(held_after(500));
  EXPECT_NEAR(one_go, batches, 0.02 * batches);
}

TEST(GridVerlet, ConstCallsRunConcurrentlyOnThreads) {
  // Enough movers for the pair pass to split over the pool, whose buffers
  // two concurrent calls must not share (run under ThreadSanitizer in CI).
  broadphase::testing::const_calls_on_two_threads("grid-verlet:threads=2",
                                                  generate(Distribution::all_moving, 6000, 3));
}

TEST(GridVerlet, TheLevelGridBuildsFromItsItemsAndSaysWhereEachWent) {
  // detail::LevelGrid on its own: items of sizes over four decades, a few
  // outside the world and a few coincident; the same grid on one and three
  // threads; each item at the entry the build returns, in the cell of its
  // lower corner on a level that fits it; scans find what brute force finds.
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    Rng rng(seed);
    std::vector<detail::GridEntry> items(3000);
    for (std::uint32_t i = 0; i < items.size(); ++i) {
      const double c[3] = {rng.uniform(-50, 1050), rng.uniform(-50, 1050), rng.uniform(-50, 1050)};
      const double r = std::pow(10.0, rng.uniform(-2, 2));
      detail::GridEntry& e = items[i];
      for (int a = 0; a < 3; ++a) {
        e.lo[a] = static_cast<float>(i % 97 == 0 ? 500 : c[a] - r);
        e.hi[a] = static_cast<float>(i % 97 == 0 ? 501 : c[a] + r);
      }
      e.slot = i;
      e.gen = 1;
    }
    const detail::LevelGridSpec spec{{{0, 0, 0}, {1000, 1000, 1000}}, 1, 2};
    detail::LevelGrid grids[2];
    std::vector<std::uint32_t> at[2];
    for (int t = 0; t < 2; ++t) {
      const detail::WorkShares shares(t == 0 ? 1 : 3, 1);
      detail::LevelGrid::Scratch scratch;
      const std::span<const std::uint32_t> where = grids[t].build(items, spec, shares, scratch);
      at[t].assign(where.begin(), where.end());
    }
    ASSERT_EQ(at[0], at[1]) << "the build depends on the thread count";
    ASSERT_EQ(grids[0].cell_start, grids[1].cell_start);
    const detail::LevelGrid& g = grids[0];
    ASSERT_EQ(g.entries.size(), items.size());
    ASSERT_EQ(g.shapes.size(), items.size());
    std::vector<bool> taken(items.size(), false);
    for (std::size_t i = 0; i < items.size(); ++i) {
      const std::uint32_t k = at[0][i];
      ASSERT_LT(k, items.size());
      ASSERT_FALSE(taken[k]) << "two items at entry " << k;
      taken[k] = true;
      ASSERT_EQ(g.entries[k].slot, items[i].slot);
      ASSERT_TRUE(g.entries[k].overlaps(items[i].box()) && items[i].overlaps(g.entries[k].box()));
      std::size_t l = 0;
      while (k >= g.level_end(l)) ++l;
      const detail::GridLevel& lv = g.levels[l];
      EXPECT_LE(detail::extent_of(items[i].lo, items[i].hi), detail::LevelGrid::kFill * lv.reach);
      const std::uint32_t c = lv.cell_of(items[i].lo);
      EXPECT_TRUE(g.cell_start[c] <= k && k < g.cell_start[c + 1]) << "item " << i;
    }
    for (int q = 0; q < 200; ++q) {
      const float x = static_cast<float>(rng.uniform(0, 1000)),
                  y = static_cast<float>(rng.uniform(0, 1000)),
                  z = static_cast<float>(rng.uniform(0, 1000)),
                  w = static_cast<float>(rng.uniform(0, 80));
      const AabbF box{{x, y, z}, {x + w, y + w, z + w}};
      std::set<std::uint32_t> found, expect;
      g.scan(box, 0, detail::LevelGrid::kNoMinX, [&](std::uint32_t k) {
        EXPECT_TRUE(found.insert(g.entries[k].slot).second) << "an entry met twice";
        return true;
      });
      for (const detail::GridEntry& e : items)
        if (e.overlaps(box)) expect.insert(e.slot);
      ASSERT_EQ(found, expect) << "query " << q;
    }
  }
}

TEST(GridVerlet, TheOldNamesStillWork) {
  // `fast-grid` is an alias in the registry, listed as such, and FastGrid a
  // deprecated alias of the class.
  const Registry reg = Registry::library();
  ASSERT_NE(reg.find("fast-grid"), nullptr);
  EXPECT_EQ(reg.find("fast-grid"), reg.find("grid-verlet"));
  ASSERT_EQ(reg.aliases().size(), 1u);
  EXPECT_EQ(reg.aliases()[0].alias, "fast-grid");
  EXPECT_EQ(reg.aliases()[0].name, "grid-verlet");
  for (const StructureInfo& e : reg.entries()) EXPECT_NE(e.name, "fast-grid");
  EXPECT_NO_THROW(make_structure("fast-grid:threads=2"));
  EXPECT_THROW(make_structure("fast-grid:threads=65"), InvalidConfig);
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
  FastGrid old(Config{}, FastGridOptions{.threads = 2});
#pragma GCC diagnostic pop
  EXPECT_EQ(old.threads(), 2u);
}

}  // namespace
}  // namespace broadphase
