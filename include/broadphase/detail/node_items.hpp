/// \file node_items.hpp
/// The bookkeeping the trees share for objects held in per-node item
/// vectors: each object remembers its node and its position there, so that
/// removal and update never search.
#pragma once

#include <broadphase/geometry.hpp>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace broadphase::detail {

/// A node of a pool: the last of `free` (the first indices of freed blocks
/// of `block` consecutive nodes) or, when none is free, `block` new default
/// nodes at the end of `nodes`. Returns the first index; the caller sets the
/// node's fields (a reused node keeps its old ones, and its items' capacity).
template <class Node>
std::uint32_t take_nodes(std::vector<Node>& nodes, std::vector<std::uint32_t>& free,
                         std::size_t block = 1) {
  if (!free.empty()) {
    const std::uint32_t n = free.back();
    free.pop_back();
    return n;
  }
  const auto n = static_cast<std::uint32_t>(nodes.size());
  nodes.resize(nodes.size() + block);
  return n;
}

/// An object as a node stores it: its conservative float box beside its
/// slot, so that the scans over a node's objects read one contiguous array.
struct OctItem {
  AabbF box;
  std::uint32_t slot;
};

/// Slot -> node and slot -> position in that node's `items`, for any node
/// type with a `std::vector<OctItem> items` member.
struct ItemIndex {
  std::vector<std::uint32_t> node_of;  // slot -> node
  std::vector<std::uint32_t> pos_of;   // slot -> position in the node's items

  /// Reserves room for `n` slots.
  void reserve(std::size_t n) {
    node_of.reserve(n);
    pos_of.reserve(n);
  }
  /// Makes room for `slot`.
  void fit(std::uint32_t slot) {
    if (slot >= node_of.size()) {
      node_of.resize(slot + 1);
      pos_of.resize(slot + 1);
    }
  }
  /// Appends `slot` to the items of `node`.
  template <class Node>
  void attach(std::vector<Node>& nodes, std::uint32_t node, std::uint32_t slot, const AabbF& box) {
    std::vector<OctItem>& items = nodes[node].items;
    node_of[slot] = node;
    pos_of[slot] = static_cast<std::uint32_t>(items.size());
    items.push_back({box, slot});
  }
  /// Takes `slot` out of its node's items (the last item fills the hole).
  template <class Node>
  void detach(std::vector<Node>& nodes, std::uint32_t slot) {
    std::vector<OctItem>& items = nodes[node_of[slot]].items;
    const std::uint32_t p = pos_of[slot];
    items[p] = items.back();
    pos_of[items[p].slot] = p;
    items.pop_back();
  }
  /// The record of `slot` in its node.
  template <class Node>
  OctItem& item(std::vector<Node>& nodes, std::uint32_t slot) const {
    return nodes[node_of[slot]].items[pos_of[slot]];
  }
  template <class Node>
  const OctItem& item(const std::vector<Node>& nodes, std::uint32_t slot) const {
    return nodes[node_of[slot]].items[pos_of[slot]];
  }
  /// True when `slot`'s node and position point back at `slot`.
  template <class Node>
  bool consistent(const std::vector<Node>& nodes, std::uint32_t slot) const {
    const std::uint32_t n = node_of[slot];
    return n < nodes.size() && pos_of[slot] < nodes[n].items.size() &&
           nodes[n].items[pos_of[slot]].slot == slot;
  }
  /// Bytes held by the two maps.
  std::size_t memory_bytes() const {
    return (node_of.capacity() + pos_of.capacity()) * sizeof(std::uint32_t);
  }
};

/// Bytes held by the item vectors of `nodes`.
template <class Node>
std::size_t items_bytes(const std::vector<Node>& nodes) {
  std::size_t bytes = 0;
  for (const Node& n : nodes) bytes += n.items.capacity() * sizeof(OctItem);
  return bytes;
}

/// True when two float boxes are bit-for-bit the same box.
inline bool same_box(const AabbF& a, const AabbF& b) {
  for (int i = 0; i < 3; ++i)
    if (a.lo[i] != b.lo[i] || a.hi[i] != b.hi[i]) return false;
  return true;
}

/// What every tree's `validate()` checks after the store's own check
/// (StoreBase::validate_store): for each live object that its node and position point back
/// at it and that its stored box is its current conservative box. Calls
/// `placed_at(slot, node)` for the structure's own placement rule and
/// `fail(what)` (which throws) on a broken invariant. Returns the number of
/// live objects, for the tree's count check.
template <class Store, class Node, class Fail, class PlacedAt>
std::size_t validate_items(const Store& store, const ItemIndex& index,
                           const std::vector<Node>& nodes, const Fail& fail, PlacedAt&& placed_at) {
  std::size_t placed = 0;
  for (std::uint32_t slot = 0; slot < store.slot_count(); ++slot) {
    if (!store.slots().alive(slot)) continue;
    ++placed;
    if (!index.consistent(nodes, slot))
      fail("an object's node and position disagree with the node's items");
    if (!same_box(index.item(nodes, slot).box, bounds_f(store.shape(slot))))
      fail("stale stored box");
    placed_at(slot, index.node_of[slot]);
  }
  return placed;
}

}  // namespace broadphase::detail
