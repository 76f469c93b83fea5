#include "register.hpp"

#include <broadphase/study/hgrid_paper.hpp>
#include <broadphase/naive.hpp>
#include <broadphase/study/octree_paper.hpp>

namespace broadphase::detail {

void register_study(Registry& r) {
  add_structure<Naive>(r, "naive",
                       "tests every pair, O(n^2): the study's base case and the oracle");
  add_structure<OctreePaper>(r, "octree-paper",
                             "the study's octree: fixed depth 4 over the world cube, objects at "
                             "the deepest node containing them");
  add_structure<HGridPaper>(
      r, "hgrid-paper",
      "the study's hierarchical hashed grid: levels of 2^k cells per axis in one hash table");
}

}  // namespace broadphase::detail
