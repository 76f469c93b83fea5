#include <broadphase/aabb_tree.hpp>
#include <broadphase/kdtree.hpp>
#include <broadphase/octree.hpp>
#include <broadphase/octree_linear.hpp>
#include <broadphase/octree_loose.hpp>
#include <broadphase/sap.hpp>
#include <broadphase/sort_sweep.hpp>

#include "register.hpp"

namespace broadphase {

OctreeOptions OctreeOptions::from(const OptionText& text) {
  OptionReader r(text, "octree");
  OctreeOptions o;
  o.split = detail::narrow<std::size_t>(r.integer("split", o.split));
  r.finish();
  return o;
}

LooseOctreeOptions LooseOctreeOptions::from(const OptionText& text) {
  OptionReader r(text, "octree-loose");
  LooseOctreeOptions o;
  o.k = r.number("k", o.k);
  o.depth = detail::narrow<int>(r.integer("depth", static_cast<std::uint64_t>(o.depth)));
  r.finish();
  return o;
}

LinearOctreeOptions LinearOctreeOptions::from(const OptionText& text) {
  OptionReader r(text, "octree-linear");
  LinearOctreeOptions o;
  o.depth = detail::narrow<int>(r.integer("depth", static_cast<std::uint64_t>(o.depth)));
  r.finish();
  return o;
}

KdTreeOptions KdTreeOptions::from(const OptionText& text) {
  OptionReader r(text, "kdtree");
  KdTreeOptions o;
  const std::string p = r.choice("rebuild", "decay", {"refit", "decay", "always"});
  o.rebuild = p == "refit"    ? KdTreePolicy::refit
              : p == "always" ? KdTreePolicy::always
                              : KdTreePolicy::decay;
  o.decay = r.number("decay", o.decay);
  o.leaf = detail::narrow<std::size_t>(r.integer("leaf", o.leaf));
  r.finish();
  return o;
}

SapOptions SapOptions::from(const OptionText& text) {
  OptionReader(text, "sap").finish();
  return {};
}

SortSweepOptions SortSweepOptions::from(const OptionText& text) {
  OptionReader(text, "sort-sweep").finish();
  return {};
}

AabbTreeOptions AabbTreeOptions::from(const OptionText& text) {
  OptionReader r(text, "aabb-tree");
  AabbTreeOptions o;
  const double margin = r.number("margin", 0);
  if (text.count("margin") != 0) o.margin = margin;  // absent: from the world
  const std::string order = r.choice(
      "order", "leaves-first", {"leaves-first", "smaller-first", "hit-ratio", "near-far", "none"});
  o.order = order == "none"            ? AabbTreeOrder::none
            : order == "smaller-first" ? AabbTreeOrder::smaller_first
            : order == "hit-ratio"     ? AabbTreeOrder::hit_ratio
            : order == "near-far"      ? AabbTreeOrder::near_far
                                       : AabbTreeOrder::leaves_first;
  o.predict = r.number("predict", o.predict);
  o.max_depth = detail::narrow<std::uint32_t>(r.integer("max_depth", o.max_depth));
  const std::string front = r.choice("front", "off", {"off", "basic", "deferred"});
  o.front = front == "basic"      ? AabbTreeFront::basic
            : front == "deferred" ? AabbTreeFront::deferred
                                  : AabbTreeFront::off;
  r.finish();
  return o;
}

}  // namespace broadphase

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
  // aabb-tree with front=basic unless the options say otherwise.
  constexpr auto front = [](const Config& c, const OptionText& text) {
    OptionText with_front = text;
    with_front.try_emplace("front", "basic");
    return build_structure<AabbTree>(c, with_front);
  };
  r.add({"aabb-tree-front",
         "aabb-tree keeping the traversal front between frames (front=basic; also deferred)", false,
         [front](const Config& c) { return front(without_options(c), c.options); }, front});
}

}  // namespace broadphase::detail
