// The lean path's tracker (PairTracker, arrays.hpp) against a brute-force
// oracle over overlaps(): random moves, teleports, resizes, kind changes,
// appends and removals between calls, on 1, 2 and 3 threads; movers mode,
// its lists, quiet objects, calls afresh and renewals.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <set>
#include <utility>

#include "arrays_testing.hpp"
#include "testing.hpp"

namespace broadphase {
namespace {

using namespace arrays_testing;  // NOLINT(google-build-using-namespace)

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

// Trackers on 1, 2 and 3 threads, otherwise with `options`.
void on_threads(PairTracker (&trackers)[3], ArrayOptions options = {}) {
  for (unsigned t = 0; t < 3; ++t) {
    options.threads = t + 1;
    trackers[t] = PairTracker(options);
  }
}

// About one of every k of n objects, drawn at random, increasing.
std::vector<std::uint32_t> pick_movers(Rng& rng, std::size_t n, std::uint64_t k) {
  std::vector<std::uint32_t> movers;
  for (std::uint32_t i = 0; i < n; ++i)
    if (rng.below(k) == 0) movers.push_back(i);
  return movers;
}

// `rows` rows of `per_row` quiet spheres along x, 2.5 to 5 apart, 10 apart
// in z, then one mover a row at x = -3 (their indices in `movers`); with
// `jitter`, the quiet ones off the row's line by up to 1 in y and of radius
// 0.8 to 1.2, else on it and of radius 1.
std::vector<Shape> rows_with_movers(Rng& rng, int rows, int per_row, bool jitter,
                                    std::vector<std::uint32_t>& movers) {
  std::vector<Shape> shapes;
  for (int row = 0; row < rows; ++row) {
    double x = rng.uniform(0, 3);
    for (int k = 0; k < per_row; ++k, x += rng.uniform(2.5, 5)) {
      const double y = jitter ? rng.uniform(-1, 1) : 0;
      const double r = jitter ? rng.uniform(0.8, 1.2) : 1;
      shapes.push_back(Shape::sphere({x, y, 10.0 * row}, r));
    }
  }
  movers.clear();
  for (int row = 0; row < rows; ++row) {
    movers.push_back(static_cast<std::uint32_t>(shapes.size()));
    shapes.push_back(Shape::sphere({-3, 0, 10.0 * row}, 1));
  }
  return shapes;
}

// Trackers on 1 to 3 threads told everything once, then `steps` calls
// listing `movers`, each after `move(step)`: the oracle's pairs on every
// call, one order on every thread count, the invariants after every call.
// Returns the renewals and the movers calls of the steps in [from, to).
template <class Move>
std::pair<std::uint64_t, std::uint64_t> renewals_of(std::vector<Shape>& shapes,
                                                    const std::vector<std::uint32_t>& movers,
                                                    int steps, int from, int to, Move&& move) {
  PairTracker trackers[3];
  on_threads(trackers);
  ArrayCallStats stats;
  {
    Storage st(shapes, Layout::soa_double);
    call_on_each(trackers, st.objects, Changes::everything(), oracle(st.objects), stats);
  }
  std::uint64_t renewed = 0, calls = 0;
  for (int step = 0; step < steps; ++step) {
    move(step);
    Storage st(shapes, Layout::soa_double);
    SCOPED_TRACE(::testing::Message() << "step " << step);
    call_on_each(trackers, st.objects, Changes::only(movers), oracle(st.objects), stats);
    if (step >= from && step < to && stats.movers) {
      ++calls;
      renewed += stats.renewed;
    }
  }
  return {renewed, calls};
}

// The tracker over random frames: moves, teleports, resizes, kind changes,
// appends and removals (swap with the last), told everything or only what
// changed, on 1, 2 and 3 threads in lockstep.
TEST(Arrays, TrackerMatchesOracleUnderRandomChanges) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(12)); ++seed) {
    Rng rng(seed * 7919);
    const World w = kWorlds[seed % std::size(kWorlds)];
    const Layout layout = kLayouts[seed % std::size(kLayouts)];
    std::vector<Shape> shapes = random_world(w, 50 + rng.below(700), rng);
    const double world = 20.0 * std::cbrt(static_cast<double>(shapes.size()) / 10.0) + 1;
    ArrayOptions opt;
    opt.skin = seed % 3 == 0 ? 0 : rng.uniform(0.05, 2);
    PairTracker trackers[3];
    on_threads(trackers, opt);
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

// The tracker with filter columns: objects move (listed), and masks change
// between calls without being listed (the filters are read at every
// hand-over), in worlds that take the index and in movers mode.
TEST(Arrays, TrackerWithFilterColumnsMatchesOracle) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(4)); ++seed) {
    Rng rng(seed * 6151);
    const World w = kWorlds[seed % std::size(kWorlds)];
    const int layers = seed % 3 == 0 ? 0 : (seed % 3 == 1 ? 4 : 16);
    std::vector<Shape> shapes = random_world(w, 200 + rng.below(600), rng);
    FilterColumns fc(shapes.size(), layers, rng);
    std::vector<std::uint32_t> movers = pick_movers(rng, shapes.size(), 10);
    PairTracker trackers[3];
    on_threads(trackers);
    for (int frame = 0; frame < 15; ++frame) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " world " << name(w) << " layers "
                                        << layers << " frame " << frame);
      std::vector<std::uint32_t> changed;
      for (std::uint32_t i : movers) {
        const Vec3 d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
        shapes[i].center = shapes[i].center + d * rng.uniform(0, 2);
        changed.push_back(i);
      }
      const int flips = frame == 0 ? 0 : static_cast<int>(rng.below(12));
      for (int k = 0; k < flips; ++k) fc.draw(rng.below(shapes.size()), layers, rng);
      Storage st(shapes, Layout::soa_double);
      fc.attach(st.objects);
      const auto want = oracle(st.objects);
      const bool tell_all = frame == 0 || rng.below(8) == 0;
      ArrayCallStats stats;
      ASSERT_NO_FATAL_FAILURE(
          call_on_each(trackers, st.objects,
                       tell_all ? Changes::everything() : Changes::only(changed), want, stats));
    }
  }
}

// Movers in movers mode running through rows of quiet spheres, head on, in
// small steps (a fortieth of their skin and more): each sphere begins to
// touch its mover at some step, at every distance from where the mover's
// list of quiet candidates was made, so a list kept past its reach misses a
// pair (a list kept to 0.97 of its reach's distance fails here).
TEST(Arrays, MoverListsHoldToTheirReach) {
  for (const double speed : {0.006, 0.03}) {
    SCOPED_TRACE(::testing::Message() << "step " << speed);
    Rng rng(11);
    constexpr int kRows = 16;
    std::vector<std::uint32_t> movers;
    std::vector<Shape> shapes = rows_with_movers(rng, kRows, 10, false, movers);
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

// Movers in steady motion along rows of quiet spheres, on 1 to 3 threads:
// a list is put ahead of its mover (kListAhead), so that the mover crosses
// it whole before renewing it, about every 24 calls at this speed rather
// than every 12 of a centred list; then the movers turn back (their lists
// lie the wrong way) and go on at a random speed and direction each call.
// The oracle's pairs on every call throughout, the invariants after every
// call, one order on every thread count.
TEST(Arrays, MoverListsLieAheadOfSteadyMovers) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(2)); ++seed) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    Rng rng(seed * 6007);
    constexpr int kRows = 12;
    std::vector<std::uint32_t> movers;
    std::vector<Shape> shapes = rows_with_movers(rng, kRows, 12, true, movers);
    const auto [renewed, calls] = renewals_of(shapes, movers, 700, 40, 400, [&](int step) {
      for (const std::uint32_t i : movers) {
        Vec3& c = shapes[i].center;
        if (step < 400) {
          c.x += 0.05;
        } else if (step < 500) {
          c.x -= 0.05;
        } else {
          c.x += rng.uniform(-0.1, 0.1);
          c.y += rng.uniform(-0.1, 0.1);
        }
      }
    });
    ASSERT_GT(calls, 300u);
    // About one renewal a mover every 24 calls; centred lists take 12.
    EXPECT_LT(renewed * 18, calls * kRows) << renewed << " renewals in " << calls << " calls";
  }
}

// Slow movers whose indices lie in another order than their places (the
// order in which a call goes through them, and lays their lists out for the
// next): each still finds its own list, so that lists hold for about 25
// calls at this speed; a list found by another mover's slot would not hold
// it and be renewed on nearly every call. The oracle's pairs on every call,
// the invariants after every call, one order on 1 to 3 threads.
TEST(Arrays, MoverListsFollowTheirMoversInAnyOrder) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(2)); ++seed) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    Rng rng(seed * 8011);
    constexpr int kRows = 12;
    std::vector<std::uint32_t> movers;
    std::vector<Shape> shapes = rows_with_movers(rng, kRows, 12, true, movers);
    // The movers' places shuffled among their indices.
    for (std::size_t k = movers.size() - 1; k > 0; --k)
      std::swap(shapes[movers[k]], shapes[movers[rng.below(k + 1)]]);
    const auto [renewed, calls] = renewals_of(shapes, movers, 160, 40, 160, [&](int) {
      for (const std::uint32_t i : movers) shapes[i].center.x += 0.01;
    });
    ASSERT_GT(calls, 100u);
    EXPECT_LT(renewed * 8, calls * kRows) << renewed << " renewals in " << calls << " calls";
  }
}

// Movers mode in a crowded set (the quiet spheres overlap several others
// each), where ArrayOptions::spare_bytes bounds the movers' lists and the
// quiet pairs kept as IndexPairs: with no room for any, with room for some
// (the others probe), and with the default: the oracle's pairs on every
// frame, the same order on 1 to 3 threads, the invariants after every
// call; the own memory shows which bound held.
TEST(Arrays, MoverListsKeepToTheirRoom) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(3)); ++seed) {
    std::size_t memory[3] = {};
    const std::size_t rooms[3] = {1, 96 << 10, 0};
    for (int b = 0; b < 3; ++b) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " spare_bytes " << rooms[b]);
      Rng rng(seed * 7727);
      std::vector<Shape> shapes;
      for (int k = 0; k < 1200; ++k)
        shapes.push_back(Shape::sphere({rng.uniform(0, 15), rng.uniform(0, 15), rng.uniform(0, 15)},
                                       rng.uniform(0.5, 1.5)));
      std::vector<std::uint32_t> movers = pick_movers(rng, shapes.size(), 7);
      PairTracker trackers[3];
      ArrayOptions options;
      options.spare_bytes = rooms[b];
      on_threads(trackers, options);
      int in_mode = 0;
      for (int frame = 0; frame < 16; ++frame) {
        SCOPED_TRACE(::testing::Message() << "frame " << frame);
        for (const std::uint32_t i : movers) {
          const Vec3 d{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
          if (rng.below(40) == 0)  // a teleport
            shapes[i].center = {rng.uniform(0, 15), rng.uniform(0, 15), rng.uniform(0, 15)};
          else
            shapes[i].center = shapes[i].center + d * 0.05;
        }
        Storage st(shapes, Layout::soa_double);
        ArrayCallStats stats;
        ASSERT_NO_FATAL_FAILURE(
            call_on_each(trackers, st.objects, Changes::only(movers), oracle(st.objects), stats));
        ASSERT_GT(stats.pairs, 2 * shapes.size()) << "not a crowded set";
        in_mode += stats.movers ? 1 : 0;
      }
      EXPECT_GE(in_mode, 12);
      memory[b] = trackers[0].memory_bytes();
    }
    // Some lists, within their room; more with the default.
    EXPECT_LT(memory[0] + 24 * 256, memory[1]) << "seed " << seed;
    EXPECT_LE(memory[1], memory[0] + (96 << 10)) << "seed " << seed;
    EXPECT_LT(memory[1] + (16 << 10), memory[2]) << "seed " << seed;
  }
}

// Movers mode: spheres of which about one in ten moves each frame (listed),
// with quiet ones woken, movers stopping, teleports, resizes, a sphere
// turned into a box and back, appends, removals and "everything" now and
// then: the oracle's pairs on every frame, the same order on 1 to 3
// threads, the invariants after every call, and the mode taken on most
// frames (so that the checks above are of it).
TEST(Arrays, TrackerMoversModeMatchesOracle) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(10)); ++seed) {
    Rng rng(seed * 104729);
    // (Not the lattice: its cells are too crowded for the mode.)
    const World kinds[] = {World::spheres, World::similar, World::sizes};
    const World w = kinds[seed % std::size(kinds)];
    const Layout layout = kLayouts[seed % std::size(kLayouts)];
    std::vector<Shape> shapes = random_world(w, 300 + rng.below(1500), rng);
    const double world = 20.0 * std::cbrt(static_cast<double>(shapes.size()) / 10.0) + 1;
    std::vector<std::uint32_t> movers = pick_movers(rng, shapes.size(), 10);
    PairTracker trackers[3];
    on_threads(trackers);
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

// A movers call checks the objects listed and no other (it reads no
// other value): a bad value in a listed one throws, naming the lowest such
// index, and leaves the tracker as it was; a call told that everything may
// have changed, and a call that leaves movers mode, check every value.
TEST(Arrays, MoversCallsCheckTheListedObjects) {
  Rng rng(907);
  const double nan = std::nan("");
  std::vector<Shape> shapes = random_world(World::similar, 1200, rng);
  std::vector<std::uint32_t> movers;
  for (std::uint32_t i = 0; i < shapes.size(); i += 10) movers.push_back(i);
  auto step = [&] {
    for (std::uint32_t i : movers) shapes[i].center = shapes[i].center + Vec3{0.05, 0, 0};
  };
  PairTracker tracker;
  std::vector<IndexPair> got;
  ArrayCallStats stats;
  tracker.find_pairs(Storage(shapes, Layout::soa_double).objects, got);
  for (int call = 0; call < 6; ++call) {
    step();
    got.clear();
    stats =
        tracker.find_pairs(Storage(shapes, Layout::soa_double).objects, got, Changes::only(movers));
  }
  ASSERT_TRUE(stats.movers) << "the set did not take movers mode";
  const std::size_t bytes = tracker.memory_bytes();
  const std::size_t quiet = stats.quiet;
  step();
  const std::vector<Shape> good = shapes;
  // Two bad listed objects: the lower index is named, whatever the order
  // of the list.
  shapes[movers[7]].half = Vec3{-1, -1, -1};  // a negative radius
  shapes[movers[3]].center.y = nan;
  {
    Storage bad(shapes, Layout::aos_float);
    std::vector<std::uint32_t> backwards(movers.rbegin(), movers.rend());
    try {
      tracker.find_pairs(bad.objects, got, Changes::only(backwards));
      ADD_FAILURE() << "no throw";
    } catch (const InvalidObjects& e) {
      EXPECT_EQ(e.index(), movers[3]);
      EXPECT_NE(std::string(e.what()).find("y is nan"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(tracker.memory_bytes(), bytes);
  // A quiet object listed (it would wake) with a bad value below them: it
  // is named, and it does not wake.
  {
    shapes[1].center.x = -HUGE_VAL;
    Storage bad(shapes, Layout::soa_double);
    std::vector<std::uint32_t> listed = movers;
    listed.push_back(1);
    try {
      tracker.find_pairs(bad.objects, got, Changes::only(listed));
      ADD_FAILURE() << "no throw";
    } catch (const InvalidObjects& e) {
      EXPECT_EQ(e.index(), 1u) << e.what();
    }
  }
  EXPECT_EQ(tracker.memory_bytes(), bytes);
  // A bad value in an object not listed: told everything, the call throws.
  shapes = good;
  shapes[5].center.z = HUGE_VAL;
  EXPECT_THROW(
      tracker.find_pairs(Storage(shapes, Layout::soa_double).objects, got, Changes::everything()),
      InvalidObjects);
  // Listing a box (which leaves movers mode) checks every value too.
  std::vector<std::uint32_t> with_box = movers;
  shapes[movers[1]] = Shape::box(shapes[movers[1]].center, {1, 1, 1});
  EXPECT_THROW(
      tracker.find_pairs(Storage(shapes, Layout::soa_double).objects, got, Changes::only(with_box)),
      InvalidObjects);
  EXPECT_EQ(tracker.memory_bytes(), bytes);
  // The tracker is as it was: the good objects give the oracle's pairs,
  // still in movers mode.
  Storage st(good, Layout::soa_double);
  got.clear();
  stats = tracker.find_pairs(st.objects, got, Changes::only(movers));
  EXPECT_TRUE(stats.movers);
  EXPECT_EQ(stats.quiet, quiet);
  EXPECT_EQ(sorted(got), oracle(st.objects));
  ASSERT_NO_THROW(tracker.validate(st.objects));
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

// An object far larger than the median keeps a skin of a share of its own
// size: a slow drift of a few skins of the median does not renew it (its
// renewal would query every finer level), and the pairs stay exact.
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

// A few objects leave their skin on every call: they are renewed alone
// (no rebuild), and the candidates stay complete and exact call after call
// (validate checks the renewed objects' loose pairs and the kept grid).
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

// Boxes whose movers leave the default skin at every call (a fifth of
// them, each a fifth of a box a call): the tracker builds its index again
// once with a wider skin, and then renews far fewer of them; a skin the
// caller chose stays, however often it is outrun. Exact at every call.
TEST(Arrays, TrackerWidensAnOutrunDefaultSkinOnce) {
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(testing::repeats(3)); ++seed) {
    std::uint64_t renewed[2] = {0, 0};
    for (int chosen = 0; chosen < 2; ++chosen) {
      Rng rng(seed * 7727);
      const std::size_t n = 400 + rng.below(400);
      const double world = 4.0 * std::cbrt(static_cast<double>(n));
      std::vector<Shape> shapes;
      std::vector<Vec3> step;
      for (std::size_t i = 0; i < n; ++i) {
        const Vec3 c{rng.uniform(0, world), rng.uniform(0, world), rng.uniform(0, world)};
        shapes.push_back(
            Shape::box(c, {rng.uniform(0.2, 0.8), rng.uniform(0.2, 0.8), rng.uniform(0.2, 0.8)}));
        step.push_back(i % 5 == 0 ? Vec3{rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), 0.2}
                                  : Vec3{});
      }
      ArrayOptions opt;
      opt.skin = chosen ? 0.25 : 0;  // the default's value, chosen
      PairTracker tracker(opt);
      int rebuilds = 0;
      for (int frame = 0; frame < 30; ++frame) {
        SCOPED_TRACE(::testing::Message()
                     << "seed " << seed << " skin " << opt.skin << " frame " << frame);
        std::vector<std::uint32_t> moved;
        if (frame > 0)
          for (std::uint32_t i = 0; i < n; ++i)
            if (step[i].z != 0) {
              shapes[i].center = shapes[i].center + step[i];
              moved.push_back(i);
            }
        Storage st(shapes, Layout::soa_double);
        std::vector<IndexPair> got;
        const auto stats = tracker.find_pairs(
            st.objects, got, frame == 0 ? Changes::everything() : Changes::only(moved));
        ASSERT_NO_THROW(tracker.validate(st.objects));
        ASSERT_EQ(sorted(got), oracle(st.objects));
        EXPECT_FALSE(stats.movers);
        rebuilds += stats.rebuilt ? 1 : 0;
        if (frame >= 10) renewed[chosen] += stats.renewed;
      }
      // The first call's build, and for the default skin the one that widens it.
      EXPECT_EQ(rebuilds, chosen ? 1 : 2) << "seed " << seed;
    }
    EXPECT_LT(2 * renewed[0], renewed[1]) << "seed " << seed;
  }
}

}  // namespace
}  // namespace broadphase
