// The linear octree: Morton keys, the key table, child masks instead of
// links, and its depth option.
#include <gtest/gtest.h>

#include <broadphase/octree_linear.hpp>
#include <cstdint>
#include <map>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

std::size_t count_pairs(const LinearOctree& t) {
  std::size_t n = 0;
  t.for_each_pair([&](Handle, Handle) { ++n; });
  return n;
}

TEST(LinearOctree, MortonKeysNestAndStayUnique) {
  EXPECT_EQ(detail::morton_key(0, 0, 0, 0), 1u);
  EXPECT_EQ(detail::morton_key(1, 1, 0, 1), 0b1101u);
  const std::uint32_t m = (1u << 20) - 1;
  EXPECT_EQ(detail::morton_key(20, m, m, m), ~0ull >> 3);
  EXPECT_EQ(detail::morton_key(5, 17, 3, 30) >> 3, detail::morton_key(4, 8, 1, 15));
}

TEST(LinearOctree, KeyTableAgreesWithAMap) {
  detail::KeyTable table;
  std::map<std::uint64_t, std::uint32_t> model;
  Rng rng(9);
  for (int step = 0; step < 20000; ++step) {
    const std::uint64_t key = 1 + rng.below(3000) * 977;  // collisions in the low bits
    if (model.count(key)) {
      ASSERT_EQ(table.find(key), model[key]);
      table.erase(key);
      model.erase(key);
    } else {
      const auto v = static_cast<std::uint32_t>(step);
      table.insert(key, v);
      model[key] = v;
    }
    ASSERT_EQ(table.size(), model.size());
  }
  for (const auto& [k, v] : model) ASSERT_EQ(table.find(k), v);
  EXPECT_EQ(table.find(2), detail::kNoNode);
}

TEST(LinearOctree, NodesExistOnlyAlongOccupiedPaths) {
  Config c;
  c.options["depth"] = "4";
  LinearOctree t(c);
  const Handle a = t.insert(Shape::sphere({100, 100, 100}, 0.5), 0);
  t.validate();
  EXPECT_EQ(t.node_count(), 5u);  // the root and one cell per level
  const Handle b = t.insert(Shape::sphere({100.5, 100, 100}, 0.5), 1);
  EXPECT_EQ(t.node_count(), 5u);
  EXPECT_EQ(count_pairs(t), 1u);
  t.remove(a);
  t.remove(b);
  t.validate();
  EXPECT_EQ(t.node_count(), 1u);
}

TEST(LinearOctree, OutsideAndStraddlingObjectsStayAtTheRoot) {
  LinearOctree t;
  t.insert(Shape::sphere({500, 200, 200}, 3), 0);  // on the root's midplane
  t.insert(Shape::sphere({-400, 200, 200}, 3), 1);
  t.insert(Shape::box({0, 0, 0}, {1e6, 1e6, 1e6}), 2);
  t.validate();
  EXPECT_EQ(t.node_count(), 1u);
  EXPECT_EQ(count_pairs(t), 2u);
}

TEST(LinearOctree, RejectsBadOptions) {
  EXPECT_THROW(make_structure("octree-linear:depth=21"), InvalidConfig);
  EXPECT_THROW(make_structure("octree-linear:k=2"), InvalidConfig);
}

TEST(LinearOctree, MatchesNaiveAtEveryDepthLimit) {
  for (const char* spec :
       {"octree-linear:depth=0", "octree-linear:depth=1", "octree-linear:depth=20"}) {
    for (auto w : {testing::World::mixed, testing::World::touching, testing::World::far}) {
      testing::differential(spec, w, 17, 400);
      if (HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace broadphase
