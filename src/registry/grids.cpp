#include "register.hpp"

#include <broadphase/grid_dense.hpp>
#include <broadphase/grid_hashed.hpp>
#include <broadphase/grid_hybrid.hpp>
#include <broadphase/grid_implicit.hpp>
#include <broadphase/grid_static.hpp>
#include <broadphase/hgrid.hpp>

namespace broadphase::detail {

void register_grids(Registry& r) {
  add_structure<GridDense>(r, "grid-dense",
                           "uniform grid: dense cell array over the world, linked lists");
  add_structure<GridHashed>(r, "grid-hashed",
                            "uniform grid: cells hashed into a bucket table, unbounded world");
  add_structure<GridStatic>(
      r, "grid-static",
      "uniform grid: contiguous cells by counting sort, fixed pairs cached, rebuild/patch");
  add_structure<GridImplicit>(r, "grid-implicit",
                              "uniform grid as per-axis slab bit arrays, cells = AND of three");
  add_structure<HGrid>(r, "hgrid",
                       "hierarchical grid: power-of-two levels in one hash table, any size");
  add_structure<GridHybrid>(r, "grid-hybrid",
                            "coarse hashed grid whose cells hold x-sorted lists, swept");
}

}  // namespace broadphase::detail
