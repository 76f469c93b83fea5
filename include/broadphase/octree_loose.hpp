/// \file octree_loose.hpp
/// `octree-loose`: a loose octree. Every cell's box is enlarged by a factor
/// `k` around its centre, so an object's node follows from its size (the
/// depth) and its centre (the cell) in O(1), with no descent. Only occupied
/// nodes and their ancestors exist: a table of (depth, cell) keys finds a
/// node, child links let queries descend through occupied nodes only.
#pragma once

#include <algorithm>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/octree.hpp>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

/// The options of LooseOctree (`octree-loose:k=K,depth=N`).
struct LooseOctreeOptions {
  /// Loose factor: a node's box is k times its cell, in [1.1, 8]. Default 2.
  double k = 2;
  /// Deepest level, in [0, 20]. Default 4: deeper levels cost more traversal
  /// than they save (docs/octrees.md).
  int depth = 4;
  /// Throws InvalidConfig for a value out of range (detail/structure_base.hpp).
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static LooseOctreeOptions from(const OptionText& text);
};

/// A sparse loose octree with objects placed by size and centre.
///
/// Placement: the depth is the deepest one whose margin ((k - 1) / 2 cell
/// sides) covers the object's extent around its centre, the cell the one
/// holding the centre; placement is then verified exactly against the
/// node's loose box and moves shallower if rounding or a centre outside the
/// world says so. Objects that fit nowhere (outside the world, larger than
/// it) live at the root, which is never culled.
///
/// insert, remove, update: O(1) expected (plus creating or pruning the
/// ancestors of a new or emptied node). query: descends occupied nodes
/// whose loose box touches the query. for_each_pair: each object searches
/// the nodes at its own depth and deeper; pairs at the same depth are taken
/// from the node with the smaller index, so each is met once. Handles stay
/// valid until their object is removed. Mutations need exclusive access;
/// const members may run concurrently.
class LooseOctree : public detail::StoreBase<LooseOctree> {
 public:
  using Options = LooseOctreeOptions;
  /// Reads the deprecated Config::options map into LooseOctreeOptions.
  /// Throws InvalidConfig.
  explicit LooseOctree(const Config& c = {})
      : LooseOctree(without_options(c), LooseOctreeOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (LooseOctreeOptions::check).
  LooseOctree(const Config& c, const LooseOctreeOptions& o);

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves or resizes an object. Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object overlapping `q`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    return detail::tree_query(*this, store_, q, visitor);
  }
  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair once.
  template <class V>
  QueryCost walk_pairs(V& visitor) const;
  /// Casts a ray (HasRayCast): front to back through the nodes whose boxes
  /// the ray enters before its live tmax (detail/ray_walk.hpp); the root,
  /// which also holds the objects outside the cube, is always opened.
  /// Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    return detail::tree_cast_ray(*this, store_, r, visitor);
  }

  /// Bytes held (capacities of every array and table). O(nodes).
  std::size_t memory_bytes() const;
  /// Checks placement, positions, loose boxes, links, the key table and
  /// that no empty leaf survives.
  void validate() const;
  /// Reports every node: its cell (not the loose box around it; an object may
  /// reach into the margin), its depth, the objects it holds. O(nodes).
  void visit_cells(CellVisitor visitor) const;

  /// Nodes in use (for the lab).
  std::size_t node_count() const { return nodes_.size() - free_.size(); }

  // The nested-tree interface of detail::tree_query, public so that the
  // template can read the nodes; not for users.
  /// The root node's index.
  std::uint32_t root() const { return 0; }
  /// The object records held by node `n`.
  std::span<const detail::OctItem> items(std::uint32_t n) const { return nodes_[n].items; }
  /// Node `n`'s loose box, holding every object below it (not the root's).
  const Aabb& box(std::uint32_t n) const { return nodes_[n].loose; }
  /// Calls `f(child)` for each existing child of `n`.
  template <class F>
  void for_each_child(std::uint32_t n, F&& f) const {
    for (std::uint32_t c : nodes_[n].child)
      if (c != detail::kNoNode) f(c);
  }

 private:
  struct Node {
    Aabb loose;
    std::vector<detail::OctItem> items;
    std::uint64_t key = 1;
    std::uint32_t parent = detail::kNoNode;
    std::uint32_t child[8] = {detail::kNoNode, detail::kNoNode, detail::kNoNode, detail::kNoNode,
                              detail::kNoNode, detail::kNoNode, detail::kNoNode, detail::kNoNode};
    std::uint32_t ix = 0, iy = 0, iz = 0;
    std::uint8_t depth = 0;
    std::uint8_t children = 0;
  };
  struct Place {
    int depth;
    std::uint32_t ix, iy, iz;
  };

  Aabb loose_box(int depth, std::uint32_t ix, std::uint32_t iy, std::uint32_t iz) const;
  Place place_of(const Shape& s) const;
  std::uint32_t node_at(const Place& p);
  void prune(std::uint32_t node);

  detail::Cube cube_;
  double margin_ = 0;  // (k - 1) / 2 world sides: the margin at depth 0
  int max_depth_ = 4;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> free_;
  detail::KeyTable table_;   // key -> node
  detail::ItemIndex index_;  // slot -> node and position
};

template <class V>
QueryCost LooseOctree::walk_pairs(V& visitor) const {
  // Loose cells overlap, so partners may sit in any subtree whose loose box
  // touches. The pairs are split into disjoint groups by a traversal of the
  // tree against itself:
  //  - within(n): the pairs inside n's subtree = the pairs among n's objects
  //    + n's objects against each child's subtree + within(child) for each
  //    child + between(ci, cj) for each two children whose loose boxes touch;
  //  - between(a, b), for disjoint subtrees: a's objects against b's subtree
  //    + between(child of a, b) for each child of a touching b.
  // Each pair lands in exactly one group; subtrees are culled by loose boxes,
  // which hold every object below them (the root, which also holds objects
  // outside the world, is never culled).
  QueryCost cost;
  struct Task {
    std::uint32_t a, b;  // a == b: within(a); else between(a, b)
  };
  detail::InlineStack<Task, 128> tasks;
  detail::InlineStack<std::uint32_t, 64> sub;
  // a's objects (at least one) against the subtree of b (b != a, b below
  // or beside a). Only b itself is not culled: callers check it.
  auto objects_against = [&](const Node& a, std::uint32_t b) {
    // Cull by the union of a's objects, often much smaller than a's loose box.
    AabbF reach = a.items[0].box;
    for (const detail::OctItem& x : a.items)
      for (int k = 0; k < 3; ++k) {
        reach.lo[k] = std::min(reach.lo[k], x.box.lo[k]);
        reach.hi[k] = std::max(reach.hi[k], x.box.hi[k]);
      }
    const Aabb rb = detail::to_double(reach);
    sub.clear();
    sub.push(b);
    while (!sub.empty()) {
      const Node& m = nodes_[sub.pop()];
      if (!m.items.empty())
        for (const detail::OctItem& x : a.items)
          if ((a.items.size() == 1 || m.loose.overlaps(detail::to_double(x.box))) &&
              !detail::test_against(store_, x, std::span<const detail::OctItem>(m.items), 0, cost,
                                    visitor))
            return false;
      for (std::uint32_t c : m.child)
        if (c != detail::kNoNode && nodes_[c].loose.overlaps(rb)) sub.push(c);
    }
    return true;
  };
  // The root's loose box does not bound its objects: search all of the
  // root's subtree for them, culling per object only.
  auto root_objects_against = [&](std::uint32_t b) {
    for (const detail::OctItem& x : nodes_[0].items) {
      const Aabb xb = detail::to_double(x.box);
      sub.clear();
      sub.push(b);
      while (!sub.empty()) {
        const Node& m = nodes_[sub.pop()];
        if (!detail::test_against(store_, x, std::span<const detail::OctItem>(m.items), 0, cost,
                                  visitor))
          return false;
        for (std::uint32_t c : m.child)
          if (c != detail::kNoNode && nodes_[c].loose.overlaps(xb)) sub.push(c);
      }
    }
    return true;
  };
  tasks.push({0, 0});
  while (!tasks.empty()) {
    const Task t = tasks.pop();
    const Node& a = nodes_[t.a];
    if (t.a == t.b) {
      const std::span<const detail::OctItem> its = a.items;
      for (std::size_t i = 0; i + 1 < its.size(); ++i)
        if (!detail::test_against(store_, its[i], its, i + 1, cost, visitor)) return cost;
      for (int i = 0; i < 8; ++i) {
        const std::uint32_t ci = a.child[i];
        if (ci == detail::kNoNode) continue;
        if (!its.empty()) {
          if (t.a == 0 ? !root_objects_against(ci)
                       : (nodes_[ci].loose.overlaps(a.loose) && !objects_against(a, ci)))
            return cost;
        }
        tasks.push({ci, ci});
        for (int j = i + 1; j < 8; ++j) {
          const std::uint32_t cj = a.child[j];
          if (cj != detail::kNoNode && nodes_[ci].loose.overlaps(nodes_[cj].loose))
            tasks.push({ci, cj});
        }
      }
      continue;
    }
    const Node& b = nodes_[t.b];
    if (!a.items.empty() && !objects_against(a, t.b)) return cost;
    for (std::uint32_t c : a.child)
      if (c != detail::kNoNode && nodes_[c].loose.overlaps(b.loose)) tasks.push({c, t.b});
  }
  return cost;
}

}  // namespace broadphase
