// PairTable (the hash set behind sap) and PairCache's contact events.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/detail/pair_table.hpp>
#include <broadphase/pair_cache.hpp>
#include <broadphase/scenes/scene.hpp>
#include <set>

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

}  // namespace
}  // namespace broadphase
