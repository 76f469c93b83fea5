// Typed options and the one configuration error: every structure, built
// directly or through the registry, refuses a bad option value or a bad
// world with InvalidConfig, and takes good typed options as given.
#include <gtest/gtest.h>

#include <broadphase/aabb_tree.hpp>
#include <broadphase/broadphase.hpp>
#include <broadphase/grid_dense.hpp>
#include <broadphase/grid_hashed.hpp>
#include <broadphase/grid_hybrid.hpp>
#include <broadphase/grid_implicit.hpp>
#include <broadphase/grid_static.hpp>
#include <broadphase/grid_verlet.hpp>
#include <broadphase/kdtree.hpp>
#include <broadphase/naive.hpp>
#include <broadphase/octree.hpp>
#include <broadphase/octree_linear.hpp>
#include <broadphase/octree_loose.hpp>
#include <broadphase/sap.hpp>
#include <broadphase/study/hgrid_paper.hpp>
#include <broadphase/study/octree_paper.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kSubnormal = 1e-310;
constexpr double kMax = std::numeric_limits<double>::max();

// A structure built directly with a bad option.
struct DirectCase {
  const char* what;
  std::function<void()> build;
};

std::vector<DirectCase> bad_direct_options() {
  const Config c;  // captured by value: the lambdas outlive this function
  return {
      {"octree split=0", [c] { Octree(c, {.split = 0}); }},
      {"octree split=2e6", [c] { Octree(c, {.split = 2000000}); }},
      {"octree-loose k=NaN", [c] { LooseOctree(c, {.k = kNan}); }},
      {"octree-loose k=inf", [c] { LooseOctree(c, {.k = kInf}); }},
      {"octree-loose k=1", [c] { LooseOctree(c, {.k = 1}); }},
      {"octree-loose depth=21", [c] { LooseOctree(c, {.depth = 21}); }},
      {"octree-loose depth=-1", [c] { LooseOctree(c, {.depth = -1}); }},
      {"octree-linear depth=21", [c] { LinearOctree(c, {.depth = 21}); }},
      {"kdtree leaf=0", [c] { KdTree(c, {.leaf = 0}); }},
      {"kdtree decay=0.5", [c] { KdTree(c, {.decay = 0.5}); }},
      {"kdtree decay=NaN", [c] { KdTree(c, {.decay = kNan}); }},
      {"aabb-tree margin=-1", [c] { AabbTree(c, {.margin = -1.0}); }},
      {"aabb-tree margin=inf", [c] { AabbTree(c, {.margin = kInf}); }},
      {"aabb-tree margin=subnormal", [c] { AabbTree(c, {.margin = kSubnormal}); }},
      {"aabb-tree predict=NaN", [c] { AabbTree(c, {.predict = kNan}); }},
      {"grid-dense cell=-1", [c] { GridDense(c, {.cell = -1}); }},
      {"grid-dense cell=NaN", [c] { GridDense(c, {.cell = kNan}); }},
      {"grid-dense cell=subnormal", [c] { GridDense(c, {.cell = kSubnormal}); }},
      {"grid-hashed cell=inf", [c] { GridHashed(c, {.cell = kInf}); }},
      {"grid-hashed cell=subnormal", [c] { GridHashed(c, {.cell = kSubnormal}); }},
      {"grid-hashed buckets=2^26+1",
       [c] { GridHashed(c, {.buckets = GridHashedOptions::kMaxBuckets + 1}); }},
      {"grid-hybrid buckets=2^29+1", [c] { GridHybrid(c, {.buckets = (1u << 29) + 1}); }},
      {"grid-hybrid cell=NaN", [c] { GridHybrid(c, {.cell = kNan}); }},
      {"grid-static cell=subnormal", [c] { GridStatic(c, {.cell = kSubnormal}); }},
      {"grid-implicit cell=-inf", [c] { GridImplicit(c, {.cell = -kInf}); }},
      {"hgrid-paper levels=0", [c] { HGridPaper(c, {.levels = 0}); }},
      {"hgrid-paper levels=31", [c] { HGridPaper(c, {.levels = 31}); }},
      {"grid-verlet threads=65", [c] { GridVerlet(c, {.threads = 65}); }},
      {"grid-verlet cell=0.25", [c] { GridVerlet(c, {.cell = 0.25}); }},
      {"grid-verlet cell=NaN", [c] { GridVerlet(c, {.cell = kNan}); }},
      {"grid-verlet grain=0", [c] { GridVerlet(c, {.grain = 0}); }},
  };
}

TEST(Options, EveryStructureBuiltDirectlyRefusesABadOptionWithInvalidConfig) {
  for (const DirectCase& k : bad_direct_options()) EXPECT_THROW(k.build(), InvalidConfig) << k.what;
}

TEST(Options, TheRegistryRefusesTheSameValuesWithTheSameType) {
  for (const char* spec : {"octree:split=0",
                           "octree-loose:k=nan",
                           "octree-loose:k=inf",
                           "octree-loose:k=1",
                           "octree-linear:depth=21",
                           "kdtree:decay=0.5",
                           "aabb-tree:margin=-1",
                           "aabb-tree:margin=1e-310",
                           "grid-dense:cell=-1",
                           "grid-dense:cell=1e-310",
                           "grid-hashed:cell=1e-310",
                           "grid-hashed:buckets=536870913",
                           "grid-hybrid:buckets=67108865",
                           "grid-static:cell=1e-310",
                           "grid-implicit:cell=inf",
                           "hgrid-paper:levels=0",
                           "hgrid-paper:levels=4294967300",
                           "octree-loose:depth=4294967300",
                           "grid-verlet:threads=65",
                           "grid-verlet:cell=0.25",
                           "grid-verlet:grain=0",
                           "grid-verlet:grain=-1",
                           "naive:cell=1",
                           "sap:x=1",
                           "grid-hashed:cell",
                           "octree:split=1,split=2"})
    EXPECT_THROW(make_structure(spec), InvalidConfig) << spec;
}

TEST(Options, AnUnknownNameIsAnUnknownStructureWhichIsAnInvalidConfig) {
  EXPECT_THROW(make_structure("no-such-grid"), UnknownStructure);
  EXPECT_THROW(make_structure("no-such-grid"), InvalidConfig);
  // A bad option is a configuration error, not an unknown structure.
  try {
    make_structure("octree:split=0");
    ADD_FAILURE() << "accepted split=0";
  } catch (const UnknownStructure&) {
    ADD_FAILURE() << "a bad option value is not an unknown structure";
  } catch (const InvalidConfig& e) {
    EXPECT_NE(std::string(e.what()).find("split"), std::string::npos) << e.what();
  }
}

// The worlds no scene can produce: every structure refuses them, built
// through the registry or directly.
std::vector<Aabb> bad_worlds() {
  return {
      {{-1e308, -1e308, -1e308}, {1e308, 1e308, 1e308}},  // finite corners, width overflows
      {{0, 0, 0}, {kInf, 1, 1}},
      {{kNan, 0, 0}, {1, 1, 1}},
      {{0, 0, 0}, {1, 1, kNan}},
      {{0, 0, 0}, {0, 1, 1}},  // empty
      {{1, 0, 0}, {0, 1, 1}},  // inverted
  };
}

TEST(Options, EveryStructureRefusesAWorldThatNoSceneCanProduce) {
  for (const std::string& name : testing::library_structures()) {
    for (const Aabb& w : bad_worlds()) {
      Config c;
      c.world = w;
      EXPECT_THROW(make_structure(name, c), InvalidConfig)
          << name << " world [" << w.lo.x << ", " << w.hi.x << "]";
    }
  }
  Config c;
  c.world = bad_worlds()[0];
  EXPECT_THROW(Octree{c}, InvalidConfig);
  EXPECT_THROW(GridVerlet{c}, InvalidConfig);
  EXPECT_THROW(GridDense{c}, InvalidConfig);
  EXPECT_THROW(GridImplicit{c}, InvalidConfig);
  EXPECT_THROW(OctreePaper{c}, InvalidConfig);
  EXPECT_THROW(HGridPaper{c}, InvalidConfig);
  EXPECT_THROW(Naive{c}, InvalidConfig);
  EXPECT_THROW(Sap{c}, InvalidConfig);
}

TEST(Options, AWorldAsWideAsTheLargestDoubleIsAccepted) {
  // [0, DBL_MAX]^3 is the world of a scene with `world 1.7976931348623157e308`.
  Config c;
  c.world = {{0, 0, 0}, {kMax, kMax, kMax}};
  for (const std::string& name : testing::library_structures())
    EXPECT_NO_THROW(make_structure(name, c)) << name;
}

TEST(Options, TypedOptionsAndTheMapMayNotBothBeGiven) {
  Config c;
  c.options["split"] = "4";
  EXPECT_THROW(Octree(c, OctreeOptions{}), InvalidConfig);
  EXPECT_NO_THROW(Octree{c});  // the map alone: still read (deprecated)
}

TEST(Options, TypedOptionsTakeEffect) {
  const Config c;
  EXPECT_EQ(GridVerlet(c, {.threads = 3}).threads(), 3u);
  EXPECT_EQ(AabbTree(c, {.order = AabbTreeOrder::near_far}).order(), AabbTree::Order::near_far);
  EXPECT_EQ(AabbTree(c, {.front = AabbTreeFront::basic}).front_mode(), AabbTree::FrontMode::basic);
  // The same split given typed and as text builds the same tree.
  Octree typed(c, {.split = 2});
  Config text;
  text.options["split"] = "2";
  Octree mapped(text);
  for (Octree* t : {&typed, &mapped})
    for (int i = 0; i < 9; ++i) t->insert(Shape::sphere({100.0 + 10 * i, 100, 100}, 1), 0);
  EXPECT_EQ(typed.node_count(), mapped.node_count());
  EXPECT_GT(typed.node_count(), 1u);
  // The registry's entries take the map's defaults from the structs.
  EXPECT_EQ(make_structure("grid-verlet")->size(), 0u);
}

TEST(Options, TheRegistryReadsASpecStraightIntoTheTypedOptions) {
  // Every library entry builds from a Config without options and the
  // spec's text (StructureInfo::build); `make`, for callers holding a
  // Config with options, reads them the same way.
  const Registry r = Registry::library();
  for (const StructureInfo& e : r.entries()) EXPECT_TRUE(static_cast<bool>(e.build)) << e.name;
  auto via_spec = make_structure("octree:split=2");
  Config c;
  c.options["split"] = "2";
  auto via_map = make_structure("octree", c);  // the deprecated map
  auto via_make = r.find("octree")->make(c);   // the entry's Config path
  auto via_build = r.find("octree")->build(Config{}, {{"split", "2"}});
  for (AnyBroadPhase* t : {via_spec.get(), via_map.get(), via_make.get(), via_build.get()})
    for (int i = 0; i < 9; ++i) t->insert(Shape::sphere({100.0 + 10 * i, 100, 100}, 1), 0);
  auto nodes = [](const AnyBroadPhase& t) {
    return dynamic_cast<const Erased<Octree>&>(t).get().node_count();
  };
  EXPECT_GT(nodes(*via_spec), 1u);
  for (const AnyBroadPhase* t : {via_map.get(), via_make.get(), via_build.get()})
    EXPECT_EQ(nodes(*t), nodes(*via_spec));
  // A key of the spec wins over the same key of the map; unknown keys of
  // either are refused.
  c.options["split"] = "0";
  EXPECT_NO_THROW(make_structure("octree:split=2", c));
  c.options = {{"nope", "1"}};
  EXPECT_THROW(make_structure("octree", c), InvalidConfig);
  EXPECT_THROW(r.find("octree")->make(c), InvalidConfig);
  EXPECT_THROW(r.find("octree")->build(Config{}, {{"nope", "1"}}), InvalidConfig);
}

TEST(Options, SettleIsANoOpWhereThereIsNothingToCommit) {
  for (const std::string& name : testing::library_structures()) {
    auto s = make_structure(name);
    for (int i = 0; i < 40; ++i) s->insert(Shape::sphere({10.0 * i, 10, 10}, 6), i);
    std::vector<HandlePair> before, after;
    s->find_pairs(before);
    s->settle();
    s->validate();
    s->find_pairs(after);
    EXPECT_EQ(before.size(), after.size()) << name;
    EXPECT_EQ(s->size(), 40u) << name;
  }
}

TEST(Options, SettleBuildsTheFixedPairCacheAsAnEmptyBulkUpdateDoes) {
  GridVerlet a, b;
  for (GridVerlet* g : {&a, &b}) {
    for (int i = 0; i < 50; ++i)
      g->insert(Shape::sphere({10.0 + i, 10, 10}, 0.8), static_cast<std::uint64_t>(i),
                Motion::fixed);
  }
  a.settle();
  b.update(std::span<const Move>{});
  a.validate();
  b.validate();
  std::vector<HandlePair> pa, pb;
  a.find_pairs(pa);
  b.find_pairs(pb);
  EXPECT_EQ(pa.size(), 49u);
  EXPECT_EQ(pa.size(), pb.size());
  EXPECT_EQ(a.memory_bytes(), b.memory_bytes());
}

}  // namespace
}  // namespace broadphase
