#include "../register.hpp"

#include <broadphase/sap.hpp>
#include <broadphase/sort_sweep.hpp>

namespace broadphase::detail {

void register_trees(Registry& r) {
  add_structure<Sap>(r, "sap",
                     "incremental 3-axis sweep-and-prune: sorted endpoints kept by insertion sort, "
                     "pair set updated at each crossing");
  add_structure<SortSweep>(r, "sort-sweep",
                           "batch sweep-and-prune: radix sort on the axis of largest variance "
                           "each frame, then sweep");
}

}  // namespace broadphase::detail
