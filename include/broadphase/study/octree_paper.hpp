/// \file study/octree_paper.hpp
/// `octree-paper`: the study's octree, a fixed tree of depth 4 over the world
/// cube, made exact.
///
/// The 1 + 8 + 64 + 512 nodes exist from construction on, in arrays indexed
/// like a heap (the children of node i are 8i + 1 ... 8i + 8), so nothing is
/// allocated or freed as objects come and go except the nodes' index lists.
/// An object lives in the deepest node whose cube contains its conservative
/// bounds; an object that leaves the world cube, or is larger than it, lives
/// at the root and is tested by every query. Option `outside=clamp` instead
/// places such an object by its bounds clipped to the cube (an object near a
/// face goes to a node at that face, a far one to a corner node); this stays
/// exact because clipping keeps the cell formula monotone.
///
/// Containment and overlap of cubes are decided on integer cell coordinates
/// at the finest level, computed by one monotone formula (`cell_of`), never
/// by comparing against cube faces: because the formula is monotone, two
/// overlapping bounds always give overlapping cell ranges, so no pair is
/// lost to rounding wherever the objects are.
#pragma once

#include <algorithm>
#include <array>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace broadphase {

/// The options of OctreePaper (`octree-paper:outside=root|clamp`).
struct OctreePaperOptions {
  /// Where objects not inside the cube go: false (`outside=root`, default)
  /// the root, true (`outside=clamp`) the node of their bounds clamped into
  /// the cube.
  bool clamp_outside = false;
  /// Nothing to check (every value is valid).
  void check() const {}
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static OctreePaperOptions from(const OptionText& text);
};

/// The study's fixed-depth octree.
/// insert: O(1) plus an amortised list append. remove: O(length of the
/// object's node list), as in the study (the node is found in O(1), then its
/// list is searched). update: O(1) when the object stays in its node, else
/// a remove and an insert. query: the nodes on the way down that the query
/// overlaps. for_each_pair: each node's objects among themselves and against
/// the descendants they overlap.
/// Handles stay valid until their object is removed. Not thread-safe for
/// writers; const members may run concurrently.
class OctreePaper : public detail::StoreBase<OctreePaper> {
 public:
  /// Levels 0 (the root) to 3.
  static constexpr int kDepth = 4;
  /// The finest level, whose cells the node choice is computed on.
  static constexpr int kFinest = kDepth - 1;
  /// Cells per axis at the finest level.
  static constexpr int kFinestCells = 1 << kFinest;
  /// 1 + 8 + 64 + 512.
  static constexpr std::uint32_t kNodeCount = 585;

  /// Builds the empty tree over the cube with corner `c.world.lo` and side
  /// the world box's largest extent.
  using Options = OctreePaperOptions;
  /// Reads the deprecated Config::options map into OctreePaperOptions.
  /// Throws InvalidConfig.
  explicit OctreePaper(const Config& c = {})
      : OctreePaper(without_options(c), OctreePaperOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (OctreePaperOptions::check).
  OctreePaper(const Config& c, const OctreePaperOptions& o);

  /// Adds an object to the node its bounds prescribe. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic);
  /// Removes an object: finds its node from its bounds, then searches that
  /// node's list. Throws InvalidHandle.
  void remove(Handle h);
  /// Replaces an object's shape, moving it between nodes when needed.
  /// Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object whose shape overlaps `q` exactly. Tests every
  /// object of every node the query's bounds reach on the way down.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const;

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair exactly once.
  template <class V>
  QueryCost walk_pairs(V& visitor) const;

  /// Casts a ray (HasRayCast): front to back through the nodes whose cubes
  /// the ray enters before its live tmax (detail/ray_walk.hpp); the root,
  /// which holds the objects outside the cube, is always opened, and with
  /// `clamp_outside` the border nodes reach out to infinity. Throws
  /// InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const;

  /// The store (shapes, user data, generations), the node lists' capacities
  /// and the fixed node arrays.
  std::size_t memory_bytes() const;

  /// Checks that every live object is in exactly one node list, the one its
  /// bounds prescribe, and that the subtree counts agree with the lists.
  /// Throws std::logic_error.
  void validate() const;
  /// Reports every node with objects below it: its cube, its level, the
  /// objects it holds itself. O(nodes).
  void visit_cells(CellVisitor visitor) const;

  /// The node an object of shape `s` belongs in. O(1).
  std::uint32_t node_of(const Shape& s) const;
  /// The level (0 = root) of a node index.
  static int level_of(std::uint32_t node);
  /// The slot indices of the objects stored at `node` (for tests and tools).
  std::span<const std::uint32_t> objects_at(std::uint32_t node) const { return lists_[node]; }

 private:
  // A box of finest-level cells, each axis clamped to [0, kFinestCells).
  struct CellRange {
    int lo[3];
    int hi[3];
    bool empty;
  };
  // A node's level and cell coordinates at that level.
  struct NodeCell {
    int level;
    int x, y, z;
  };

  int cell_of(double v, int axis) const;
  CellRange range_of(const Aabb& b) const;
  static NodeCell decode(std::uint32_t node);
  void link(std::uint32_t node, std::uint32_t slot);
  void unlink(std::uint32_t node, std::uint32_t slot);

  // Calls f(node) for every proper descendant of `at` whose cube meets `r`,
  // skipping empty subtrees; stops when f returns false. Recursion depth is
  // at most kFinest, so no stack can overflow.
  template <class F>
  bool visit_descendants(std::uint32_t at, const NodeCell& cell, const CellRange& r, F& f) const;

  std::array<std::vector<std::uint32_t>, kNodeCount> lists_;  // slot indices per node
  std::array<std::uint32_t, kNodeCount> subtree_count_{};     // objects in each subtree
  Vec3 origin_;
  double scale_ = 0;            // finest cells per world unit
  bool clamp_outside_ = false;  // place outside objects by their clipped bounds
};

template <class F>
bool OctreePaper::visit_descendants(std::uint32_t at, const NodeCell& cell, const CellRange& r,
                                    F& f) const {
  if (cell.level == kFinest) return true;
  const int shift = kFinest - cell.level - 1;
  // The children's coordinates along each axis, cut to the range.
  int lo[3], hi[3];
  const int c[3] = {cell.x, cell.y, cell.z};
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(2 * c[a], r.lo[a] >> shift);
    hi[a] = std::min(2 * c[a] + 1, r.hi[a] >> shift);
  }
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y)
      for (int x = lo[0]; x <= hi[0]; ++x) {
        const std::uint32_t child =
            8 * at + 1 + static_cast<std::uint32_t>((x & 1) | ((y & 1) << 1) | ((z & 1) << 2));
        if (subtree_count_[child] == 0) continue;
        if (!lists_[child].empty() && !f(child)) return false;
        if (!visit_descendants(child, {cell.level + 1, x, y, z}, r, f)) return false;
      }
  return true;
}

template <class V>
QueryCost OctreePaper::query(const Shape& q, V&& visitor) const {
  require_valid(q);
  QueryCost cost;
  auto test_node = [&](std::uint32_t node) {
    for (std::uint32_t i : lists_[node]) {
      ++cost.tests;
      if (overlaps(q, store_.shape(i)) && !visit(visitor, store_.handle(i))) return false;
    }
    return true;
  };
  if (!test_node(0)) {
    cost.stopped = true;
    return cost;
  }
  const CellRange r = range_of(bounds(q));
  if (!r.empty && !visit_descendants(0, {0, 0, 0, 0}, r, test_node)) cost.stopped = true;
  return cost;
}

template <class V>
QueryCost OctreePaper::cast_ray(const Ray& r, V&& visitor) const {
  require_valid(r);
  detail::RayCast<std::remove_reference_t<V>> cast(store_, r, visitor);
  // A node's cube, grown by 2^-30 of its magnitude and side: an object is
  // placed by cell_of, whose rounding is a few ulps of |v| + |origin|, and
  // the side is at least 1/8 of the world's, so this covers it by far.
  auto cube = [&](std::uint32_t node) {
    const NodeCell c = decode(node);
    const double side = std::ldexp(1.0, kFinest - c.level) / scale_;
    const int cells = 1 << c.level;
    const int at[3] = {c.x, c.y, c.z};
    Aabb b;
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = origin_[a] + at[a] * side;
      b.hi[a] = origin_[a] + (at[a] + 1) * side;
      const double grow =
          0x1p-30 * (std::fabs(b.lo[a]) + std::fabs(b.hi[a]) + side + std::fabs(origin_[a]));
      b.lo[a] -= grow;
      b.hi[a] += grow;
      if (clamp_outside_ && at[a] == 0) b.lo[a] = -std::numeric_limits<double>::infinity();
      if (clamp_outside_ && at[a] == cells - 1) b.hi[a] = std::numeric_limits<double>::infinity();
    }
    return b;
  };
  detail::ray_tree_walk(
      cast, 0, 0.0, cube,
      [&](std::uint32_t n, auto&& f) {
        if (level_of(n) == kFinest) return;
        for (std::uint32_t k = 1; k <= 8; ++k)
          if (subtree_count_[8 * n + k] != 0) f(8 * n + k);
      },
      [&](std::uint32_t n) {
        for (std::uint32_t i : lists_[n])
          if (!cast.test(i)) return false;
        return true;
      });
  return cast.cost;
}

template <class V>
QueryCost OctreePaper::walk_pairs(V& visitor) const {
  QueryCost cost;
  for (std::uint32_t node = 0; node < kNodeCount; ++node) {
    const std::vector<std::uint32_t>& list = lists_[node];
    if (list.empty()) continue;
    const NodeCell cell = decode(node);
    const bool below = subtree_count_[node] > list.size();
    for (std::size_t a = 0; a < list.size(); ++a) {
      const std::uint32_t ia = list[a];
      const Shape& sa = store_.shape(ia);
      for (std::size_t b = a + 1; b < list.size(); ++b) {
        if (!detail::admits(visitor, ia, list[b])) continue;
        ++cost.tests;
        if (overlaps(sa, store_.shape(list[b])) &&
            !visit(visitor, store_.handle(ia), store_.handle(list[b]))) {
          cost.stopped = true;
          return cost;
        }
      }
      if (!below) continue;
      // A pair between a node and one of its descendants is found from the
      // ancestor's side only; nodes that are not in one line hold disjoint
      // cell ranges, so their objects cannot overlap.
      const CellRange r = range_of(bounds(sa));
      if (r.empty) continue;
      auto test_node = [&](std::uint32_t d) {
        for (std::uint32_t j : lists_[d]) {
          if (!detail::admits(visitor, ia, j)) continue;
          ++cost.tests;
          if (overlaps(sa, store_.shape(j)) && !visit(visitor, store_.handle(ia), store_.handle(j)))
            return false;
        }
        return true;
      };
      if (!visit_descendants(node, cell, r, test_node)) {
        cost.stopped = true;
        return cost;
      }
    }
  }
  return cost;
}

}  // namespace broadphase
