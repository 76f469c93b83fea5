// PairTable (the hash set behind sap) and PairCache's contact events.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/detail/pair_table.hpp>
#include <broadphase/pair_cache.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <set>

#include "testing.hpp"

namespace broadphase {
namespace {

TEST(PairTable, AgreesWithStdSetUnderRandomInsertAndErase) {
  detail::PairTable t;
  std::set<std::pair<std::uint32_t, std::uint32_t>> model;
  Rng rng(7);
  for (int step = 0; step < 200000; ++step) {
    std::uint32_t a = static_cast<std::uint32_t>(rng.below(300));
    std::uint32_t b = static_cast<std::uint32_t>(rng.below(300));
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    if (rng.uniform() < 0.55) {
      EXPECT_EQ(t.insert(a, b), model.insert(key).second);
    } else {
      EXPECT_EQ(t.erase(b, a), model.erase(key) == 1);
    }
    if (step % 20000 == 0) t.validate();
  }
  t.validate();
  EXPECT_EQ(t.size(), model.size());
  for (const auto& p : t.pairs()) EXPECT_TRUE(model.count({p.a, p.b}));
}

TEST(PairCache, ReportsBegunPersistingAndEnded) {
  const Handle a{0, 1}, b{1, 1}, c{2, 1};
  PairCache cache;
  const HandlePair f0[] = {{a, b}};
  cache.frame(f0);
  ASSERT_EQ(cache.begun().size(), 1u);
  EXPECT_TRUE(cache.persisting().empty());
  const HandlePair f1[] = {{b, a}, {b, c}, {c, b}};  // reversed and duplicated pairs
  cache.frame(f1);
  EXPECT_EQ(cache.persisting().size(), 1u);
  EXPECT_EQ(cache.begun().size(), 1u);
  EXPECT_TRUE(cache.ended().empty());
  EXPECT_TRUE(cache.contains(a, b));
  cache.frame({});
  EXPECT_EQ(cache.ended().size(), 2u);
  EXPECT_EQ(cache.size(), 0u);
}

TEST(PairCache, AReusedSlotIsANewObject) {
  PairCache cache;
  const Handle a{0, 1}, b{1, 1}, b_again{1, 3};
  const HandlePair f0[] = {{a, b}};
  cache.frame(f0);
  const HandlePair f1[] = {{a, b_again}};
  cache.frame(f1);
  EXPECT_EQ(cache.begun().size(), 1u);
  EXPECT_EQ(cache.ended().size(), 1u);
  EXPECT_TRUE(cache.persisting().empty());
}

TEST(PairCache, ManyFramesStayConsistent) {
  PairCache cache;
  Rng rng(3);
  std::set<std::pair<std::uint32_t, std::uint32_t>> prev;
  for (int f = 0; f < 300; ++f) {
    std::set<std::pair<std::uint32_t, std::uint32_t>> now;
    cache.begin_frame();
    for (int k = 0; k < 400; ++k) {
      const std::uint32_t x = static_cast<std::uint32_t>(rng.below(60));
      const std::uint32_t y = static_cast<std::uint32_t>(rng.below(60));
      if (x == y) continue;
      now.insert({std::min(x, y), std::max(x, y)});
      cache.add({x, 1}, {y, 1});
    }
    cache.end_frame();
    std::size_t persisting = 0;
    for (const auto& p : now) persisting += prev.count(p);
    EXPECT_EQ(cache.persisting().size(), persisting);
    EXPECT_EQ(cache.begun().size(), now.size() - persisting);
    EXPECT_EQ(cache.ended().size(), prev.size() - persisting);
    prev = now;
  }
  EXPECT_THROW(cache.end_frame(), std::logic_error);
}

TEST(PairCache, APairAChangedMaskRemovesEnds) {
  // Two touching objects, then a mask that excludes the other's group: the
  // structure no longer reports the pair, so it ends; the mask restored, it
  // begins again; a pair filter installed, it ends.
  for (const std::string& name : testing::library_structures()) {
    SCOPED_TRACE(name);
    auto bp = make_structure(name);
    const Handle a = bp->insert(Shape::sphere({10, 10, 10}, 1), 0, Motion::dynamic, {1, 0xffu});
    const Handle b = bp->insert(Shape::sphere({11, 10, 10}, 1), 1, Motion::fixed, {2, 0xffu});
    bp->settle();
    PairCache cache;
    auto frame = [&] {
      std::vector<HandlePair> pairs;
      bp->find_pairs(pairs);
      cache.frame(pairs);
    };
    frame();
    ASSERT_EQ(cache.begun().size(), 1u);
    bp->set_filter(a, {1, 0x1u});  // a no longer accepts group 2
    frame();
    ASSERT_EQ(cache.ended().size(), 1u);
    EXPECT_TRUE(cache.begun().empty());
    EXPECT_EQ(cache.size(), 0u);
    bp->set_filter(a, {1, 0x3u});
    frame();
    ASSERT_EQ(cache.begun().size(), 1u);
    bp->set_filter(b, {4, 0xffu});  // b's group leaves a's mask
    frame();
    ASSERT_EQ(cache.ended().size(), 1u);
    bp->set_filter(b, {2, 0xffu});
    frame();
    ASSERT_EQ(cache.begun().size(), 1u);
    bp->set_pair_filter(
        [&](Handle x, Handle y) { return !((x == a && y == b) || (x == b && y == a)); });
    frame();
    ASSERT_EQ(cache.ended().size(), 1u);
    bp->set_pair_filter({});
    frame();
    ASSERT_EQ(cache.begun().size(), 1u);
  }
}

TEST(PairCache, EventsFollowRandomFilterChangesOnEveryStructure) {
  // Frame after frame of moves and random mask changes, the cache's events
  // against the difference of two brute-force pair sets.
  using Set = std::set<std::pair<std::uint64_t, std::uint64_t>>;
  for (const std::string& name : testing::library_structures()) {
    const std::uint64_t seed = 5;
    SCOPED_TRACE(name + " seed " + std::to_string(seed));
    Rng rng(seed);
    Scene scene = generate(Distribution::even, 800, seed);
    auto bp = make_structure(name);
    std::vector<Handle> h;
    std::vector<Filter> filters(scene.size());
    for (std::size_t i = 0; i < scene.size(); ++i) {
      filters[i] = {1u << rng.below(4), static_cast<std::uint32_t>(rng.below(16))};
      h.push_back(bp->insert(scene.objects[i], i,
                             scene.is_moving(i) ? Motion::dynamic : Motion::fixed, filters[i]));
    }
    bp->settle();
    PairCache cache;
    Set before;
    for (int f = 0; f < 12; ++f) {
      if (f > 0) {
        step(scene);
        std::vector<Move> moves;
        for (std::size_t i = 0; i < scene.size(); ++i)
          if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
        bp->update(moves);
        for (int k = 0; k < 20; ++k) {
          const std::size_t i = rng.below(scene.size());
          filters[i] = {1u << rng.below(4), static_cast<std::uint32_t>(rng.below(16))};
          bp->set_filter(h[i], filters[i]);
        }
      }
      std::vector<HandlePair> pairs;
      bp->find_pairs(pairs);
      cache.frame(pairs);
      Set now;
      for (std::size_t i = 0; i < scene.size(); ++i)
        for (std::size_t j = i + 1; j < scene.size(); ++j)
          if (filters_pass(filters[i], filters[j]) && overlaps(scene.objects[i], scene.objects[j]))
            now.insert({i, j});
      auto ids = [&](std::span<const HandlePair> ps) {
        Set out;
        for (const HandlePair& p : ps) {
          const std::uint64_t x = bp->user_data(p.a), y = bp->user_data(p.b);
          out.insert({std::min(x, y), std::max(x, y)});
        }
        return out;
      };
      Set begun, ended, persisting;
      for (const auto& p : now) (before.count(p) ? persisting : begun).insert(p);
      for (const auto& p : before)
        if (!now.count(p)) ended.insert(p);
      ASSERT_EQ(ids(cache.begun()), begun) << "frame " << f;
      ASSERT_EQ(ids(cache.persisting()), persisting) << "frame " << f;
      ASSERT_EQ(ids(cache.ended()), ended) << "frame " << f;
      before = now;
    }
  }
}

}  // namespace
}  // namespace broadphase
