#include <broadphase/octree.hpp>
#include <string>

namespace broadphase {

using detail::kNoNode;

void OctreeOptions::check() const { detail::check_integer("octree", "split", split, 1, 1000000); }

Octree::Octree(const Config& c, const OctreeOptions& o)
    : cube_(detail::Cube::around(check_config(c, "octree").world)) {
  o.check();
  split_ = o.split;
  nodes_.emplace_back();
  nodes_[0].cell = cube_.cell(0, 0, 0, 0);
  if (c.expected_objects != 0) index_.reserve(c.expected_objects);
}

Vec3 Octree::mid(const Node& n) const {
  const int d = n.depth + 1;
  return {cube_.boundary(0, d, 2ull * n.ix + 1), cube_.boundary(1, d, 2ull * n.iy + 1),
          cube_.boundary(2, d, 2ull * n.iz + 1)};
}

namespace {

// True when `b` may live at a node with this cell: inside it, and touching
// none of its faces that is a midplane of an ancestor (faces on the world
// cube's boundary may be touched, as the root's containment test allows).
bool inside(const Aabb& cell, int depth, const std::uint32_t (&idx)[3], const Aabb& b) {
  const std::uint64_t last = (1ull << depth) - 1;
  for (int a = 0; a < 3; ++a) {
    if (idx[a] == 0 ? b.lo[a] < cell.lo[a] : b.lo[a] <= cell.lo[a]) return false;
    if (idx[a] == last ? b.hi[a] > cell.hi[a] : b.hi[a] >= cell.hi[a]) return false;
  }
  return true;
}

}  // namespace

std::uint32_t Octree::descend(std::uint32_t from, const Aabb& b) const {
  std::uint32_t n = from;
  while (nodes_[n].first_child != kNoNode) {
    const int o = detail::strict_octant(b, mid(nodes_[n]));
    if (o < 0) break;
    n = nodes_[n].first_child + static_cast<std::uint32_t>(o);
  }
  return n;
}

void Octree::detach(std::uint32_t slot) {
  const std::uint32_t n = index_.node_of[slot];
  index_.detach(nodes_, slot);
  add_count(n, -1);
}

void Octree::add_count(std::uint32_t node, int delta) {
  for (std::uint32_t n = node; n != kNoNode; n = nodes_[n].parent)
    nodes_[n].subtree = static_cast<std::uint32_t>(static_cast<int>(nodes_[n].subtree) + delta);
}

std::uint32_t Octree::allocate_children(std::uint32_t parent) {
  const std::uint32_t first = detail::take_nodes(nodes_, free_blocks_, 8);
  const Node& p = nodes_[parent];
  const int depth = p.depth + 1;
  const std::uint32_t px = p.ix, py = p.iy, pz = p.iz;
  for (std::uint32_t o = 0; o < 8; ++o) {
    Node& c = nodes_[first + o];
    c.ix = 2 * px + (o & 1);
    c.iy = 2 * py + ((o >> 1) & 1);
    c.iz = 2 * pz + ((o >> 2) & 1);
    c.depth = static_cast<std::uint8_t>(depth);
    c.cell = cube_.cell(depth, c.ix, c.iy, c.iz);
    c.parent = parent;
    c.first_child = kNoNode;
    c.subtree = 0;
    c.items.clear();
  }
  nodes_[parent].first_child = first;
  return first;
}

int Octree::child_octant(std::uint32_t node, std::uint32_t slot, const Vec3& m) const {
  const Aabb b = bounds(store_.shape(slot));
  // The root also holds the objects outside the world cube: they stay.
  if (node == 0 && !nodes_[0].cell.contains(b)) return -1;
  return detail::strict_octant(b, m);
}

void Octree::split(std::uint32_t node) {
  // Split only when at least one object would move down: a split that moves
  // nothing would leave eight empty children to be merged right back.
  const Vec3 m = mid(nodes_[node]);
  bool any = false;
  for (const detail::OctItem& it : nodes_[node].items)
    if (child_octant(node, it.slot, m) >= 0) {
      any = true;
      break;
    }
  if (!any) return;
  const std::uint32_t first = allocate_children(node);
  std::vector<detail::OctItem>& items = nodes_[node].items;
  for (std::size_t i = 0; i < items.size();) {
    const detail::OctItem it = items[i];
    const int o = child_octant(node, it.slot, m);
    if (o < 0) {
      ++i;
      continue;
    }
    index_.detach(nodes_, it.slot);  // the last item moves to i
    const std::uint32_t c = first + static_cast<std::uint32_t>(o);
    index_.attach(nodes_, c, it.slot, it.box);
    ++nodes_[c].subtree;
  }
  for (std::uint32_t c = first; c < first + 8; ++c)
    if (nodes_[c].items.size() > split_ && nodes_[c].depth < kMaxDepth) split(c);
}

void Octree::free_children(std::uint32_t node) {
  const std::uint32_t first = nodes_[node].first_child;
  for (std::uint32_t c = first; c < first + 8; ++c) {
    if (nodes_[c].first_child != kNoNode) free_children(c);
    nodes_[c].items.clear();
  }
  free_blocks_.push_back(first);
  nodes_[node].first_child = kNoNode;
}

void Octree::merge_empty_above(std::uint32_t node) {
  std::uint32_t top = kNoNode;
  for (std::uint32_t n = node; n != kNoNode; n = nodes_[n].parent)
    if (nodes_[n].first_child != kNoNode && nodes_[n].subtree == nodes_[n].items.size()) top = n;
  if (top != kNoNode) free_children(top);
}

Handle Octree::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  index_.fit(h.index);
  const Aabb b = bounds(s);
  const std::uint32_t n = nodes_[0].cell.contains(b) ? descend(0, b) : 0;
  index_.attach(nodes_, n, h.index, bounds_f(s));
  add_count(n, +1);
  if (nodes_[n].first_child == kNoNode && nodes_[n].items.size() > split_ &&
      nodes_[n].depth < kMaxDepth)
    split(n);
  return h;
}

void Octree::remove(Handle h) {
  const std::uint32_t slot = store_.erase(h);
  const std::uint32_t n = index_.node_of[slot];
  detach(slot);
  merge_empty_above(n);
}

void Octree::update(Handle h, const Shape& s) {
  const std::uint32_t slot = store_.set_shape(h, s);
  const Aabb b = bounds(s);
  const std::uint32_t n = index_.node_of[slot];
  // Climb to the nearest cell that may hold the new box, then go down again.
  std::uint32_t a = n;
  while (a != 0) {
    const Node& an = nodes_[a];
    const std::uint32_t idx[3] = {an.ix, an.iy, an.iz};
    if (inside(an.cell, an.depth, idx, b)) break;
    a = an.parent;
  }
  const std::uint32_t target = (a != 0 || nodes_[0].cell.contains(b)) ? descend(a, b) : 0;
  if (target == n) {
    index_.item(nodes_, slot).box = bounds_f(s);
    return;
  }
  detach(slot);
  index_.attach(nodes_, target, slot, bounds_f(s));
  add_count(target, +1);
  if (nodes_[target].first_child == kNoNode && nodes_[target].items.size() > split_ &&
      nodes_[target].depth < kMaxDepth)
    split(target);
  merge_empty_above(n);
}

std::size_t Octree::memory_bytes() const {
  std::size_t bytes = store_.memory_bytes() + nodes_.capacity() * sizeof(Node) +
                      free_blocks_.capacity() * sizeof(std::uint32_t) + index_.memory_bytes();
  return bytes + detail::items_bytes(nodes_);
}

void Octree::validate() const {
  const auto fail = validate_store("octree");
  const std::size_t placed = detail::validate_items(
      store_, index_, nodes_, fail, [&](std::uint32_t slot, std::uint32_t n) {
        const Aabb b = bounds(store_.shape(slot));
        const std::uint32_t want = nodes_[0].cell.contains(b) ? descend(0, b) : 0;
        if (want != n) fail("object " + std::to_string(slot) + " is not at its smallest cell");
      });
  // Walk the tree: counts, parents, cells and merging.
  std::size_t reachable = 0, items = 0;
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const std::uint32_t n = stack.back();
    stack.pop_back();
    ++reachable;
    const Node& node = nodes_[n];
    items += node.items.size();
    std::size_t sum = node.items.size();
    if (node.first_child != kNoNode) {
      if (node.depth >= kMaxDepth) fail("node below the maximum depth");
      for (std::uint32_t c = node.first_child; c < node.first_child + 8; ++c) {
        const Node& child = nodes_[c];
        if (child.parent != n || child.depth != node.depth + 1) fail("child links");
        if (!node.cell.contains(child.cell)) fail("child cell outside its parent");
        sum += child.subtree;
        stack.push_back(c);
      }
      if (sum == node.items.size()) fail("children left unmerged with an empty subtree");
    }
    if (sum != node.subtree) fail("subtree count");
  }
  if (items != placed || nodes_[0].subtree != store_.size()) fail("object count");
  if (reachable + 8 * free_blocks_.size() != nodes_.size()) fail("node pool and free list");
}

void Octree::visit_cells(CellVisitor visitor) const {
  std::vector<std::uint32_t> stack{root()};
  while (!stack.empty()) {
    const Node& n = nodes_[stack.back()];
    stack.pop_back();
    visitor(n.cell, n.depth, n.items.size());
    for_each_child(static_cast<std::uint32_t>(&n - nodes_.data()),
                   [&](std::uint32_t c) { stack.push_back(c); });
  }
}

}  // namespace broadphase
