// visit_cells, the cells or nodes a structure reports for pictures: on every
// structure that has them, after random inserts, updates and removals, each
// object lies in the cells that say they hold it; the type-erased wrapper
// forwards the call; structures without cells say so.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/broadphase.hpp>
#include <broadphase/grid_verlet.hpp>
#include <broadphase/octree.hpp>
#include <cstdint>
#include <ostream>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "testing.hpp"

namespace broadphase {
namespace {

struct Cell {
  Aabb box;
  int level;
  std::size_t objects;
};

/// How a structure's objects sit in its cells.
enum class Holds {
  bounds,  ///< the cells holding an object cover its bounds
  centre,  ///< an object's cell holds its centre; the object may reach beyond (loose, hgrids)
  /// A cell holds the lower corner of the box its grid keeps for an object:
  /// the object's bounds, or for a moving object of grid-verlet its fat box,
  /// whose corner lies a margin below the object's (here at most 2% of its
  /// extent: the objects' speeds are unknown or too high for a wider one).
  lower_corner,
};
/// Whether an object is counted in one cell or in every cell it touches.
enum class Counted { once, per_cell };

struct Case {
  std::string spec;
  Holds holds;
  Counted counted;
  /// grid-verlet: half the objects are fixed (it keeps them in a grid of
  /// their own), and settle() ends the list of objects inserted or moved one
  /// at a time before the cells are read (without it they would show as
  /// cells of their own, after the grids' levels).
  bool settle = false;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.spec; }

std::vector<Case> cases() {
  return {
      {"octree", Holds::bounds, Counted::once},
      {"octree:split=4", Holds::bounds, Counted::once},
      {"octree-loose", Holds::centre, Counted::once},
      {"octree-linear", Holds::bounds, Counted::once},
      {"kdtree", Holds::bounds, Counted::once},
      {"aabb-tree", Holds::bounds, Counted::once},
      {"grid-dense", Holds::bounds, Counted::per_cell},
      {"grid-hashed", Holds::bounds, Counted::per_cell},
      {"grid-hybrid", Holds::bounds, Counted::per_cell},
      {"grid-static", Holds::bounds, Counted::per_cell},
      {"grid-implicit", Holds::bounds, Counted::per_cell},
      {"hgrid", Holds::centre, Counted::once},
      {"octree-paper", Holds::bounds, Counted::once},
      {"hgrid-paper", Holds::centre, Counted::once},
      {"grid-verlet", Holds::lower_corner, Counted::once, true},
      {"grid-verlet:threads=2,grain=1", Holds::lower_corner, Counted::once, true},
      {"grid-verlet:cell=4", Holds::lower_corner, Counted::once, true},
  };
}

std::vector<Cell> cells_of(const AnyBroadPhase& s) {
  std::vector<Cell> out;
  const bool has = s.visit_cells([&](const Aabb& box, int level, std::size_t n) {
    out.push_back({box, level, n});
  });
  EXPECT_TRUE(has) << "visit_cells is not forwarded";
  return out;
}

/// True when `p` lies in a cell holding objects (closed, with a rounding
/// allowance far below any cell).
bool in_occupied(const std::vector<Cell>& cells, const Vec3& p) {
  constexpr double kSlack = 1e-9;
  for (const Cell& c : cells) {
    if (c.objects == 0) continue;
    bool in = true;
    for (int a = 0; a < 3 && in; ++a)
      in = c.box.lo[a] - kSlack <= p[a] && p[a] <= c.box.hi[a] + kSlack;
    if (in) return true;
  }
  return false;
}

/// True when the box [lo, hi] meets a cell holding objects (closed, with the
/// same allowance).
bool meets_occupied(const std::vector<Cell>& cells, const Vec3& lo, const Vec3& hi) {
  constexpr double kSlack = 1e-9;
  for (const Cell& c : cells) {
    if (c.objects == 0) continue;
    bool meets = true;
    for (int a = 0; a < 3 && meets; ++a)
      meets = c.box.lo[a] - kSlack <= hi[a] && lo[a] <= c.box.hi[a] + kSlack;
    if (meets) return true;
  }
  return false;
}

class Cells : public ::testing::TestWithParam<Case> {};

TEST_P(Cells, EveryObjectLiesInTheCellsThatHoldIt) {
  const Case& c = GetParam();
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("spec " + c.spec + ", seed " + std::to_string(seed));
    Rng rng(seed);
    auto s = make_structure(c.spec);
    // Small objects well inside the world: no grid sends any to an overflow list.
    const auto random_shape = [&] {
      const Vec3 p{rng.uniform(50, 950), rng.uniform(50, 950), rng.uniform(50, 950)};
      const double r = rng.uniform(0.5, 12);
      return rng.below(2) == 0 ? Shape::sphere(p, r)
                               : Shape::box(p, {r, rng.uniform(0.5, 12), rng.uniform(0.5, 12)});
    };
    std::vector<Handle> live;
    for (int i = 0; i < 600; ++i)
      live.push_back(
          s->insert(random_shape(), i, c.settle && i % 2 == 0 ? Motion::fixed : Motion::dynamic));
    for (int i = 0; i < 200; ++i) s->update(live[rng.below(live.size())], random_shape());
    for (int i = 0; i < 150; ++i) {
      const std::size_t k = rng.below(live.size());
      s->remove(live[k]);
      live[k] = live.back();
      live.pop_back();
    }
    if (c.settle) s->settle();
    s->validate();

    const std::vector<Cell> cells = cells_of(*s);
    std::size_t counted = 0;
    for (const Cell& cell : cells) {
      counted += cell.objects;
      for (int a = 0; a < 3; ++a) ASSERT_LT(cell.box.lo[a], cell.box.hi[a]) << "an empty cell box";
    }
    if (c.counted == Counted::once)
      EXPECT_EQ(counted, s->size()) << "each object is held by exactly one node";
    else
      EXPECT_GE(counted, s->size()) << "each object is held by at least one cell";

    for (const Handle h : live) {
      const Aabb b = bounds(s->shape(h));
      if (c.holds == Holds::lower_corner) {
        const double extent = std::max({b.hi.x - b.lo.x, b.hi.y - b.lo.y, b.hi.z - b.lo.z});
        const double margin = 0.025 * extent;
        ASSERT_TRUE(meets_occupied(cells, b.lo - Vec3{margin, margin, margin}, b.lo))
            << "object " << s->user_data(h) << "'s lower corner";
        continue;
      }
      const Vec3 centre = (b.lo + b.hi) * 0.5;
      ASSERT_TRUE(in_occupied(cells, centre)) << "object " << s->user_data(h) << "'s centre";
      if (c.holds == Holds::centre) continue;
      for (int k = 0; k < 8; ++k) {
        const Vec3 corner{(k & 1) ? b.hi.x : b.lo.x, (k & 2) ? b.hi.y : b.lo.y,
                          (k & 4) ? b.hi.z : b.lo.z};
        ASSERT_TRUE(in_occupied(cells, corner))
            << "corner " << k << " of object " << s->user_data(h);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Structures, Cells, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& info) {
                           return testing::StructureParamName::identifier(info.param.spec);
                         });

TEST(Cells, TheWrapperReportsWhatTheStructureReports) {
  Octree direct;
  Erased<Octree> erased;
  Rng rng(7);
  for (int i = 0; i < 300; ++i) {
    const Shape s = Shape::sphere(
        {rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, rng.uniform(1, 5));
    direct.insert(s, i);
    erased.insert(s, i, Motion::dynamic);
  }
  std::vector<std::tuple<double, double, double, int, std::size_t>> a, b;
  direct.visit_cells([&](const Aabb& box, int level, std::size_t n) {
    a.emplace_back(box.lo.x, box.lo.y, box.lo.z, level, n);
  });
  const AnyBroadPhase& any = erased;
  EXPECT_TRUE(any.visit_cells([&](const Aabb& box, int level, std::size_t n) {
    b.emplace_back(box.lo.x, box.lo.y, box.lo.z, level, n);
  }));
  EXPECT_GT(a.size(), 8u);
  EXPECT_EQ(a, b);
}

TEST(Cells, StructuresWithoutCellsSaySo) {
  for (const char* spec : {"naive", "sap", "sort-sweep"}) {
    auto s = make_structure(spec);
    s->insert(Shape::sphere({1, 2, 3}, 1), 0);
    int visits = 0;
    EXPECT_FALSE(s->visit_cells([&](const Aabb&, int, std::size_t) { ++visits; })) << spec;
    EXPECT_EQ(visits, 0) << spec;
  }
}

TEST(Cells, GridVerletReportsItsLooseObjectsUntilSettled) {
  // Inserted one at a time, a few objects wait on the loose list (below
  // the rebuild threshold): each is reported as its own box, on the level
  // after the grids'; settle() puts them into the grids.
  GridVerlet g;
  std::vector<Aabb> boxes;
  for (int i = 0; i < 20; ++i) {
    const Shape s = Shape::sphere({50.0 * i + 10, 20, 30}, 2);
    g.insert(s, static_cast<std::uint64_t>(i));
    boxes.push_back(bounds(s));
  }
  auto objects_in_cells = [&g] {
    std::size_t held = 0;
    g.visit_cells([&](const Aabb&, int, std::size_t n) { held += n; });
    return held;
  };
  std::size_t loose = 0;
  g.visit_cells([&](const Aabb& box, int, std::size_t n) {
    EXPECT_EQ(n, 1u);
    bool covers = false;
    for (const Aabb& b : boxes)
      covers = covers || (box.lo.x <= b.lo.x && b.hi.x <= box.hi.x && box.lo.y <= b.lo.y &&
                          b.hi.y <= box.hi.y && box.lo.z <= b.lo.z && b.hi.z <= box.hi.z);
    EXPECT_TRUE(covers) << "a loose object's cell is its own box, rounded outwards";
    ++loose;
  });
  EXPECT_EQ(loose, boxes.size());
  g.settle();
  g.validate();
  EXPECT_EQ(objects_in_cells(), boxes.size());
}

TEST(Cells, TheOptionsShapeTheCells) {
  // The picture of `octree:split=16` is not that of `octree:split=4`.
  Rng rng(11);
  auto coarse = make_structure("octree:split=16");
  auto fine = make_structure("octree:split=4");
  for (int i = 0; i < 400; ++i) {
    const Shape s = Shape::sphere(
        {rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(0, 1000)}, rng.uniform(1, 5));
    coarse->insert(s, i);
    fine->insert(s, i);
  }
  std::size_t n_coarse = 0, n_fine = 0;
  coarse->visit_cells([&](const Aabb&, int, std::size_t) { ++n_coarse; });
  fine->visit_cells([&](const Aabb&, int, std::size_t) { ++n_fine; });
  EXPECT_GT(n_fine, n_coarse);
}

}  // namespace
}  // namespace broadphase
