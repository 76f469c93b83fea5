/// \file octree.hpp
/// `octree`: an adaptive octree over a pool of nodes. Each object remembers
/// its node and its position in that node, so removal and update never
/// descend; a leaf splits when it holds more than `split` objects and a
/// subtree is merged back as soon as it is empty.
///
/// What the octrees and the k-d tree share (cell arithmetic, Morton keys,
/// the nested-tree traversals) is in detail/tree_walk.hpp.
#pragma once

#include <array>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/inline_stack.hpp>
#include <broadphase/detail/node_items.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/detail/tree_walk.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

namespace broadphase {

/// The options of Octree (`octree:split=N`).
struct OctreeOptions {
  /// Objects a leaf holds before it splits, in [1, 1000000]. Default 32: the
  /// frame time falls up to 16 and is flat beyond (docs/octrees.md).
  std::size_t split = 32;
  /// Throws InvalidConfig for a value out of range.
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static OctreeOptions from(const OptionText& text);
};

/// An adaptive octree with objects at the smallest cell that holds them.
///
/// Placement: an object goes down from the root while its conservative box
/// lies strictly on one side of every midplane of the current cell; objects
/// that straddle a midplane stay at that node, objects not inside the world
/// cube (Config::world made cubic) stay at the root. A leaf holding more
/// than `split` objects splits (depth at most kMaxDepth); children whose
/// subtree becomes empty are merged back into their parent.
///
/// insert: O(depth). remove: O(1) to find the object (node and position are
/// stored per object), O(depth) to maintain the subtree counts. update:
/// O(1) when the object stays in its node, else O(depth). query: output
/// sensitive, descends only into cells that touch the query. for_each_pair:
/// every object is tested against its own node and the touching cells of its
/// subtree. Handles stay valid until their object is removed. Mutations
/// need exclusive access; const members may run concurrently.
class Octree : public detail::StoreBase<Octree> {
 public:
  static constexpr int kMaxDepth = 20;

  using Options = OctreeOptions;
  /// Reads the deprecated Config::options map into OctreeOptions.
  /// Throws InvalidConfig.
  explicit Octree(const Config& c = {})
      : Octree(without_options(c), OctreeOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (OctreeOptions::check).
  Octree(const Config& c, const OctreeOptions& o);

  /// Adds an object. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves or resizes an object; O(1) when it stays in its node.
  /// Throws InvalidHandle, InvalidShape.
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
  QueryCost walk_pairs(V& visitor) const {
    return detail::nested_tree_pairs(*this, store_, visitor);
  }
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
  /// Checks placement, positions, subtree counts, merging and the free list.
  void validate() const;
  /// Reports every node with objects below it: its cell, its depth, the objects
  /// it holds itself. O(nodes).
  void visit_cells(CellVisitor visitor) const;

  /// Nodes in use (for the lab).
  std::size_t node_count() const { return nodes_.size() - 8 * free_blocks_.size(); }

  // The nested-tree interface of detail::tree_query and nested_tree_pairs,
  // public so that those templates can read the nodes; not for users.
  /// The root node's index.
  std::uint32_t root() const { return 0; }
  /// The object records held by node `n`.
  std::span<const detail::OctItem> items(std::uint32_t n) const { return nodes_[n].items; }
  /// A box holding every object below node `n` (not asked of the root).
  const Aabb& box(std::uint32_t n) const { return nodes_[n].cell; }
  /// Calls `f(child)` for each child of `n` with objects below it.
  template <class F>
  void for_each_child(std::uint32_t n, F&& f) const {
    const std::uint32_t first = nodes_[n].first_child;
    if (first == detail::kNoNode) return;
    for (std::uint32_t c = first; c < first + 8; ++c)
      if (nodes_[c].subtree != 0) f(c);
  }

 private:
  struct Node {
    Aabb cell;
    std::vector<detail::OctItem> items;
    std::uint32_t parent = detail::kNoNode;
    std::uint32_t first_child = detail::kNoNode;  // eight consecutive nodes
    std::uint32_t subtree = 0;                    // objects in this subtree
    std::uint32_t ix = 0, iy = 0, iz = 0;
    std::uint8_t depth = 0;
  };

  Vec3 mid(const Node& n) const;
  std::uint32_t descend(std::uint32_t from, const Aabb& b) const;
  void detach(std::uint32_t slot);
  void add_count(std::uint32_t node, int delta);
  int child_octant(std::uint32_t node, std::uint32_t slot, const Vec3& m) const;
  void split(std::uint32_t node);
  void merge_empty_above(std::uint32_t node);
  void free_children(std::uint32_t node);
  std::uint32_t allocate_children(std::uint32_t parent);

  detail::Cube cube_;
  std::size_t split_ = 32;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> free_blocks_;  // first nodes of free blocks of eight
  detail::ItemIndex index_;                 // slot -> node and position
};

}  // namespace broadphase
