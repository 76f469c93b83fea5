/// \file kdtree.hpp
/// `kdtree`: a k-d tree over object centres whose nodes carry the bounds of
/// their subtree. Each node's split axis and plane are chosen by the surface
/// area heuristic (any axis, not cycled). Motion is absorbed by refitting the
/// bounds; a rebuild policy decides when the refitted tree has decayed
/// enough to be rebuilt.
#pragma once

#include <broadphase/detail/level_grid.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/octree.hpp>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

/// How a KdTree reacts to motion (option `rebuild`).
enum class KdTreePolicy : std::uint8_t {
  refit,   ///< never rebuild for motion
  decay,   ///< rebuild when the nodes' surface areas grew past `decay` times
  always,  ///< rebuild after every update call
};

/// The options of KdTree (`kdtree:rebuild=refit|decay|always,decay=D,leaf=N`).
struct KdTreeOptions {
  /// When to rebuild for motion. Default decay.
  KdTreePolicy rebuild = KdTreePolicy::decay;
  /// The surface-area growth that triggers a rebuild under `decay`, in
  /// [1, 1e6]. Default 1.5.
  double decay = 1.5;
  /// Objects per leaf, in [1, 1024]. Default 8.
  std::size_t leaf = 8;
  /// Throws InvalidConfig for a value out of range.
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static KdTreeOptions from(const OptionText& text);
};

/// A k-d tree with refitted bounds and a rebuild policy.
///
/// Objects are partitioned by their centres at build time; afterwards an
/// object stays in its leaf when it moves, and the leaf's and ancestors'
/// boxes are refitted (each node's box is exactly the union of its objects'
/// float boxes). Options:
///  - `rebuild=refit` never rebuilds for motion; `rebuild=decay` (default)
///    rebuilds when the sum of the nodes' surface areas exceeds `decay=`
///    (default 1.5) times its value after the last build; `rebuild=always`
///    rebuilds after every update call (a bulk update is one call).
///  - `leaf=` objects per leaf (default 8).
/// Every policy also rebuilds when the object count has doubled or halved
/// since the last build, so insertion order does not shape the tree.
///
/// insert: O(depth), amortised O(log n) for rebuilds. remove: O(1) to find
/// the object, O(depth) to refit. update: O(depth) refit; bulk update: one
/// O(nodes) refit. Rebuild: O(n log n). query: descends touching nodes with
/// a growable stack. for_each_pair: simultaneous traversal of the tree
/// against itself with a growable stack, each pair met once. Handles stay
/// valid until their object is removed. Mutations need exclusive access;
/// const members may run concurrently.
class KdTree : public detail::StoreBase<KdTree> {
 public:
  /// How the tree reacts to motion.
  using Policy = KdTreePolicy;

  using Options = KdTreeOptions;
  /// Reads the deprecated Config::options map into KdTreeOptions.
  /// Throws InvalidConfig.
  explicit KdTree(const Config& c = {})
      : KdTree(without_options(c), KdTreeOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (KdTreeOptions::check).
  KdTree(const Config& c, const KdTreeOptions& o);

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves or resizes one object (refits its path). Throws InvalidHandle,
  /// InvalidShape.
  void update(Handle h, const Shape& s);
  /// Moves many objects, then refits the whole tree once. All-or-nothing:
  /// throws InvalidHandle, InvalidShape before moving anything; a repeated
  /// handle takes its last move.
  void update(std::span<const Move> moves);

  /// Visits every object overlapping `q`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const;
  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair once.
  template <class V>
  QueryCost walk_pairs(V& visitor) const;
  /// Casts a ray (HasRayCast): front to back through the nodes whose boxes
  /// the ray enters before its live tmax (detail/ray_walk.hpp). Throws
  /// InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const;
  /// The closest hit of each ray into `out` (as long as `rays`,
  /// std::invalid_argument): closest_hit(*this, rays[i]) bit for bit, with
  /// several rays walked at once, a step of each in turn, so that one's
  /// loads arrive while the others work. Throws InvalidRay, naming the
  /// first invalid ray, before casting any.
  /// From `flights_from` objects on (detail::kRayFlightsFrom: where it was
  /// measured faster); below, one ray at a time.
  void closest_hits(std::span<const Ray> rays, std::span<RayHit> out,
                    std::size_t flights_from = detail::kRayFlightsFrom) const;

  /// Bytes held (capacities of every array and table). O(nodes).
  std::size_t memory_bytes() const;
  /// Checks positions, exact refitted boxes, links and the free list.
  void validate() const;
  /// Reports every node: its box (fitted to the objects below it), its depth,
  /// the objects it holds (leaves only). O(nodes).
  void visit_cells(CellVisitor visitor) const;

  /// Rebuilds the tree from scratch with the surface area heuristic.
  void rebuild();
  /// How many rebuilds happened (for the lab).
  std::uint64_t rebuilds() const { return rebuilds_; }
  /// Sum of the nodes' surface areas now and after the last build.
  double surface_sum() const { return surface_; }
  double built_surface_sum() const { return built_surface_; }

 private:
  struct Node {
    AabbF box;
    std::vector<detail::OctItem> items;  // leaves only
    std::uint32_t parent = detail::kNoNode;
    std::uint32_t left = detail::kNoNode;  // leaf when kNoNode
    std::uint32_t right = detail::kNoNode;
    float split = 0;  // insertion goes left when centre[axis] < split
    std::uint8_t axis = 0;
  };
  bool leaf(std::uint32_t n) const { return nodes_[n].left == detail::kNoNode; }
  // The ray walk's copy of a node, by node: an inner node's children and
  // their boxes, a leaf's items (child[0] is kNoNode). A step of the walk
  // reads this one cache line where it read both children's nodes, or a
  // leaf's node before its items: the walk waited on those loads for most
  // of its time (perf, 10^5 uniform spheres), and with the copy (and the
  // prefetch of both children) casts ran 13 % faster (CPU time, medians of
  // 7 runs). Kept beside the nodes, not in them, so the pair walk reads
  // the 72-byte nodes it read before.
  struct LeafItems {
    const detail::OctItem* items;
    std::uint32_t count;
  };
  struct alignas(64) RayKids {
    union {
      AabbF box[2];    // inner node
      LeafItems leaf;  // leaf: nodes_[n].items' data and size
    };
    std::uint32_t child[2] = {detail::kNoNode, detail::kNoNode};
  };
  static_assert(sizeof(RayKids) == 64, "one cache line");
  // Sets node n's box, and its copy in its parent's RayKids.
  void set_box(std::uint32_t n, const AabbF& b);
  // Refreshes leaf n's RayKids after its items changed.
  void sync_leaf(std::uint32_t n) {
    ray_kids_[n].leaf = {nodes_[n].items.data(),
                         static_cast<std::uint32_t>(nodes_[n].items.size())};
  }

  // A cast's step at node n: an inner node's children (prefetched), false
  // at a leaf.
  bool ray_children(std::uint32_t n, detail::RayChildren& kids) const;
  // Culls leaf n's items two boxes at a time (RayCull::Within::enter2)
  // against tmax(), read before each pair, and calls take(item, that tmax)
  // for each the ray enters, in the leaf's order; false when take did.
  template <class Tmax, class Take>
  bool ray_items(std::uint32_t n, const detail::RayCull::Within& within, Tmax&& tmax,
                 Take&& take) const;
  // Tests leaf n's items; false when the visitor stopped.
  template <class Cast>
  bool ray_leaf(Cast& cast, const detail::RayCull::Within& within, std::uint32_t n) const;

  std::uint32_t new_node(std::uint32_t parent);
  void build(std::uint32_t node, std::size_t begin, std::size_t end);
  void split_leaf(std::uint32_t node);
  void refit_path(std::uint32_t node);
  void refit_all();
  void after_motion();
  void after_resize();

  Policy policy_ = Policy::decay;
  double decay_ = 1.5;
  std::size_t leaf_size_ = 8;
  std::vector<Node> nodes_;
  std::vector<RayKids> ray_kids_;  // by node, beside nodes_
  std::vector<std::uint32_t> free_;
  std::uint32_t root_ = 0;
  std::vector<detail::OctItem> scratch_;      // rebuild's working copy
  std::vector<std::uint32_t> scratch_order_;  // refit_all's node order
  bool order_stale_ = true;                   // scratch_order_ must be redone
  detail::ItemIndex index_;                   // slot -> leaf and position
  double surface_ = 0;
  double built_surface_ = 0;
  std::size_t built_size_ = 0;
  std::uint64_t rebuilds_ = 0;
};

template <class V>
QueryCost KdTree::query(const Shape& q, V&& visitor) const {
  require_valid(q);
  QueryCost cost;
  const AabbF qf = bounds_f(q);
  detail::InlineStack<std::uint32_t, 64> stack;
  stack.push(root_);
  while (!stack.empty()) {
    const Node& n = nodes_[stack.pop()];
    if (!n.box.overlaps(qf)) continue;
    if (n.left != detail::kNoNode) {
      stack.push(n.left);
      stack.push(n.right);
      continue;
    }
    for (const detail::OctItem& it : n.items) {
      if (!it.box.overlaps(qf)) continue;
      ++cost.tests;
      if (overlaps(q, store_.shape(it.slot)) && !visit(visitor, store_.handle(it.slot))) {
        cost.stopped = true;
        return cost;
      }
    }
  }
  return cost;
}

template <class V>
QueryCost KdTree::walk_pairs(V& visitor) const {
  // Pairs of subtrees: (n, n) stands for the pairs inside n; (a, b) with
  // a != b for the pairs with one object in each. A node's two children are
  // disjoint, so every object pair descends to exactly one stack entry.
  QueryCost cost;
  struct Task {
    std::uint32_t a, b;
  };
  detail::InlineStack<Task, 128> stack;
  stack.push({root_, root_});
  while (!stack.empty()) {
    const Task t = stack.pop();
    const Node& a = nodes_[t.a];
    if (t.a == t.b) {
      if (a.left == detail::kNoNode) {
        for (std::size_t i = 0; i < a.items.size(); ++i)
          if (!detail::test_against(store_, a.items[i], std::span<const detail::OctItem>(a.items),
                                    i + 1, cost, visitor))
            return cost;
        continue;
      }
      stack.push({a.left, a.left});
      stack.push({a.right, a.right});
      if (nodes_[a.left].box.overlaps(nodes_[a.right].box)) stack.push({a.left, a.right});
      continue;
    }
    const Node& b = nodes_[t.b];
    const bool a_leaf = a.left == detail::kNoNode;
    const bool b_leaf = b.left == detail::kNoNode;
    if (a_leaf && b_leaf) {
      for (const detail::OctItem& it : a.items)
        if (!detail::test_against(store_, it, std::span<const detail::OctItem>(b.items), 0, cost,
                                  visitor))
          return cost;
      continue;
    }
    // Descend the node with more objects under it, guessed by its box: the
    // larger box, unless it is a leaf.
    auto area = [](const AabbF& x) {
      return (x.hi[0] - x.lo[0]) * (x.hi[1] - x.lo[1]) + (x.hi[1] - x.lo[1]) * (x.hi[2] - x.lo[2]) +
             (x.hi[2] - x.lo[2]) * (x.hi[0] - x.lo[0]);
    };
    if (b_leaf || (!a_leaf && area(a.box) >= area(b.box))) {
      if (nodes_[a.left].box.overlaps(b.box)) stack.push({a.left, t.b});
      if (nodes_[a.right].box.overlaps(b.box)) stack.push({a.right, t.b});
    } else {
      if (nodes_[b.left].box.overlaps(a.box)) stack.push({t.a, b.left});
      if (nodes_[b.right].box.overlaps(a.box)) stack.push({t.a, b.right});
    }
  }
  return cost;
}

template <class V>
QueryCost KdTree::cast_ray(const Ray& r, V&& visitor) const {
  require_valid(r);
  detail::RayCast<std::remove_reference_t<V>> cast(store_, r, visitor);
  double t0;
  if (!cast.cull.enter(nodes_[root_].box, cast.tmax, t0)) return cast.cost;
  // Every node's and object's box lies inside the root's.
  const auto within = cast.cull.within(nodes_[root_].box);
  detail::ray_binary_walk(
      cast, within, root_, t0,
      [&](std::uint32_t n, detail::RayChildren& kids) { return ray_children(n, kids); },
      [&](std::uint32_t n) { return ray_leaf(cast, within, n); });
  return cast.cost;
}

inline bool KdTree::ray_children(std::uint32_t n, detail::RayChildren& kids) const {
  const RayKids& k = ray_kids_[n];
  if (k.child[0] == detail::kNoNode) return false;
  // Both children's lines on their way while the boxes are tested
  // (5 % faster casts, measured).
  detail::prefetch(&ray_kids_[k.child[0]]);
  detail::prefetch(&ray_kids_[k.child[1]]);
  kids = {{k.child[0], k.child[1]}, {&k.box[0], &k.box[1]}};
  return true;
}

template <class Tmax, class Take>
bool KdTree::ray_items(std::uint32_t n, const detail::RayCull::Within& within, Tmax&& tmax,
                       Take&& take) const {
  const RayKids& k = ray_kids_[n];
  const detail::OctItem* items = k.leaf.items;
  const std::uint32_t count = k.leaf.count;
  std::uint32_t i = 0;
  for (; i + 1 < count; i += 2) {
    double ta, tb;
    const double t = tmax();
    const unsigned in = within.enter2(items[i].box, items[i + 1].box, t, ta, tb);
    if ((in & 1) && !take(items[i], t)) return false;
    if ((in & 2) && !take(items[i + 1], t)) return false;
  }
  double t0;
  const double t = tmax();
  return i == count || !within.enter(items[i].box, t, t0) || take(items[i], t);
}

template <class Cast>
bool KdTree::ray_leaf(Cast& cast, const detail::RayCull::Within& within, std::uint32_t n) const {
  // Each item tested as culled; the second of a pair culled again if the
  // first's hit clipped the ray.
  return ray_items(
      n, within, [&] { return cast.tmax; },
      [&](const detail::OctItem& it, double culled) {
        return cast.tmax == culled ? cast.test(it.slot) : cast.test(it.slot, it.box, within);
      });
}

inline void KdTree::closest_hits(std::span<const Ray> rays, std::span<RayHit> out,
                                 std::size_t flights_from) const {
  detail::require_valid_batch(rays, out.size(), "KdTree::closest_hits");
  if (store_.size() < flights_from) {
    for (std::size_t i = 0; i < rays.size(); ++i) out[i] = closest_hit(*this, rays[i]);
    return;
  }
  detail::ray_binary_closest_hits(
      store_, root_, nodes_[root_].box, rays, out,
      [&](std::uint32_t n, detail::RayChildren& kids) { return ray_children(n, kids); },
      [&](std::uint32_t n) {
        const RayKids& k = ray_kids_[n];
        const char* p = reinterpret_cast<const char*>(k.leaf.items);
        const char* end = reinterpret_cast<const char*>(k.leaf.items + k.leaf.count);
        for (; p < end; p += 64) detail::prefetch(p);
      },
      [&](std::uint32_t n, const detail::RayCull::Within& within, double tmax, auto& found) {
        ray_items(
            n, within, [&] { return tmax; },
            [&](const detail::OctItem& it, double) {
              found.push({it.slot, &it.box});
              return true;
            });
      });
}

}  // namespace broadphase
