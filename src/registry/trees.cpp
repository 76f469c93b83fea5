#include "register.hpp"

#include <broadphase/aabb_tree.hpp>
#include <broadphase/kdtree.hpp>
#include <broadphase/octree.hpp>
#include <broadphase/octree_linear.hpp>
#include <broadphase/octree_loose.hpp>
#include <broadphase/sap.hpp>
#include <broadphase/sort_sweep.hpp>

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
  add_structure<Sap>(r, "sap",
                     "incremental 3-axis sweep-and-prune: sorted endpoints kept by insertion sort, "
                     "pair set updated at each crossing");
  add_structure<SortSweep>(r, "sort-sweep",
                           "batch sweep-and-prune: radix sort on the axis of largest variance "
                           "each frame, then sweep");
  add_structure<AabbTree>(r, "aabb-tree",
                          "dynamic AABB tree: fat leaves, surface-area insertion, rotations, "
                          "self-traversal (options margin, order, max_depth, front)");
  r.add({"aabb-tree-front",
         "aabb-tree keeping the traversal front between frames (front=basic; also deferred)", false,
         [](const Config& c) -> std::unique_ptr<AnyBroadPhase> {
           Config with_front = c;
           with_front.options.try_emplace("front", "basic");
           return std::make_unique<Erased<AabbTree>>(with_front, "aabb-tree-front");
         }});
}

}  // namespace broadphase::detail
