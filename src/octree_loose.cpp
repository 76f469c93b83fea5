#include <algorithm>
#include <broadphase/detail/clamp_index.hpp>
#include <broadphase/octree_loose.hpp>
#include <cmath>
#include <string>

namespace broadphase {

using detail::kNoNode;

void LooseOctreeOptions::check() const {
  detail::check_number("octree-loose", "k", k, 1.1, 8);
  detail::check_integer("octree-loose", "depth", static_cast<std::uint64_t>(depth), 0, 20);
}

LooseOctree::LooseOctree(const Config& c, const LooseOctreeOptions& o)
    : cube_(detail::Cube::around(check_config(c, "octree-loose").world)) {
  o.check();
  max_depth_ = o.depth;
  margin_ = (o.k - 1) / 2 * cube_.side;
  nodes_.emplace_back();
  nodes_[0].loose = loose_box(0, 0, 0, 0);
  table_.insert(1, 0);
  if (c.expected_objects != 0) index_.reserve(c.expected_objects);
}

Aabb LooseOctree::loose_box(int depth, std::uint32_t ix, std::uint32_t iy, std::uint32_t iz) const {
  // The margin halves exactly with each level, and subtraction rounds
  // monotonically, so a child's loose box lies inside its parent's.
  const double m = std::ldexp(margin_, -depth);
  Aabb b = cube_.cell(depth, ix, iy, iz);
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = b.lo[a] - m;
    b.hi[a] = b.hi[a] + m;
  }
  return b;
}

LooseOctree::Place LooseOctree::place_of(const Shape& s) const {
  const Aabb b = bounds(s);
  double ext = 0;
  for (int a = 0; a < 3; ++a)
    ext = std::max(ext, std::max(s.center[a] - b.lo[a], b.hi[a] - s.center[a]));
  // The deepest level whose margin covers the extent: margin_ / 2^d >= ext.
  int d = max_depth_;
  if (ext > 0) {
    // NaN (an infinite margin over an infinite extent) or beyond int:
    // clamped before the conversion; the containment test below decides.
    d = detail::clamp_floor<int>(std::log2(margin_ / ext), 0, max_depth_);
  }
  for (; d >= 1; --d) {
    const double cell = std::ldexp(cube_.side, -d);
    const double last = std::ldexp(1.0, d) - 1;
    std::uint32_t idx[3];
    for (int a = 0; a < 3; ++a) {
      idx[a] =
          detail::clamp_floor<std::uint32_t>((s.center[a] - cube_.origin[a]) / cell, 0.0, last);
    }
    if (loose_box(d, idx[0], idx[1], idx[2]).contains(b)) return {d, idx[0], idx[1], idx[2]};
  }
  return {0, 0, 0, 0};
}

std::uint32_t LooseOctree::node_at(const Place& p) {
  const std::uint64_t key = detail::morton_key(p.depth, p.ix, p.iy, p.iz);
  const std::uint32_t found = table_.find(key);
  if (found != kNoNode) return found;
  // Create the missing ancestors first, so that every node hangs from the root.
  const std::uint32_t parent = node_at({p.depth - 1, p.ix >> 1, p.iy >> 1, p.iz >> 1});
  const std::uint32_t n = detail::take_nodes(nodes_, free_);
  Node& node = nodes_[n];
  node.loose = loose_box(p.depth, p.ix, p.iy, p.iz);
  node.items.clear();
  node.key = key;
  node.parent = parent;
  std::fill(std::begin(node.child), std::end(node.child), kNoNode);
  node.ix = p.ix;
  node.iy = p.iy;
  node.iz = p.iz;
  node.depth = static_cast<std::uint8_t>(p.depth);
  node.children = 0;
  nodes_[parent].child[key & 7] = n;
  ++nodes_[parent].children;
  table_.insert(key, n);
  return n;
}

void LooseOctree::prune(std::uint32_t node) {
  std::uint32_t n = node;
  while (n != 0 && nodes_[n].items.empty() && nodes_[n].children == 0) {
    const std::uint32_t parent = nodes_[n].parent;
    nodes_[parent].child[nodes_[n].key & 7] = kNoNode;
    --nodes_[parent].children;
    table_.erase(nodes_[n].key);
    free_.push_back(n);
    n = parent;
  }
}

Handle LooseOctree::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  index_.fit(h.index);
  index_.attach(nodes_, node_at(place_of(s)), h.index, bounds_f(s));
  return h;
}

void LooseOctree::remove(Handle h) {
  const std::uint32_t slot = store_.erase(h);
  const std::uint32_t n = index_.node_of[slot];
  index_.detach(nodes_, slot);
  prune(n);
}

void LooseOctree::update(Handle h, const Shape& s) {
  const std::uint32_t slot = store_.set_shape(h, s);
  const std::uint32_t n = index_.node_of[slot];
  const Place p = place_of(s);
  const Node& old = nodes_[n];
  if (old.depth == p.depth && old.ix == p.ix && old.iy == p.iy && old.iz == p.iz) {
    index_.item(nodes_, slot).box = bounds_f(s);
    return;
  }
  index_.detach(nodes_, slot);
  index_.attach(nodes_, node_at(p), slot, bounds_f(s));
  prune(n);
}

std::size_t LooseOctree::memory_bytes() const {
  std::size_t bytes = store_.memory_bytes() + nodes_.capacity() * sizeof(Node) +
                      free_.capacity() * sizeof(std::uint32_t) + table_.memory_bytes() +
                      index_.memory_bytes();
  return bytes + detail::items_bytes(nodes_);
}

void LooseOctree::validate() const {
  const auto fail = validate_store("octree-loose");
  const std::size_t placed = detail::validate_items(
      store_, index_, nodes_, fail, [&](std::uint32_t slot, std::uint32_t n) {
        const Shape& s = store_.shape(slot);
        const Place p = place_of(s);
        const Node& node = nodes_[n];
        if (node.depth != p.depth || node.ix != p.ix || node.iy != p.iy || node.iz != p.iz)
          fail("object " + std::to_string(slot) + " is not at the node of its size and centre");
        if (n != 0 && !node.loose.contains(bounds(s))) fail("object outside its node's loose box");
      });
  std::size_t reachable = 0, items = 0;
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const std::uint32_t n = stack.back();
    stack.pop_back();
    ++reachable;
    const Node& node = nodes_[n];
    items += node.items.size();
    if (table_.find(node.key) != n) fail("key table misses a node");
    if (n != 0 && node.items.empty() && node.children == 0) fail("empty leaf left behind");
    int children = 0;
    for (std::uint32_t o = 0; o < 8; ++o) {
      const std::uint32_t c = node.child[o];
      if (c == kNoNode) continue;
      ++children;
      const Node& child = nodes_[c];
      if (child.parent != n || child.key != ((node.key << 3) | o)) fail("child links");
      if (!node.loose.contains(child.loose)) fail("child loose box outside its parent's");
      stack.push_back(c);
    }
    if (children != node.children) fail("child count");
  }
  if (items != placed) fail("object count");
  if (reachable + free_.size() != nodes_.size() || table_.size() != reachable)
    fail("node pool, free list and key table disagree");
}

void LooseOctree::visit_cells(CellVisitor visitor) const {
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const Node& n = nodes_[stack.back()];
    stack.pop_back();
    visitor(cube_.cell(n.depth, n.ix, n.iy, n.iz), n.depth, n.items.size());
    for (const std::uint32_t c : n.child)
      if (c != kNoNode) stack.push_back(c);
  }
}

}  // namespace broadphase
