/// \file octree_loose.hpp
/// `octree-loose`: a loose octree. Every cell's box is enlarged by a factor
/// `k` around its centre, so an object's node follows from its size (the
/// depth) and its centre (the cell) in O(1), with no descent. Only occupied
/// nodes and their ancestors exist: a table of (depth, cell) keys finds a
/// node, child links let queries descend through occupied nodes only.
#pragma once

#include <algorithm>
#include <broadphase/octree.hpp>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

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
class LooseOctree {
 public:
  /// Options: `k=` (loose factor in [1.1, 8], default 2), `depth=` (deepest
  /// level, default 10, at most 20).
  explicit LooseOctree(const Config& c = {});

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves or resizes an object. Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object overlapping `q`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    return detail::tree_query(*this, store_, q, visitor);
  }
  /// Visits every overlapping pair once.
  template <class V>
  QueryCost for_each_pair(V&& visitor) const;

  std::size_t size() const { return store_.size(); }
  std::size_t memory_bytes() const;
  bool contains(Handle h) const { return store_.contains(h); }
  const Shape& shape(Handle h) const { return store_.shape_of(h); }
  std::uint64_t user_data(Handle h) const { return store_.user_data(h); }
  /// Checks placement, positions, loose boxes, links, the key table and
  /// that no empty leaf survives.
  void validate() const;

  /// Nodes in use (for the lab).
  std::size_t node_count() const { return nodes_.size() - free_.size(); }

  // The nested-tree interface of detail::tree_query.
  std::uint32_t root() const { return 0; }
  std::span<const detail::OctItem> items(std::uint32_t n) const { return nodes_[n].items; }
  const Aabb& box(std::uint32_t n) const { return nodes_[n].loose; }
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
  void attach(std::uint32_t node, std::uint32_t slot, const AabbF& box);
  void detach(std::uint32_t slot);
  void prune(std::uint32_t node);

  ObjectStore store_;
  detail::Cube cube_;
  double margin_ = 0;  // (k - 1) / 2 world sides: the margin at depth 0
  int max_depth_ = 10;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> free_;
  detail::KeyTable table_;              // key -> node
  std::vector<std::uint32_t> node_of_;  // slot -> node
  std::vector<std::uint32_t> pos_of_;   // slot -> position in the node's items
};

template <class V>
QueryCost LooseOctree::for_each_pair(V&& visitor) const {
  // Loose cells overlap, so partners may sit anywhere in the tree. For each
  // node, one search from the root collects the nodes whose loose box
  // touches the node's objects and that are deeper, or at the same depth
  // with a larger index (shallower nodes are only passed through). Every
  // pair is thus met once: from its shallower object, or at equal depths
  // from the node with the smaller index, or inside one node.
  QueryCost cost;
  detail::InlineStack<std::uint32_t, 64> nodes;
  detail::InlineStack<std::uint32_t, 64> sub;
  detail::InlineStack<std::uint32_t, 256> partners;
  nodes.push(0);
  while (!nodes.empty()) {
    const std::uint32_t n = nodes.pop();
    const Node& node = nodes_[n];
    for (std::uint32_t c : node.child)
      if (c != detail::kNoNode) nodes.push(c);
    const std::span<const detail::OctItem> its = node.items;
    if (its.empty()) continue;
    AabbF reach = its[0].box;
    for (const detail::OctItem& it : its)
      for (int a = 0; a < 3; ++a) {
        reach.lo[a] = std::min(reach.lo[a], it.box.lo[a]);
        reach.hi[a] = std::max(reach.hi[a], it.box.hi[a]);
      }
    const Aabb rb = detail::to_double(reach);
    partners.clear();
    sub.clear();
    sub.push(0);
    while (!sub.empty()) {
      const std::uint32_t m = sub.pop();
      const Node& other = nodes_[m];
      if (m != n && !other.items.empty() &&
          (other.depth > node.depth || (other.depth == node.depth && m > n)))
        partners.push(m);
      for (std::uint32_t c : other.child)
        if (c != detail::kNoNode && nodes_[c].loose.overlaps(rb)) sub.push(c);
    }
    for (std::size_t i = 0; i < its.size(); ++i) {
      const detail::OctItem& a = its[i];
      if (!detail::test_against(store_, a, its, i + 1, cost, visitor)) return cost;
      const Aabb ab = detail::to_double(a.box);
      for (std::size_t p = 0; p < partners.size(); ++p) {
        const Node& other = nodes_[partners[p]];
        if (other.loose.overlaps(ab) &&
            !detail::test_against(store_, a, std::span<const detail::OctItem>(other.items), 0, cost,
                                  visitor))
          return cost;
      }
    }
  }
  return cost;
}

}  // namespace broadphase
