#include "../register.hpp"

#include <broadphase/kdtree.hpp>
#include <broadphase/octree.hpp>
#include <broadphase/octree_linear.hpp>
#include <broadphase/octree_loose.hpp>

namespace broadphase::detail {

void register_trees(Registry& r) {
  add_structure<Octree>(r, "octree",
                        "adaptive octree: leaves split past split= objects, O(1) removal");
  add_structure<LooseOctree>(r, "octree-loose",
                             "loose octree (k=2): node from size and centre in O(1), sparse");
  add_structure<LinearOctree>(r, "octree-linear",
                              "linear octree: Morton keys in a hash table, no child links");
  add_structure<KdTree>(r, "kdtree",
                        "k-d tree, SAH splits on any axis, refitted, rebuilt when it decays");
}

}  // namespace broadphase::detail
