/// \file detail/tree_walk.hpp
/// What the octrees and the k-d tree share: the cell arithmetic of a cubic
/// world (`Cube`, octants, Morton keys), an open-addressing table of 64-bit
/// keys, and the traversals of a nested tree (`tree_query`,
/// `nested_tree_pairs`) over any tree that offers `root()`, `items(node)`,
/// `box(node)` and `for_each_child(node, f)`.
#pragma once

#include <array>
#include <broadphase/detail/inline_stack.hpp>
#include <broadphase/detail/node_items.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

namespace broadphase {

namespace detail {

/// The null node index.
inline constexpr std::uint32_t kNoNode = 0xffffffffu;

/// A float box widened to double (exact: every float is a double).
inline Aabb to_double(const AabbF& b) {
  return {{b.lo[0], b.lo[1], b.lo[2]}, {b.hi[0], b.hi[1], b.hi[2]}};
}

/// The cube the octrees subdivide: the world hint made cubic (same centre,
/// side the largest extent) and enlarged by kRootGrowth, so that objects
/// reaching a little over the world's walls still fit below the root
/// instead of piling up at it, and the cells' faces do not fall on the
/// walls, where objects often rest. Cell boundaries are `origin + i * (side / 2^d)`:
/// the product is exact real arithmetic rounded once, so the boundary of a
/// cell at depth d is bit-identical to the same boundary seen from depth
/// d + 1 (index 2i), and rounding is monotone; hence every child cell lies
/// inside its parent, exactly.
struct Cube {
  static constexpr double kRootGrowth = 1.25;
  Vec3 origin;
  double side = 1;

  /// The enlarged cube around a world hint. Throws std::invalid_argument
  /// for an empty or non-finite box.
  static Cube around(const Aabb& world) {
    if (!(world.lo.x <= world.hi.x && world.lo.y <= world.hi.y && world.lo.z <= world.hi.z) ||
        !std::isfinite(world.lo.x) || !std::isfinite(world.lo.y) || !std::isfinite(world.lo.z) ||
        !std::isfinite(world.hi.x) || !std::isfinite(world.hi.y) || !std::isfinite(world.hi.z))
      throw std::invalid_argument("broadphase: Config::world must be a non-empty finite box");
    double side = std::max(world.hi.x - world.lo.x,
                           std::max(world.hi.y - world.lo.y, world.hi.z - world.lo.z));
    if (!(side > 0)) side = 1;
    side *= kRootGrowth;
    Vec3 c = (world.lo + world.hi) * 0.5;
    // Finite corners farther apart than the largest double ([-1e308, 1e308]):
    // the largest cube whose cell boundaries stay finite, around the
    // centre taken without overflow; objects beyond it live at the root.
    if (!std::isfinite(side)) side = std::numeric_limits<double>::max();
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(c[a])) c[a] = world.lo[a] * 0.5 + world.hi[a] * 0.5;
    return {c - Vec3{side, side, side} * 0.5, side};
  }
  /// Boundary `i` of the cells of depth `depth` along `axis`.
  double boundary(int axis, int depth, std::uint64_t i) const {
    return origin[axis] + static_cast<double>(i) * std::ldexp(side, -depth);
  }
  /// The closed box of cell (ix, iy, iz) at `depth`.
  Aabb cell(int depth, std::uint32_t ix, std::uint32_t iy, std::uint32_t iz) const {
    return {{boundary(0, depth, ix), boundary(1, depth, iy), boundary(2, depth, iz)},
            {boundary(0, depth, ix + 1ull), boundary(1, depth, iy + 1ull),
             boundary(2, depth, iz + 1ull)}};
  }
};

/// The octant of a cell's child that holds box `b` strictly on one side of
/// every midplane, or -1 when `b` touches or crosses one. Strictness is what
/// keeps the pairs exact: objects in two sibling subtrees are separated by
/// a plane neither touches, so they cannot overlap.
inline int strict_octant(const Aabb& b, const Vec3& mid) {
  int o = 0;
  for (int a = 0; a < 3; ++a) {
    if (b.hi[a] < mid[a]) continue;
    if (b.lo[a] > mid[a]) {
      o |= 1 << a;
      continue;
    }
    return -1;
  }
  return o;
}

/// Spreads the low 21 bits of `v` to every third bit.
inline std::uint64_t spread3(std::uint64_t v) {
  v &= 0x1fffffull;
  v = (v | v << 32) & 0x1f00000000ffffull;
  v = (v | v << 16) & 0x1f0000ff0000ffull;
  v = (v | v << 8) & 0x100f00f00f00f00full;
  v = (v | v << 4) & 0x10c30c30c30c30c3ull;
  v = (v | v << 2) & 0x1249249249249249ull;
  return v;
}

/// The locational code of a cell: a 1 bit, then `depth` Morton triples.
/// Depth 0 is 1; a child is `(parent << 3) | octant`. Unique for depth <= 20.
inline std::uint64_t morton_key(int depth, std::uint32_t ix, std::uint32_t iy, std::uint32_t iz) {
  return (1ull << (3 * depth)) | spread3(ix) | spread3(iy) << 1 | spread3(iz) << 2;
}

/// An open-addressing table from non-zero 64-bit keys to 32-bit values:
/// linear probing, at most half full, deletion by backward shift (no
/// tombstones), so a steady population never allocates.
class KeyTable {
 public:
  /// The value of `key`, or kNoNode. O(1) expected.
  std::uint32_t find(std::uint64_t key) const {
    if (keys_.empty()) return kNoNode;
    for (std::size_t i = home(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key) return values_[i];
      if (keys_[i] == 0) return kNoNode;
    }
  }
  /// Adds `key` (which must be absent). Amortised O(1).
  void insert(std::uint64_t key, std::uint32_t value) {
    if (2 * (size_ + 1) > keys_.size()) grow();
    std::size_t i = home(key);
    while (keys_[i] != 0) i = (i + 1) & mask_;
    keys_[i] = key;
    values_[i] = value;
    ++size_;
  }
  /// Removes `key` (which must be present). O(1) expected.
  void erase(std::uint64_t key) {
    std::size_t i = home(key);
    while (keys_[i] != key) i = (i + 1) & mask_;
    // Shift later entries of the probe run back into the hole, unless their
    // home lies cyclically after the hole (they would become unreachable).
    for (std::size_t j = (i + 1) & mask_; keys_[j] != 0; j = (j + 1) & mask_) {
      const std::size_t h = home(keys_[j]);
      if (((j - h) & mask_) >= ((j - i) & mask_)) {
        keys_[i] = keys_[j];
        values_[i] = values_[j];
        i = j;
      }
    }
    keys_[i] = 0;
    --size_;
  }
  /// Keys held.
  std::size_t size() const { return size_; }
  /// Bytes held (capacities).
  std::size_t memory_bytes() const {
    return keys_.capacity() * sizeof(std::uint64_t) + values_.capacity() * sizeof(std::uint32_t);
  }

 private:
  std::size_t home(std::uint64_t key) const {
    std::uint64_t z = key * 0x9E3779B97F4A7C15ull;
    return static_cast<std::size_t>(z ^ (z >> 29)) & mask_;
  }
  void grow() {
    std::vector<std::uint64_t> keys = std::move(keys_);
    std::vector<std::uint32_t> values = std::move(values_);
    const std::size_t cap = keys.empty() ? 64 : keys.size() * 2;
    keys_.assign(cap, 0);
    values_.assign(cap, 0);
    mask_ = cap - 1;
    size_ = 0;
    for (std::size_t i = 0; i < keys.size(); ++i)
      if (keys[i] != 0) insert(keys[i], values[i]);
  }

  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> values_;
  std::size_t mask_ = 0;
  std::size_t size_ = 0;
};

/// Visits every object of a tree that overlaps `q` exactly. The tree gives
/// `root()`, `items(node)`, `box(node)` (a box holding every object of the
/// node's subtree; never asked of the root, which may also hold objects
/// outside the world) and `for_each_child(node, f)` over occupied children.
template <class Tree, class V>
QueryCost tree_query(const Tree& t, const ObjectStore& store, const Shape& q, V& visitor) {
  QueryCost cost;
  const Aabb qb = bounds(q);
  const AabbF qf = bounds_f(q);
  InlineStack<std::uint32_t, 64> stack;
  stack.push(t.root());
  while (!stack.empty()) {
    const std::uint32_t n = stack.pop();
    for (const OctItem& it : t.items(n)) {
      if (!it.box.overlaps(qf)) continue;
      ++cost.tests;
      if (overlaps(q, store.shape(it.slot)) && !visit(visitor, store.handle(it.slot))) {
        cost.stopped = true;
        return cost;
      }
    }
    t.for_each_child(n, [&](std::uint32_t c) {
      if (t.box(c).overlaps(qb)) stack.push(c);
    });
  }
  return cost;
}

/// Tests `a` against the objects of `items` from `first` on; false when
/// the visitor asked to stop.
template <class V>
bool test_against(const ObjectStore& store, const OctItem& a, std::span<const OctItem> items,
                  std::size_t first, QueryCost& cost, V& visitor) {
  const Shape& sa = store.shape(a.slot);
  for (std::size_t j = first; j < items.size(); ++j) {
    const OctItem& b = items[j];
    // Branch-free: most candidates fail, and a chain of short-circuits
    // mispredicts on nearly every one of them.
    const bool touch = (a.box.lo[0] <= b.box.hi[0]) & (b.box.lo[0] <= a.box.hi[0]) &
                       (a.box.lo[1] <= b.box.hi[1]) & (b.box.lo[1] <= a.box.hi[1]) &
                       (a.box.lo[2] <= b.box.hi[2]) & (b.box.lo[2] <= a.box.hi[2]);
    if (!touch || !admits(visitor, a.slot, b.slot)) continue;
    ++cost.tests;
    if (overlaps(sa, store.shape(b.slot)) &&
        !visit(visitor, store.handle(a.slot), store.handle(b.slot))) {
      cost.stopped = true;
      return false;
    }
  }
  return true;
}

/// All pairs of a tree whose sibling subtrees cannot overlap (strict
/// octants): each object meets the later objects of its own node and the
/// objects of its descendants whose boxes it touches. Two objects overlap
/// only if one's node is an ancestor of (or is) the other's, so every pair
/// is met exactly once, from the shallower object (or the earlier one).
template <class Tree, class V>
QueryCost nested_tree_pairs(const Tree& t, const ObjectStore& store, V& visitor) {
  QueryCost cost;
  InlineStack<std::uint32_t, 64> nodes;
  InlineStack<std::uint32_t, 64> sub;
  nodes.push(t.root());
  while (!nodes.empty()) {
    const std::uint32_t n = nodes.pop();
    // The children and their boxes once per node, not once per object.
    std::uint32_t kids[8];
    Aabb kid_box[8];
    int kid_count = 0;
    t.for_each_child(n, [&](std::uint32_t c) {
      kids[kid_count] = c;
      kid_box[kid_count] = t.box(c);
      ++kid_count;
      nodes.push(c);
    });
    const std::span<const OctItem> items = t.items(n);
    for (std::size_t i = 0; i < items.size(); ++i) {
      const OctItem& a = items[i];
      if (!test_against(store, a, items, i + 1, cost, visitor)) return cost;
      const Aabb ab = to_double(a.box);
      sub.clear();
      for (int k = 0; k < kid_count; ++k)
        if (kid_box[k].overlaps(ab)) sub.push(kids[k]);
      while (!sub.empty()) {
        const std::uint32_t m = sub.pop();
        if (!test_against(store, a, t.items(m), 0, cost, visitor)) return cost;
        t.for_each_child(m, [&](std::uint32_t c) {
          if (t.box(c).overlaps(ab)) sub.push(c);
        });
      }
    }
  }
  return cost;
}

}  // namespace detail

}  // namespace broadphase
