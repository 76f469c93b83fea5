// The lean path over the caller's arrays (arrays.hpp) against a brute-force
// oracle over overlaps(): one-shot, bipartite, query and the tracker, in
// every layout the interface takes, with random moves, teleports, resizes,
// appends and removals between the tracker's calls, on 1, 2 and 3 threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/arrays.hpp>
#include <broadphase/lab/scene.hpp>
#include <cmath>
#include <limits>
#include <set>

#include "arrays_testing.hpp"
#include "detail/array_grid.hpp"
#include "detail/pairs_by_first.hpp"
#include "detail/sphere_cells.hpp"
#include "testing.hpp"

namespace broadphase {
namespace {

using namespace arrays_testing;  // NOLINT(google-build-using-namespace)

// Under ThreadSanitizer the seed loops run a tenth of their seeds
// (testing::repeats): the threaded calls are the same, the worlds fewer.
TEST(Arrays, OneShotMatchesOracleInEveryLayoutOnEveryThreadCount) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(6)); ++seed) {
    for (World w : kWorlds) {
      Rng rng(seed * 1000 + static_cast<std::uint64_t>(w));
      const std::size_t n = 1 + rng.below(seed % 2 ? 300 : 2500);
      const std::vector<Shape> shapes = random_world(w, n, rng);
      for (Layout layout : kLayouts) {
        SCOPED_TRACE(::testing::Message() << "seed " << seed << " world " << name(w) << " n " << n
                                          << " layout " << name(layout));
        Storage st(shapes, layout);
        const auto want = oracle(st.objects);
        std::vector<IndexPair> first;
        for (unsigned threads : {1u, 2u, 3u}) {
          std::vector<IndexPair> got;
          ArrayOptions opt;
          opt.threads = threads;
          const ArrayCallStats stats = find_pairs(st.objects, got, opt);
          ASSERT_EQ(stats.pairs, got.size());
          for (const IndexPair& p : got) ASSERT_LT(p.i, p.j);
          ASSERT_EQ(sorted(got), want) << "threads " << threads;
          if (threads == 1)
            first = got;
          else
            ASSERT_EQ(got, first) << "order differs on " << threads << " threads";
        }
      }
    }
  }
}

TEST(Arrays, ScalarRadiusAndSortedOutput) {
  Rng rng(77);
  std::vector<Shape> shapes;
  for (int i = 0; i < 2000; ++i)
    shapes.push_back(
        Shape::sphere({rng.uniform(0, 60), rng.uniform(0, 60), rng.uniform(0, 60)}, 1.5));
  for (Layout layout : {Layout::aos_double, Layout::soa_float}) {
    Storage st(shapes, layout, true);
    ASSERT_EQ(st.objects.radius.stride, 0);
    ArrayOptions opt;
    opt.sorted = true;
    std::vector<IndexPair> got;
    find_pairs(st.objects, got, opt);
    EXPECT_EQ(got, oracle(st.objects)) << name(layout);
  }
}

// The tracker's store of quiet pairs against a model: the pairs in the order
// given, stably sorted by i where kept by it; random erasures; every range
// of positions.
TEST(Arrays, PairsByFirstMatchesItsModel) {
  int plain_sets = 0, by_first_sets = 0;
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    Rng rng(seed * 104729);
    const std::size_t n = 1 + rng.below(seed % 3 == 0 ? 5 : 300);
    std::set<std::pair<std::uint32_t, std::uint32_t>> taken;
    std::vector<IndexPair> given;
    const std::size_t want =
        seed % 5 == 0 ? 0 : (seed % 2 ? rng.below(2 * n) : 2 * n + rng.below(4 * n));
    for (std::size_t k = 0; k < want && n > 1; ++k) {
      auto a = static_cast<std::uint32_t>(rng.below(n)),
           b = static_cast<std::uint32_t>(rng.below(n));
      if (a == b || !taken.insert({std::min(a, b), std::max(a, b)}).second) continue;
      given.push_back({std::min(a, b), std::max(a, b)});
    }
    // Fewer than kByFirstShare pairs an object stay as given.
    bool plain = given.size() < detail::PairsByFirst::kByFirstShare * n;
    std::vector<IndexPair> model = given;
    if (!plain)
      std::stable_sort(model.begin(), model.end(),
                       [](const IndexPair& p, const IndexPair& q) { return p.i < q.i; });
    detail::PairsByFirst store;
    store.assign(given, n);
    EXPECT_EQ(store.plain(), plain || given.empty());
    (plain ? plain_sets : by_first_sets) += given.empty() ? 0 : 1;
    auto check = [&] {
      ASSERT_EQ(store.size(), model.size());
      std::vector<IndexPair> all;
      store.for_each([&](const IndexPair& q) { all.push_back(q); });
      ASSERT_EQ(all, model);
      for (int r = 0; r < 20; ++r) {
        const std::size_t b = rng.below(model.size() + 1);
        const std::size_t e = b + rng.below(model.size() - b + 1);
        std::vector<IndexPair> got, want_range(model.begin() + static_cast<std::ptrdiff_t>(b),
                                               model.begin() + static_cast<std::ptrdiff_t>(e));
        store.expand(b, e, got, [](const IndexPair&) { return true; });
        ASSERT_EQ(got, want_range) << "positions [" << b << ", " << e << ")";
      }
      if (model.empty()) {
        EXPECT_EQ(store.memory_bytes(), 0u);
      }
    };
    check();
    for (int round = 0; round < 3; ++round) {
      const auto gone = static_cast<std::uint32_t>(rng.below(n));
      auto drop = [&](const IndexPair& q) {
        return q.i == gone || q.j % 3 == std::uint32_t(round);
      };
      store.erase_if(drop);
      std::erase_if(model, drop);
      check();
      // Kept by i while still many (else as IndexPairs from then on).
      plain = plain || model.size() < detail::PairsByFirst::kByFirstShare * n;
      EXPECT_EQ(store.plain(), plain);
    }
  }
  EXPECT_GE(plain_sets, 5);
  EXPECT_GE(by_first_sets, 5);
}

TEST(Arrays, SpheresOfOneSizeTakeTheCellKernel) {
  // The kernel itself: taken only where it suits, and, over any split of
  // its cells, each pair once. (The calls above go through it for the
  // worlds `similar` and `lattice` and the shared radius.)
  for (std::uint64_t seed = 1; seed <= 12; ++seed) {
    Rng rng(seed);
    const World kinds[] = {World::similar, World::lattice, World::sizes, World::spheres};
    const World w = kinds[seed % 4];
    // (The lattice's 216 places at most about twice over: more crowd its cells.)
    const std::size_t n = w == World::lattice ? 100 + rng.below(300) : 200 + rng.below(3000);
    const std::vector<Shape> shapes = random_world(w, n, rng);
    for (Layout layout : {Layout::soa_double, Layout::aos_float, Layout::strided_double}) {
      SCOPED_TRACE(::testing::Message()
                   << "seed " << seed << " world " << name(w) << " layout " << name(layout));
      Storage st(shapes, layout);
      detail::SphereCells cells;
      ASSERT_TRUE(cells.build(st.objects));
      if (w == World::sizes) {
        EXPECT_GE(cells.level_count(), 2u);
      }
      std::vector<IndexPair> got;
      std::uint64_t tests = 0;
      for (std::size_t c = 0; c < cells.cell_count();) {
        const std::size_t e = std::min(cells.cell_count(), c + 1 + rng.below(50));
        tests += cells.pairs(c, e, got);
        c = e;
      }
      const auto want = oracle(st.objects);
      EXPECT_GE(tests, want.size());
      for (const IndexPair& p : got) ASSERT_LT(p.i, p.j);
      EXPECT_EQ(sorted(got), want);
    }
  }
  // Touching pairs (centres exactly a diameter apart along x) with the
  // first centre swept across the cell borders in steps of 2^-22: a cell
  // a hair narrower than the diameter loses some of them.
  {
    std::vector<Shape> shapes{Shape::sphere({0, 0, 0}, 0.5)};
    int row = 0;
    for (int k = 1; k <= 10; ++k)
      for (int j = -40; j <= 40; ++j, ++row) {
        const double a = k + j * 0x1p-22, y = 1.5 * (row % 5), z = 1.5 * (row / 5 % 5);
        shapes.push_back(Shape::sphere({a, y, z}, 0.5));
        shapes.push_back(Shape::sphere({a + 1, y, z}, 0.5));
      }
    Storage st(shapes, Layout::soa_double);
    detail::SphereCells cells;
    ASSERT_TRUE(cells.build(st.objects));
    std::vector<IndexPair> got;
    cells.pairs(0, cells.cell_count(), got);
    EXPECT_EQ(sorted(got), oracle(st.objects));
    // The probe of a sphere from outside the set (the tracker's movers
    // mode): the first of each touching pair in the cells, the second
    // probing them, finds exactly its partners.
    std::vector<std::uint32_t> firsts;
    for (std::uint32_t k = 1; k < shapes.size(); k += 2) firsts.push_back(k);
    detail::SphereCells half;
    ASSERT_TRUE(half.build(st.objects, firsts));
    std::vector<IndexPair> probed, expected;
    for (std::uint32_t k = 2; k < shapes.size(); k += 2) {
      const Shape& s = shapes[k];
      half.probe(s.center.x, s.center.y, s.center.z, s.half.x, [&](std::uint32_t j) {
        probed.push_back({std::min(j, k), std::max(j, k)});
      });
      for (std::uint32_t j : firsts)
        if (overlaps(s, shapes[j])) expected.push_back({std::min(j, k), std::max(j, k)});
    }
    EXPECT_EQ(sorted(probed), sorted(expected));
    EXPECT_GE(expected.size(), 800u);
  }
  // The same across grids: small spheres touching big ones (centres
  // exactly ri + rj apart along x), the big centres swept across the
  // coarser grid's borders: a probe that reaches a hair short loses some.
  {
    std::vector<Shape> shapes{Shape::sphere({0, 0, 0}, 0.25)};
    int row = 0;
    for (int k = 1; k <= 5; ++k)
      for (int j = -40; j <= 40; ++j, ++row) {
        const double a = 8 * k + j * 0x1p-20, y = 10.0 * (row % 3), z = 10.0 * (row / 3 % 3);
        shapes.push_back(Shape::sphere({a, y, z}, 4));
        shapes.push_back(Shape::sphere({a + 4.25, y, z}, 0.25));
      }
    Storage st(shapes, Layout::soa_double);
    detail::SphereCells cells;
    ASSERT_TRUE(cells.build(st.objects));
    EXPECT_EQ(cells.level_count(), 2u);
    std::vector<IndexPair> got;
    cells.pairs(0, cells.cell_count(), got);
    const auto want = oracle(st.objects);
    EXPECT_EQ(got.size(), want.size());
    EXPECT_EQ(sorted(got), want);
  }
  auto taken = [](std::vector<Shape> shapes) {
    Storage st(shapes, Layout::soa_double);
    return detail::SphereCells().build(st.objects);
  };
  Rng rng(9);
  std::vector<Shape> base = random_world(World::similar, 500, rng);
  EXPECT_TRUE(taken(base));
  EXPECT_FALSE(taken(std::vector<Shape>(base.begin(), base.begin() + 10)));  // few
  auto with = [&](Shape s) {
    auto v = base;
    v.push_back(s);
    return v;
  };
  EXPECT_TRUE(taken(with(Shape::sphere({1, 1, 1}, 40))));                     // a grid of its own
  EXPECT_FALSE(taken(with(Shape::box({1, 1, 1}, {1, 1, 1}))));                // a box
  EXPECT_FALSE(taken(with(Shape::sphere({1e9, 1, 1}, 1.5))));                 // not dense
  EXPECT_FALSE(taken(std::vector<Shape>(100, Shape::sphere({1, 2, 3}, 0))));  // all points
}

TEST(Arrays, ObjectsFarApartInSize) {
  // Points and a few objects 10^6 times larger: the big ones on coarse
  // levels, the points on fine ones; and one object of infinite reach.
  Rng rng(5);
  std::vector<Shape> shapes;
  for (int i = 0; i < 3000; ++i)
    shapes.push_back(Shape::sphere({rng.uniform(0, 1e3), rng.uniform(0, 1e3), rng.uniform(0, 1e3)},
                                   rng.uniform(0, 1e-3)));
  shapes.push_back(Shape::sphere({500, 500, 500}, 300));
  shapes.push_back(Shape::box({0, 0, 0}, {1e3, 1, 1e3}));
  shapes.push_back(Shape::sphere({1e30, 0, 0}, 1e30));
  for (Layout layout : {Layout::aos_float, Layout::soa_double}) {
    // Doubles only: a sphere beyond the float range, whose predicate overflows.
    if (layout == Layout::soa_double) shapes.push_back(Shape::sphere({-1e300, 0, 0}, 0x1p600));
    Storage st(shapes, layout);
    std::vector<IndexPair> got;
    find_pairs(st.objects, got);
    EXPECT_EQ(sorted(got), oracle(st.objects)) << name(layout);
  }
}

TEST(Arrays, BipartiteMatchesOracle) {
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    Rng rng(seed);
    const World w = kWorlds[seed % std::size(kWorlds)];
    const auto sa = random_world(w, 1 + rng.below(800), rng);
    const auto sb = random_world(World::mixed, rng.below(800), rng);
    SCOPED_TRACE(::testing::Message() << "seed " << seed << " world " << name(w));
    Storage a(sa, Layout::soa_double);
    Storage b(sb, Layout::aos_float);
    const auto want = oracle(a.objects, b.objects);
    std::vector<IndexPair> first;
    for (unsigned threads : {1u, 2u, 3u}) {
      std::vector<IndexPair> got;
      ArrayOptions opt;
      opt.threads = threads;
      find_pairs(a.objects, b.objects, got, opt);
      ASSERT_EQ(sorted(got), want);
      if (threads == 1)
        first = got;
      else
        ASSERT_EQ(got, first);
    }
  }
}

TEST(Arrays, QueryMatchesOracle) {
  Rng rng(11);
  const auto shapes = random_world(World::decades, 3000, rng);
  Storage st(shapes, Layout::aos_double);
  for (int q = 0; q < 200; ++q) {
    const Shape s = random_shape(q % 2 ? World::mixed : World::decades, rng, 60);
    std::vector<std::uint32_t> want;
    for (std::uint32_t i = 0; i < st.objects.count; ++i)
      if (overlaps(s, st.objects.shape(i))) want.push_back(i);
    EXPECT_EQ(query(st.objects, s), want) << "query " << q;
  }
  EXPECT_THROW(query(st.objects, Shape::sphere({0, 0, 0}, -1)), InvalidShape);
}

TEST(Arrays, SinkStopsEarlyAndSeesOneOrder) {
  Rng rng(3);
  const auto shapes = random_world(World::spheres, 30000, rng);
  Storage st(shapes, Layout::soa_double);
  for (unsigned threads : {1u, 3u}) {
    int chunks = 0;
    ArrayOptions opt;
    opt.threads = threads;
    const auto stats = find_pairs(
        st.objects,
        [&](std::span<const IndexPair> c) {
          EXPECT_FALSE(c.empty());
          return ++chunks < 2;
        },
        opt);
    EXPECT_TRUE(stats.stopped);
    EXPECT_EQ(chunks, 2);
  }
}

TEST(Arrays, EmptyAndSingle) {
  std::vector<Shape> none;
  Storage e(none, Layout::soa_double);
  std::vector<IndexPair> got;
  EXPECT_EQ(find_pairs(e.objects, got).pairs, 0u);
  std::vector<Shape> one{Shape::sphere({1, 2, 3}, 1)};
  Storage s(one, Layout::soa_double);
  EXPECT_EQ(find_pairs(s.objects, got).pairs, 0u);
  PairTracker t;
  EXPECT_EQ(t.find_pairs(e.objects, got).pairs, 0u);
  EXPECT_EQ(t.find_pairs(s.objects, got).pairs, 0u);
  EXPECT_TRUE(got.empty());
}

// Bad values are refused, naming the object; the tracker is unchanged.
TEST(Arrays, BadValuesNameTheIndexAndLeaveTheTrackerAsItWas) {
  Rng rng(21);
  auto shapes = random_world(World::mixed, 500, rng);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Case {
    const char* what;
    std::size_t index;
    Shape shape;
    const char* pattern;
  };
  const Case cases[] = {
      {"nan x", 17, Shape::sphere({nan, 1, 1}, 1), "[17]: x is nan"},
      {"inf z", 3, Shape::box({1, 1, inf}, {1, 1, 1}), "[3]: z is inf"},
      {"-inf y", 499, Shape::sphere({1, -inf, 1}, 1), "[499]: y is -inf"},
      {"negative radius", 42, Shape::sphere({1, 1, 1}, -0.5), "[42]: radius is negative"},
      {"nan radius", 0, Shape::sphere({1, 1, 1}, nan), "[0]: radius is nan"},
      {"negative half", 250, Shape::box({1, 1, 1}, {1, -1, 1}), "[250]: half_y is negative"},
      {"inf half", 251, Shape::box({1, 1, 1}, {1, 1, inf}), "[251]: half_z is inf"},
  };
  for (Layout layout : {Layout::soa_double, Layout::aos_float}) {
    Storage good(shapes, layout);
    PairTracker tracker;
    std::vector<IndexPair> before;
    tracker.find_pairs(good.objects, before);
    const std::size_t bytes = tracker.memory_bytes();
    for (const Case& c : cases) {
      SCOPED_TRACE(::testing::Message() << c.what << " " << name(layout));
      auto bad_shapes = shapes;
      bad_shapes[c.index] = c.shape;
      // Spheres and boxes are both present, so every column exists.
      Storage bad(bad_shapes, layout);
      for (int call = 0; call < 3; ++call) {
        try {
          std::vector<IndexPair> out;
          if (call == 0) find_pairs(bad.objects, out);
          if (call == 1) tracker.find_pairs(bad.objects, out);
          if (call == 2) query(bad.objects, Shape::sphere({0, 0, 0}, 1));
          ADD_FAILURE() << "no throw on call " << call;
        } catch (const InvalidObjects& e) {
          EXPECT_EQ(e.index(), c.index);
          EXPECT_NE(std::string(e.what()).find(c.pattern), std::string::npos) << e.what();
        }
      }
      EXPECT_EQ(tracker.memory_bytes(), bytes);
      EXPECT_NO_THROW(tracker.validate(good.objects));
      std::vector<IndexPair> again;
      const auto stats = tracker.find_pairs(good.objects, again);
      EXPECT_FALSE(stats.rebuilt);
      EXPECT_EQ(again, before);
    }
  }
  // Spheres only: the one-shot call reads them first in the sphere kernel,
  // which checks as it reads; the error is the same.
  {
    auto spheres = random_world(World::similar, 500, rng);
    for (const Case& c : cases) {
      if (!c.shape.is_sphere()) continue;
      SCOPED_TRACE(::testing::Message() << c.what << " (spheres only)");
      auto bad_shapes = spheres;
      bad_shapes[c.index] = c.shape;
      for (Layout layout : {Layout::soa_double, Layout::aos_float}) {
        Storage bad(bad_shapes, layout);
        try {
          std::vector<IndexPair> out;
          find_pairs(bad.objects, out);
          ADD_FAILURE() << "no throw";
        } catch (const InvalidObjects& e) {
          EXPECT_EQ(e.index(), c.index);
          EXPECT_NE(std::string(e.what()).find(c.pattern), std::string::npos) << e.what();
        }
      }
    }
  }
  // A kind byte that is neither 0 nor 1, a missing column, a bad change index.
  Storage st(shapes, Layout::soa_double);
  st.kinds[9] = 7;
  try {
    check_objects(st.objects);
    ADD_FAILURE();
  } catch (const InvalidObjects& e) {
    EXPECT_EQ(e.index(), 9u);
    EXPECT_NE(std::string(e.what()).find("objects[9]: kind is 7"), std::string::npos) << e.what();
  }
  st.kinds[9] = 0;
  Objects no_y = st.objects;
  no_y.y = {};
  EXPECT_THROW(check_objects(no_y), InvalidObjects);
  PairTracker t;
  std::vector<IndexPair> out;
  const std::uint32_t far_index[] = {500};
  EXPECT_THROW(t.find_pairs(st.objects, out, Changes::only(far_index)), InvalidObjects);
}

// The tracker over random frames: moves, teleports, resizes, kind changes,
// appends and removals (swap with the last), told everything or only what
// changed, on 1, 2 and 3 threads in lockstep.
// One call of each of three trackers (on 1, 2 and 3 threads) on the same
// objects: the oracle's pairs, the invariants after the call, one order on
// every thread count; `stats` is the first tracker's.
void call_on_each(PairTracker (&trackers)[3], const Objects& objects, const Changes& changes,
                  const std::vector<IndexPair>& want, ArrayCallStats& stats) {
  std::vector<IndexPair> first;
  for (unsigned t = 0; t < 3; ++t) {
    std::vector<IndexPair> got;
    const ArrayCallStats s = trackers[t].find_pairs(objects, got, changes);
    ASSERT_EQ(s.pairs, got.size());
    ASSERT_NO_THROW(trackers[t].validate(objects)) << "threads " << t + 1;
    ASSERT_EQ(sorted(got), want) << "threads " << t + 1;
    if (t == 0) {
      first = got;
      stats = s;
    } else {
      ASSERT_EQ(got, first) << "order differs on " << t + 1 << " threads";
    }
  }
}

TEST(Arrays, TrackerMatchesOracleUnderRandomChanges) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(12)); ++seed) {
    Rng rng(seed * 7919);
    const World w = kWorlds[seed % std::size(kWorlds)];
    const Layout layout = kLayouts[seed % std::size(kLayouts)];
    std::vector<Shape> shapes = random_world(w, 50 + rng.below(700), rng);
    const double world = 20.0 * std::cbrt(static_cast<double>(shapes.size()) / 10.0) + 1;
    ArrayOptions opt;
    opt.skin = seed % 3 == 0 ? 0 : rng.uniform(0.05, 2);
    PairTracker trackers[3] = {PairTracker(opt), PairTracker(opt), PairTracker(opt)};
    for (unsigned t = 0; t < 3; ++t) {
      ArrayOptions o = opt;
      o.threads = t + 1;
      trackers[t] = PairTracker(o);
    }
    for (int frame = 0; frame < 30; ++frame) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " world " << name(w) << " layout "
                                        << name(layout) << " frame " << frame);
      std::vector<std::uint32_t> changed;
      const std::size_t count_before = shapes.size();
      std::size_t lowest = shapes.size();  // the least count during the frame
      const int ops = frame == 0 ? 0 : static_cast<int>(rng.below(40));
      for (int k = 0; k < ops && !shapes.empty(); ++k) {
        const auto i = static_cast<std::uint32_t>(rng.below(shapes.size()));
        switch (rng.below(7)) {
          case 0:  // teleport
            shapes[i].center = random_shape(w, rng, world).center;
            changed.push_back(i);
            break;
          case 1: {  // resize (same kind)
            const Shape s = random_shape(w, rng, world);
            shapes[i].half = shapes[i].is_sphere() ? Vec3{s.half.x, s.half.x, s.half.x} : s.half;
            changed.push_back(i);
            break;
          }
          case 2:  // a new shape, maybe of the other kind
            shapes[i] = random_shape(w, rng, world);
            changed.push_back(i);
            break;
          case 3:  // append
            shapes.push_back(random_shape(w, rng, world));
            break;
          case 4:  // remove by moving the last into its place
            shapes[i] = shapes.back();
            shapes.pop_back();
            lowest = std::min(lowest, shapes.size());
            if (i < shapes.size()) changed.push_back(i);
            break;
          default: {  // a small move
            const Vec3 d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
            shapes[i].center = shapes[i].center + d * rng.uniform(0, 2);
            changed.push_back(i);
          }
        }
      }
      // Removals may have shrunk the set below listed indices; an index
      // removed and then appended again holds a new object, which the caller
      // lists (the count alone cannot tell the tracker).
      std::erase_if(changed, [&](std::uint32_t i) { return i >= shapes.size(); });
      for (std::size_t i = lowest; i < std::min(shapes.size(), count_before); ++i)
        changed.push_back(static_cast<std::uint32_t>(i));
      Storage st(shapes, layout);
      const auto want = oracle(st.objects);
      // Odd seeds say "everything" rarely, so that objects become quiet
      // and some are woken by a listed change or by "everything".
      const bool tell_all = rng.below(seed % 2 ? 16 : 3) == 0;
      ArrayCallStats stats;
      ASSERT_NO_FATAL_FAILURE(
          call_on_each(trackers, st.objects,
                       tell_all ? Changes::everything() : Changes::only(changed), want, stats));
    }
  }
}

// Movers mode: spheres of which about one in ten moves each frame (listed),
// with quiet ones woken, movers stopping, teleports, resizes, a sphere
// turned into a box and back, appends, removals and "everything" now and
// then: the oracle's pairs on every frame, the same order on 1 to 3
// threads, the invariants after every call, and the mode taken on most
// frames (so that the checks above are of it).
// Movers in movers mode running through rows of quiet spheres, head on, in
// small steps (a fortieth of their skin and more): each sphere begins to
// touch its mover at some step, at every distance from where the mover's
// list of quiet candidates was made, so a list kept past its reach misses a
// pair (a list kept to 0.97 of its reach's distance fails here).
TEST(Arrays, MoverListsHoldToTheirReach) {
  for (const double speed : {0.006, 0.03}) {
    SCOPED_TRACE(::testing::Message() << "step " << speed);
    Rng rng(11);
    std::vector<Shape> shapes;
    constexpr int kRows = 16;
    for (int row = 0; row < kRows; ++row) {
      double x = rng.uniform(0, 3);
      for (int k = 0; k < 10; ++k, x += rng.uniform(2.5, 5))
        shapes.push_back(Shape::sphere({x, 0, 10.0 * row}, 1));
    }
    std::vector<std::uint32_t> movers;
    for (int row = 0; row < kRows; ++row) {
      movers.push_back(static_cast<std::uint32_t>(shapes.size()));
      shapes.push_back(Shape::sphere({-3, 0, 10.0 * row}, 1));
    }
    PairTracker tracker;
    std::vector<IndexPair> got;
    tracker.find_pairs(Storage(shapes, Layout::soa_double).objects, got);
    std::uint64_t renewed = 0, calls = 0;
    for (int step = 0; shapes[movers[0]].center.x < 20; ++step) {
      for (const std::uint32_t i : movers) shapes[i].center.x += speed;
      Storage st(shapes, Layout::soa_double);
      got.clear();
      const auto stats = tracker.find_pairs(st.objects, got, Changes::only(movers));
      ASSERT_EQ(sorted(got), oracle(st.objects)) << "step " << step;
      if (step % 16 == 0) {
        ASSERT_NO_THROW(tracker.validate(st.objects)) << "step " << step;
      }
      if (stats.movers) {
        ++calls;
        renewed += stats.renewed;
      }
    }
    EXPECT_GT(calls, 700u);
    EXPECT_LT(renewed * 4, calls * kRows);  // most movers test their lists
  }
}

TEST(Arrays, TrackerMoversModeMatchesOracle) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(10)); ++seed) {
    Rng rng(seed * 104729);
    // (Not the lattice: its cells are too crowded for the mode.)
    const World kinds[] = {World::spheres, World::similar, World::sizes};
    const World w = kinds[seed % std::size(kinds)];
    const Layout layout = kLayouts[seed % std::size(kLayouts)];
    std::vector<Shape> shapes = random_world(w, 300 + rng.below(1500), rng);
    const double world = 20.0 * std::cbrt(static_cast<double>(shapes.size()) / 10.0) + 1;
    std::vector<std::uint32_t> movers;
    for (std::uint32_t i = 0; i < shapes.size(); ++i)
      if (rng.below(10) == 0) movers.push_back(i);
    PairTracker trackers[3];
    for (unsigned t = 0; t < 3; ++t) {
      ArrayOptions o;
      o.threads = t + 1;
      trackers[t] = PairTracker(o);
    }
    int in_mode = 0;
    const int frames = 40;
    for (int frame = 0; frame < frames; ++frame) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " world " << name(w) << " layout "
                                        << name(layout) << " frame " << frame);
      std::vector<std::uint32_t> changed;
      bool tell_all = false;
      for (std::uint32_t i : movers)
        if (i < shapes.size()) {
          const Vec3 d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
          shapes[i].center = shapes[i].center + d * rng.uniform(0, 3);
          changed.push_back(i);
        }
      const auto pick = [&] { return static_cast<std::uint32_t>(rng.below(shapes.size())); };
      switch (frame == 0 ? 99 : rng.below(24)) {
        case 0: {  // wake a few quiet ones
          for (int k = 0; k < 5; ++k) {
            const std::uint32_t i = pick();
            shapes[i].center = shapes[i].center + Vec3{0.5, -0.25, 0.125};
            changed.push_back(i);
          }
          break;
        }
        case 1: {  // teleports and a resize
          const std::uint32_t i = pick(), j = pick();
          shapes[i].center = random_shape(w, rng, world).center;
          shapes[j].half = Vec3{1, 1, 1} * rng.uniform(0, 6);
          changed.insert(changed.end(), {i, j});
          break;
        }
        case 2: {  // a sphere turns into a box, and back a few frames later
          const std::uint32_t i = pick();
          shapes[i] = Shape::box(shapes[i].center, {1, 2, 0.5});
          changed.push_back(i);
          break;
        }
        case 3:  // append
          shapes.push_back(random_shape(w, rng, world));
          break;
        case 4: {  // remove by moving the last into its place
          const std::uint32_t i = pick();
          shapes[i] = shapes.back();
          shapes.pop_back();
          if (i < shapes.size()) changed.push_back(i);
          break;
        }
        case 5:  // half the movers stop
          movers.resize(movers.size() / 2);
          break;
        case 6:
          tell_all = rng.below(3) == 0;
          break;
        default:
          break;
      }
      for (Shape& s : shapes)  // boxes turn back into spheres after a while
        if (!s.is_sphere() && rng.below(4) == 0) {
          s = Shape::sphere(s.center, 1);
          changed.push_back(static_cast<std::uint32_t>(&s - shapes.data()));
        }
      std::erase_if(changed, [&](std::uint32_t i) { return i >= shapes.size(); });
      Storage st(shapes, layout);
      const auto want = oracle(st.objects);
      ArrayCallStats stats;
      ASSERT_NO_FATAL_FAILURE(
          call_on_each(trackers, st.objects,
                       tell_all ? Changes::everything() : Changes::only(changed), want, stats));
      in_mode += stats.movers ? 1 : 0;
    }
    EXPECT_GE(in_mode, frames / 3)
        << "seed " << seed << ": movers mode taken on " << in_mode << " of " << frames << " frames";
  }
}

// Many frames of small motion: the skin is reused (not every call rebuilds).
TEST(Arrays, TrackerReusesItsWorkUnderSmallMotion) {
  Rng rng(8);
  std::vector<Shape> shapes = random_world(World::spheres, 3000, rng);
  PairTracker tracker;
  int rebuilds = 0;
  for (int frame = 0; frame < 20; ++frame) {
    for (std::size_t i = 0; i < shapes.size(); i += 5)
      shapes[i].center.x += 0.001;  // far inside any skin
    Storage st(shapes, Layout::soa_double);
    std::vector<IndexPair> got;
    rebuilds += tracker.find_pairs(st.objects, got).rebuilt ? 1 : 0;
    ASSERT_EQ(sorted(got), oracle(st.objects)) << "frame " << frame;
  }
  EXPECT_EQ(rebuilds, 1);
  tracker.clear();
  EXPECT_LT(tracker.memory_bytes(), 1000u);
}

// Objects that stay unchanged over calls that list the changes become
// quiet: their pairs are handed over without a scan. A quiet object that
// moves a little (inside its skin) into a new overlap with another quiet
// one is woken, and the pair is found; so is a pair that stops touching.
// Spheres alone take movers mode; one box among them keeps them on the
// index, whose quiet objects are checked the same way.
TEST(Arrays, QuietObjectsWakeWhenTheCallerChangesThem) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(6)); ++seed) {
    Rng rng(seed * 613);
    std::vector<Shape> shapes = random_world(World::spheres, 1500, rng);
    for (Shape& s : shapes) s.half = {0.5, 0.5, 0.5};
    const bool on_index = seed % 2 == 0;
    if (on_index) shapes.back() = Shape::box(shapes.back().center, {0.5, 0.5, 0.5});
    int in_mode = 0;
    std::vector<std::uint32_t> movers;
    for (std::uint32_t i = 0; i < shapes.size(); i += 10) movers.push_back(i);
    ArrayOptions opt;
    opt.skin = 1;  // 0.5: nudges of 0.01 stay inside
    opt.threads = static_cast<unsigned>(seed + 1) / 2;
    PairTracker tracker(opt);
    std::uint64_t most_quiet = 0, woken = 0;
    for (int frame = 0; frame < 40; ++frame) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " frame " << frame);
      std::vector<std::uint32_t> changed = movers;
      for (std::uint32_t i : movers) shapes[i].center.x += 0.01;
      if (frame >= 20)
        for (int k = 0; k < 30; ++k) {  // nudge objects that were quiet
          const auto i = static_cast<std::uint32_t>(rng.below(shapes.size()));
          if (i % 10 == 0) continue;
          const Vec3 d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
          shapes[i].center = shapes[i].center + d * 0.05;
          changed.push_back(i);
        }
      Storage st(shapes, seed % 2 ? Layout::soa_double : Layout::aos_float);
      std::vector<IndexPair> got;
      const auto stats = tracker.find_pairs(
          st.objects, got, frame == 30 ? Changes::everything() : Changes::only(changed));
      ASSERT_NO_THROW(tracker.validate(st.objects));
      ASSERT_EQ(sorted(got), oracle(st.objects));
      most_quiet = std::max(most_quiet, stats.quiet);
      woken += stats.woken;
      in_mode += stats.movers ? 1 : 0;
    }
    EXPECT_GE(most_quiet, shapes.size() / 2);
    EXPECT_GT(woken, 0u);
    if (on_index)
      EXPECT_EQ(in_mode, 0);
    else
      EXPECT_GE(in_mode, 30);
  }
}

// A few objects leave their skin on every call: they are renewed alone
// (no rebuild), and the candidates stay complete and exact call after call
// (validate checks the renewed objects' loose pairs and the kept grid).
// An object far larger than the median keeps a skin of a share of its own
// size: a slow drift of a few skins of the median does not renew it (its
// renewal would query every finer level), and the pairs stay exact.
// Motion that outruns the skin: instead of building its index again, the
// tracker searches afresh for a few calls, holding nothing, then builds.
TEST(Arrays, TrackerSearchesAfreshWhenMotionOutrunsTheSkin) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    Rng rng(seed * 7919);
    const World w = seed % 2 ? World::similar : World::spheres;
    std::vector<Shape> shapes = random_world(w, 500 + rng.below(1500), rng);
    const double world = 20.0 * std::cbrt(static_cast<double>(shapes.size()) / 10.0) + 1;
    PairTracker tracker;
    int afresh = 0, rebuilt = 0, holding_nothing = 0;
    for (int frame = 0; frame < 30; ++frame) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " frame " << frame);
      std::vector<std::uint32_t> all;
      if (frame > 0)
        for (std::uint32_t i = 0; i < shapes.size(); ++i) {
          shapes[i].center = random_shape(w, rng, world).center;  // every one jumps
          all.push_back(i);
        }
      Storage st(shapes, Layout::soa_double);
      std::vector<IndexPair> got;
      const auto stats = tracker.find_pairs(st.objects, got,
                                            seed > 2 ? Changes::only(all) : Changes::everything());
      ASSERT_NO_THROW(tracker.validate(st.objects));
      ASSERT_EQ(sorted(got), oracle(st.objects));
      ASSERT_EQ(stats.pairs, got.size());
      if (stats.afresh) {
        ++afresh;
        holding_nothing += tracker.memory_bytes() < 1000u ? 1 : 0;
        EXPECT_FALSE(stats.rebuilt);
      }
      rebuilt += stats.rebuilt ? 1 : 0;
    }
    // Built after the first call and after each run of afresh calls. The
    // calls afresh hold nothing, but for the first after each build (the
    // first call, and the one after each run), which keeps its cells and
    // pairs for a next call that would list few changes.
    EXPECT_GE(afresh, 20);
    EXPECT_GE(rebuilt, 2);
    EXPECT_EQ(afresh + rebuilt, 30);
    EXPECT_GE(holding_nothing, afresh - rebuilt);
  }
  // Crowded cells (about five spheres on each of the lattice's places, too few
  // for the kernel to refuse them, too many for runs of calls afresh): the
  // index is built again after each call afresh, which is only the one
  // after a build (its pairs kept for movers mode, which takes sets this
  // crowded), never two in a row.
  Rng rng(3);
  std::vector<Shape> shapes = random_world(World::lattice, 1000, rng);
  PairTracker tracker;
  bool last_afresh = false;
  for (int frame = 0; frame < 6; ++frame) {
    SCOPED_TRACE(::testing::Message() << "lattice frame " << frame);
    for (Shape& s : shapes) s.center = random_shape(World::lattice, rng, 0).center;
    Storage st(shapes, Layout::soa_double);
    std::vector<IndexPair> got;
    const auto stats = tracker.find_pairs(st.objects, got);
    EXPECT_FALSE(stats.afresh && last_afresh);
    EXPECT_TRUE(stats.afresh || stats.rebuilt);
    last_afresh = stats.afresh;
    ASSERT_EQ(sorted(got), oracle(st.objects));
  }
}

TEST(Arrays, LargeObjectsKeepASkinOfTheirOwnSize) {
  Rng rng(31);
  std::vector<Shape> shapes = random_world(World::spheres, 2000, rng);
  for (Shape& s : shapes) s.half = {0.5, 0.5, 0.5};  // the median size
  const auto big = static_cast<std::uint32_t>(shapes.size());
  shapes.push_back(Shape::sphere({10, 10, 10}, 100));
  shapes.push_back(Shape::box({-500, -500, -500}, {0.5, 0.5, 0.5}));  // the index, not movers mode
  PairTracker tracker;  // skin 0.25 of the median half-extent: 0.125
  std::vector<IndexPair> got;
  tracker.find_pairs(Storage(shapes, Layout::soa_double).objects, got);
  for (int frame = 1; frame <= 4; ++frame) {
    shapes[big].center.x += 1;  // 8 median skins a frame, 1% of its own size
    Storage st(shapes, Layout::soa_double);
    got.clear();
    const std::vector<std::uint32_t> moved{big};
    const auto stats = tracker.find_pairs(st.objects, got, Changes::only(moved));
    EXPECT_EQ(stats.renewed, 0u) << "frame " << frame;
    EXPECT_FALSE(stats.movers);
    ASSERT_EQ(sorted(got), oracle(st.objects)) << "frame " << frame;
    ASSERT_NO_THROW(tracker.validate(st.objects));
  }
}

TEST(Arrays, TrackerRenewsObjectsThatLeaveTheirSkin) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(4)); ++seed) {
    Rng rng(seed * 104729);
    const World w =
        seed % 3 == 0 ? World::mixed : (seed % 3 == 1 ? World::spheres : World::decades);
    std::vector<Shape> shapes = random_world(w, 300 + rng.below(600), rng);
    const double world = 20.0 * std::cbrt(static_cast<double>(shapes.size()) / 10.0) + 1;
    // One box among the spheres keeps them on the index (movers mode, with
    // nothing to renew, takes sets of spheres only).
    if (w == World::spheres) shapes.push_back(Shape::box({1, 1, 1}, {0.5, 0.5, 0.5}));
    ArrayOptions opt;
    opt.skin = seed % 2 ? 0 : 0.5;
    PairTracker one(opt);
    opt.threads = 2;
    PairTracker two(opt);
    std::uint64_t renewed = 0;
    int rebuilds = 0;
    for (int frame = 0; frame < 60; ++frame) {
      SCOPED_TRACE(::testing::Message()
                   << "seed " << seed << " world " << name(w) << " frame " << frame);
      std::vector<std::uint32_t> changed;
      if (frame > 0) {
        const int leaving = 1 + static_cast<int>(rng.below(6));
        for (int k = 0; k < leaving; ++k) {  // far past any skin, or a jump
          const auto i = static_cast<std::uint32_t>(rng.below(shapes.size()));
          if (rng.below(4) == 0)
            shapes[i].center = random_shape(w, rng, world).center;
          else
            shapes[i].center.x += rng.uniform(-1, 1) * 3 * shapes[i].max_half() + 1;
          changed.push_back(i);
        }
        for (int k = 0; k < 20; ++k) {  // steady drift of a few, listed twice at times
          const auto i =
              static_cast<std::uint32_t>(rng.below(std::min<std::size_t>(shapes.size(), 64)));
          shapes[i].center.y += 0.05;
          changed.push_back(i);
        }
      }
      Storage st(shapes, seed % 2 ? Layout::soa_double : Layout::aos_float);
      const auto want = oracle(st.objects);
      const bool tell_all = frame == 0 || rng.below(4) == 0;
      const Changes ch = tell_all ? Changes::everything() : Changes::only(changed);
      std::vector<IndexPair> got1, got2;
      const auto s1 = one.find_pairs(st.objects, got1, ch);
      const auto s2 = two.find_pairs(st.objects, got2, ch);
      ASSERT_NO_THROW(one.validate(st.objects));
      ASSERT_NO_THROW(two.validate(st.objects));
      ASSERT_EQ(sorted(got1), want);
      ASSERT_EQ(got2, got1) << "order differs on 2 threads";
      ASSERT_EQ(s2.renewed, s1.renewed);
      rebuilds += s1.rebuilt ? 1 : 0;
      renewed += s1.renewed;
    }
    EXPECT_GT(renewed, 40u) << "seed " << seed;
    // The first call, up to two from objects leaving, and up to three from
    // "everything" calls that woke quiet objects (made quiet again only
    // after 2, 8, then 32 listed calls in a row).
    EXPECT_LE(rebuilds, 6) << "seed " << seed;
  }
}

// Reads a scene's objects in place: SoA columns kept by the test, updated
// by the contract's motion frame after frame.
struct SceneArrays {
  std::vector<double> x, y, z, r, hx, hy, hz;
  std::vector<std::uint8_t> kind;
  void load(const Scene& s) {
    const std::size_t n = s.size();
    for (auto* v : {&x, &y, &z, &r, &hx, &hy, &hz}) v->resize(n);
    kind.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Shape& o = s.objects[i];
      x[i] = o.center.x, y[i] = o.center.y, z[i] = o.center.z;
      r[i] = o.half.x, hx[i] = o.half.x, hy[i] = o.half.y, hz[i] = o.half.z;
      kind[i] = o.is_sphere() ? 0 : 1;
    }
  }
  Objects view() const {
    Objects o;
    o.count = x.size();
    o.x = Column::of(x.data()), o.y = Column::of(y.data()), o.z = Column::of(z.data());
    o.radius = Column::of(r.data());
    o.half_x = Column::of(hx.data()), o.half_y = Column::of(hy.data());
    o.half_z = Column::of(hz.data());
    o.kind = kind.data();
    return o;
  }
};

TEST(Arrays, ReferenceScenesFrameByFrame) {
  const auto scenes = testing::reference_scenes();
  ASSERT_GE(scenes.size(), 10u);
  for (const auto& ref : scenes) {
    for (int variant = 0; variant < 3; ++variant) {
      SCOPED_TRACE(::testing::Message() << ref.name << " variant " << variant);
      Scene scene = read_scene(ref.scene_path);
      std::vector<std::uint32_t> movers;
      for (std::uint32_t i = 0; i < scene.size(); ++i)
        if (scene.is_moving(i)) movers.push_back(i);
      ArrayOptions opt;
      opt.threads = variant == 2 ? 3 : 1;
      PairTracker tracker(opt);
      SceneArrays arrays;
      for (std::size_t f = 0; f < ref.expected.size(); ++f) {
        if (f > 0) step(scene);
        arrays.load(scene);
        FrameDigest d;
        tracker.find_pairs(
            arrays.view(),
            [&](std::span<const IndexPair> c) {
              for (const IndexPair& p : c) d.add(p.i, p.j);
              return true;
            },
            variant == 1 || f == 0 ? Changes::everything() : Changes::only(movers));
        ASSERT_EQ(d.pairs, ref.expected[f].pairs) << "frame " << f;
        ASSERT_EQ(hex16(d.hash), hex16(ref.expected[f].hash)) << "frame " << f;
      }
    }
  }
}

TEST(Arrays, GeneratedScenesMatchBruteForce) {
  for (Distribution dist : kAllDistributions) {
    SCOPED_TRACE(to_string(dist));
    Scene scene = generate(dist, 1500, 4);
    std::vector<std::uint32_t> movers;
    for (std::uint32_t i = 0; i < scene.size(); ++i)
      if (scene.is_moving(i)) movers.push_back(i);
    PairTracker tracker;
    SceneArrays arrays;
    for (int f = 0; f < 8; ++f) {
      if (f > 0) step(scene);
      arrays.load(scene);
      FrameDigest d;
      tracker.find_pairs(
          arrays.view(),
          [&](std::span<const IndexPair> c) {
            for (const IndexPair& p : c) d.add(p.i, p.j);
            return true;
          },
          f == 0 ? Changes::everything() : Changes::only(movers));
      ASSERT_EQ(d, testing::brute_force(scene.objects)) << "frame " << f;
    }
  }
}

// A tracker's compactions build a new grid with the last grid's finest cell
// as the least (ArrayGrid::build's min_cell). Given back its own finest
// cell, the grid must keep it exactly: rounding it up again raised the
// cells by a quarter octave at every compaction, and 300 frames of a
// moving workload (20% of 100 000 spheres moving) went from 17 to 900 ms a
// call as the cells filled.
TEST(ArrayGrid, KeepsTheFinestCellItIsGiven) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Rng rng(seed);
    const std::size_t n = 1 + rng.below(5000);
    const double spread = std::exp2(rng.uniform(0, 12));  // sizes over up to 12 octaves
    std::vector<AabbF> boxes(n);
    for (AabbF& b : boxes) {
      const double h = 0.001 * std::exp2(-rng.uniform(0, std::log2(spread)));
      for (int a = 0; a < 3; ++a) {
        const double c = rng.uniform();
        b.lo[a] = round_down(c - h);
        b.hi[a] = round_up(c + h);
      }
    }
    SCOPED_TRACE(::testing::Message() << "seed " << seed << " n " << n << " spread " << spread);
    detail::ArrayGrid grid;
    grid.build(boxes);
    const double first = grid.base_cell();
    ASSERT_GT(first, 0);
    for (int compaction = 0; compaction < 10; ++compaction) {
      detail::ArrayGrid next;
      next.build(boxes, 1, grid.base_cell());
      ASSERT_EQ(next.base_cell(), first) << "after " << compaction + 1 << " builds";
      grid = std::move(next);
    }
    // A least cell wider than the sample's gives that cell.
    detail::ArrayGrid wide;
    wide.build(boxes, 1, 3 * first);
    EXPECT_EQ(wide.base_cell(), 3 * first);
  }
}

}  // namespace
}  // namespace broadphase
