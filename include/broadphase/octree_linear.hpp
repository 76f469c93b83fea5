/// \file octree_linear.hpp
/// `octree-linear`: a linear octree. Nodes are addressed by their Morton
/// locational code in a hash table and keep no child or parent links: a
/// child's key is `(key << 3) | octant`, a parent's `key >> 3`, and one byte
/// per node says which children exist.
///
/// Why: a pointer octree gives every node room for its children's links,
/// and most nodes are leaves, so most of that room is wasted (eight indices
/// per leaf, or eight allocated sibling nodes per split). Here a node is its
/// objects, its key and its cell coordinates; its box is recomputed from the
/// coordinates when a traversal needs it.
#pragma once

#include <bit>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/octree.hpp>
#include <cstdint>
#include <span>
#include <vector>

namespace broadphase {

/// The options of LinearOctree (`octree-linear:depth=N`).
struct LinearOctreeOptions {
  /// Deepest level, in [0, 20]. Default 4: chosen by measurement
  /// (docs/octrees.md).
  int depth = 4;
  /// Throws InvalidConfig for a value out of range.
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static LinearOctreeOptions from(const OptionText& text);
};

/// A pointerless octree with objects at the smallest cell (down to a fixed
/// maximum depth) that holds them strictly inside its ancestors' midplanes.
///
/// insert, update: O(depth) arithmetic to find the cell plus O(1) expected
/// table work. remove: O(1) expected (node and position are stored per
/// object). query: descends the occupied children of touching cells.
/// for_each_pair: every object is tested against its own node and the
/// touching cells below it. Objects outside the world cube live at the root.
/// Handles stay valid until their object is removed. Mutations need
/// exclusive access; const members may run concurrently.
class LinearOctree : public detail::StoreBase<LinearOctree> {
 public:
  using Options = LinearOctreeOptions;
  /// Reads the deprecated Config::options map into LinearOctreeOptions.
  /// Throws InvalidConfig.
  explicit LinearOctree(const Config& c = {})
      : LinearOctree(without_options(c), LinearOctreeOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (LinearOctreeOptions::check).
  LinearOctree(const Config& c, const LinearOctreeOptions& o);

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
  /// Checks placement, positions, child masks, the key table and that no
  /// empty leaf survives.
  void validate() const;
  /// Reports every node: its cell, its depth, the objects it holds. O(nodes).
  void visit_cells(CellVisitor visitor) const;

  /// Nodes in use (for the lab).
  std::size_t node_count() const { return table_.size(); }

  // The nested-tree interface of detail::tree_query and nested_tree_pairs,
  // public so that those templates can read the nodes; not for users.
  /// The root node's index.
  std::uint32_t root() const { return 0; }
  /// The object records held by node `n`.
  std::span<const detail::OctItem> items(std::uint32_t n) const { return nodes_[n].items; }
  /// Node `n`'s cell, recomputed from its indices (not asked of the root).
  Aabb box(std::uint32_t n) const {
    const Node& node = nodes_[n];
    return cube_.cell(node.depth, node.ix, node.iy, node.iz);
  }
  /// Calls `f(child)` for each existing child of `n` (one table lookup each).
  template <class F>
  void for_each_child(std::uint32_t n, F&& f) const {
    const Node& node = nodes_[n];
    for (unsigned m = node.child_mask; m != 0; m &= m - 1)
      f(table_.find((node.key << 3) | static_cast<unsigned>(std::countr_zero(m))));
  }

 private:
  struct Node {
    std::vector<detail::OctItem> items;
    std::uint64_t key = 1;
    std::uint32_t ix = 0, iy = 0, iz = 0;
    std::uint8_t depth = 0;
    std::uint8_t child_mask = 0;
  };

  std::uint64_t key_of(const Aabb& b) const;
  std::uint32_t node_at(std::uint64_t key);
  void prune(std::uint32_t node);

  detail::Cube cube_;
  int max_depth_ = 4;
  std::vector<Node> nodes_;
  std::vector<std::uint32_t> free_;
  detail::KeyTable table_;   // Morton key -> node
  detail::ItemIndex index_;  // slot -> node and position
};

}  // namespace broadphase
