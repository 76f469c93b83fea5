#include "../register.hpp"

#include <broadphase/octree.hpp>

namespace broadphase::detail {

void register_trees(Registry& r) {
  add_structure<Octree>(r, "octree",
                        "adaptive octree: leaves split past split= objects, O(1) removal");
}

}  // namespace broadphase::detail
