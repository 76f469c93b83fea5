#include <bit>
#include <broadphase/octree_linear.hpp>
#include <string>

namespace broadphase {

using detail::kNoNode;

void LinearOctreeOptions::check() const {
  detail::check_integer("octree-linear", "depth", static_cast<std::uint64_t>(depth), 0, 20);
}

LinearOctree::LinearOctree(const Config& c, const LinearOctreeOptions& o)
    : cube_(detail::Cube::around(check_config(c, "octree-linear").world)) {
  o.check();
  max_depth_ = o.depth;
  nodes_.emplace_back();
  table_.insert(1, 0);
  if (c.expected_objects != 0) index_.reserve(c.expected_objects);
}

std::uint64_t LinearOctree::key_of(const Aabb& b) const {
  if (!cube_.cell(0, 0, 0, 0).contains(b)) return 1;
  std::uint64_t key = 1;
  std::uint32_t idx[3] = {0, 0, 0};
  for (int d = 0; d < max_depth_; ++d) {
    const Vec3 mid{cube_.boundary(0, d + 1, 2ull * idx[0] + 1),
                   cube_.boundary(1, d + 1, 2ull * idx[1] + 1),
                   cube_.boundary(2, d + 1, 2ull * idx[2] + 1)};
    const int o = detail::strict_octant(b, mid);
    if (o < 0) break;
    for (int a = 0; a < 3; ++a) idx[a] = 2 * idx[a] + ((static_cast<unsigned>(o) >> a) & 1);
    key = (key << 3) | static_cast<unsigned>(o);
  }
  return key;
}

std::uint32_t LinearOctree::node_at(std::uint64_t key) {
  const std::uint32_t found = table_.find(key);
  if (found != kNoNode) return found;
  const std::uint32_t parent = node_at(key >> 3);
  const std::uint32_t n = detail::take_nodes(nodes_, free_);
  Node& node = nodes_[n];
  const int depth = (std::bit_width(key) - 1) / 3;
  node.items.clear();
  node.key = key;
  node.depth = static_cast<std::uint8_t>(depth);
  node.child_mask = 0;
  node.ix = node.iy = node.iz = 0;
  for (int l = depth - 1; l >= 0; --l) {
    const unsigned o = static_cast<unsigned>(key >> (3 * l)) & 7;
    node.ix = 2 * node.ix + (o & 1);
    node.iy = 2 * node.iy + ((o >> 1) & 1);
    node.iz = 2 * node.iz + ((o >> 2) & 1);
  }
  nodes_[parent].child_mask |= static_cast<std::uint8_t>(1u << (key & 7));
  table_.insert(key, n);
  return n;
}

void LinearOctree::prune(std::uint32_t node) {
  std::uint32_t n = node;
  while (n != 0 && nodes_[n].items.empty() && nodes_[n].child_mask == 0) {
    const std::uint64_t key = nodes_[n].key;
    const std::uint32_t parent = table_.find(key >> 3);
    nodes_[parent].child_mask &= static_cast<std::uint8_t>(~(1u << (key & 7)));
    table_.erase(key);
    free_.push_back(n);
    n = parent;
  }
}

Handle LinearOctree::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  index_.fit(h.index);
  index_.attach(nodes_, node_at(key_of(bounds(s))), h.index, bounds_f(s));
  return h;
}

void LinearOctree::remove(Handle h) {
  const std::uint32_t slot = store_.erase(h);
  const std::uint32_t n = index_.node_of[slot];
  index_.detach(nodes_, slot);
  prune(n);
}

void LinearOctree::update(Handle h, const Shape& s) {
  const std::uint32_t slot = store_.set_shape(h, s);
  const std::uint32_t n = index_.node_of[slot];
  const std::uint64_t key = key_of(bounds(s));
  if (nodes_[n].key == key) {
    index_.item(nodes_, slot).box = bounds_f(s);
    return;
  }
  index_.detach(nodes_, slot);
  index_.attach(nodes_, node_at(key), slot, bounds_f(s));
  prune(n);
}

std::size_t LinearOctree::memory_bytes() const {
  std::size_t bytes = store_.memory_bytes() + nodes_.capacity() * sizeof(Node) +
                      free_.capacity() * sizeof(std::uint32_t) + table_.memory_bytes() +
                      index_.memory_bytes();
  return bytes + detail::items_bytes(nodes_);
}

void LinearOctree::validate() const {
  const auto fail = validate_store("octree-linear");
  const std::size_t placed = detail::validate_items(
      store_, index_, nodes_, fail, [&](std::uint32_t slot, std::uint32_t n) {
        const Aabb b = bounds(store_.shape(slot));
        if (nodes_[n].key != key_of(b))
          fail("object " + std::to_string(slot) + " is not at its smallest cell");
        if (n != 0 && !box(n).contains(b)) fail("object outside its cell");
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
    if (n != 0 && node.items.empty() && node.child_mask == 0) fail("empty leaf left behind");
    for (unsigned o = 0; o < 8; ++o) {
      const std::uint32_t c = table_.find((node.key << 3) | o);
      if (((node.child_mask >> o) & 1) != (c != kNoNode)) fail("child mask");
      if (c == kNoNode) continue;
      if (!box(n).contains(box(c))) fail("child cell outside its parent");
      stack.push_back(c);
    }
  }
  if (items != placed) fail("object count");
  if (reachable + free_.size() != nodes_.size() || table_.size() != reachable)
    fail("node pool, free list and key table disagree");
}

void LinearOctree::visit_cells(CellVisitor visitor) const {
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const Node& n = nodes_[stack.back()];
    stack.pop_back();
    visitor(cube_.cell(n.depth, n.ix, n.iy, n.iz), n.depth, n.items.size());
    for (unsigned o = 0; o < 8; ++o)
      if ((n.child_mask >> o) & 1u) stack.push_back(table_.find((n.key << 3) | o));
  }
}

}  // namespace broadphase
