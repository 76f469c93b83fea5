#include <algorithm>
#include <broadphase/kdtree.hpp>
#include <cmath>
#include <limits>
#include <string>

namespace broadphase {

using detail::kNoNode;
using detail::OctItem;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr AabbF kEmpty{{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}};
// How many moves ahead the bulk update fetches a mover's index entries,
// its leaf's node, its item (update(span)).
constexpr std::size_t kAhead3 = 24, kAhead2 = 16, kAhead1 = 8;

AabbF merged(const AabbF& a, const AabbF& b) {
  AabbF m;
  for (int k = 0; k < 3; ++k) {
    m.lo[k] = std::min(a.lo[k], b.lo[k]);
    m.hi[k] = std::max(a.hi[k], b.hi[k]);
  }
  return m;
}

// Half the surface area, in double; 0 for an empty box.
double area(const AabbF& b) {
  if (b.lo[0] > b.hi[0]) return 0;
  const double x = double(b.hi[0]) - b.lo[0];
  const double y = double(b.hi[1]) - b.lo[1];
  const double z = double(b.hi[2]) - b.lo[2];
  return x * y + y * z + z * x;
}

AabbF union_of(std::span<const OctItem> items) {
  AabbF b = kEmpty;
  for (const OctItem& it : items) b = merged(b, it.box);
  return b;
}

}  // namespace

void KdTreeOptions::check() const {
  if (rebuild != KdTreePolicy::refit && rebuild != KdTreePolicy::decay &&
      rebuild != KdTreePolicy::always)
    throw InvalidConfig("kdtree: option 'rebuild' is not a KdTreePolicy");
  detail::check_number("kdtree", "decay", decay, 1, 1e6);
  detail::check_integer("kdtree", "leaf", leaf, 1, 1024);
}

KdTree::KdTree(const Config& c, const KdTreeOptions& o) {
  check_config(c, "kdtree");
  o.check();
  policy_ = o.rebuild;
  decay_ = o.decay;
  leaf_size_ = o.leaf;
  root_ = new_node(kNoNode);
  if (c.expected_objects != 0) index_.reserve(c.expected_objects);
}

std::uint32_t KdTree::new_node(std::uint32_t parent) {
  const std::uint32_t n = detail::take_nodes(nodes_, free_);
  order_stale_ = true;
  if (ray_kids_.size() < nodes_.size()) ray_kids_.resize(nodes_.size());
  ray_kids_[n] = RayKids{};
  Node& node = nodes_[n];
  node.box = kEmpty;
  node.items.clear();
  node.parent = parent;
  node.left = node.right = kNoNode;
  node.split = 0;
  node.axis = 0;
  sync_leaf(n);
  return n;
}

void KdTree::build(std::uint32_t node, std::size_t begin, std::size_t end) {
  // Top-down over scratch_[begin, end): each task fills one node, adds its
  // area to surface_, and either makes it a leaf or splits it in two.
  struct Task {
    std::uint32_t node;
    std::size_t begin, end;
  };
  constexpr int kBins = 16;
  detail::InlineStack<Task, 64> tasks;
  tasks.push({node, begin, end});
  while (!tasks.empty()) {
    const Task t = tasks.pop();
    const std::span<OctItem> items(scratch_.data() + t.begin, t.end - t.begin);
    set_box(t.node, union_of(items));
    surface_ += area(nodes_[t.node].box);
    const std::size_t count = items.size();
    auto centre = [this](const OctItem& it, int axis) {
      return store_.shape(it.slot).center[axis];
    };

    double cmin[3], cmax[3];
    for (int a = 0; a < 3; ++a) {
      cmin[a] = std::numeric_limits<double>::infinity();
      cmax[a] = -cmin[a];
    }
    if (count > leaf_size_)
      for (const OctItem& it : items)
        for (int a = 0; a < 3; ++a) {
          cmin[a] = std::min(cmin[a], centre(it, a));
          cmax[a] = std::max(cmax[a], centre(it, a));
        }

    // Binned surface area heuristic over all three axes.
    int best_axis = -1;
    double best_split = 0, best_cost = std::numeric_limits<double>::infinity();
    int widest = -1;
    double widest_extent = 0;
    for (int a = 0; a < 3 && count > leaf_size_; ++a) {
      const double extent = cmax[a] - cmin[a];
      if (!(extent > 0)) continue;
      if (extent > widest_extent) {
        widest = a;
        widest_extent = extent;
      }
      if (!std::isfinite(extent)) continue;
      std::size_t n[kBins] = {};
      AabbF box[kBins];
      std::fill(std::begin(box), std::end(box), kEmpty);
      const double scale = kBins / extent;
      // A subnormal extent overflows the scale: no bins (the median split
      // of the widest axis below still divides the items).
      if (!std::isfinite(scale)) continue;
      for (const OctItem& it : items) {
        const int b = std::min(kBins - 1, static_cast<int>((centre(it, a) - cmin[a]) * scale));
        ++n[b];
        box[b] = merged(box[b], it.box);
      }
      double right_area[kBins];
      std::size_t right_n[kBins];
      AabbF acc = kEmpty;
      std::size_t acc_n = 0;
      for (int b = kBins - 1; b > 0; --b) {
        acc = merged(acc, box[b]);
        acc_n += n[b];
        right_area[b] = area(acc);
        right_n[b] = acc_n;
      }
      acc = kEmpty;
      acc_n = 0;
      for (int b = 0; b < kBins - 1; ++b) {
        acc = merged(acc, box[b]);
        acc_n += n[b];
        if (acc_n == 0 || right_n[b + 1] == 0) continue;
        const double cost = area(acc) * double(acc_n) + right_area[b + 1] * double(right_n[b + 1]);
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = a;
          best_split = cmin[a] + (b + 1) / scale;
        }
      }
    }
    if (widest < 0) {  // few objects, or all centres equal: a leaf
      for (const OctItem& it : items) index_.attach(nodes_, t.node, it.slot, it.box);
      sync_leaf(t.node);
      continue;
    }

    std::size_t mid = 0;
    float split = 0;
    int axis = best_axis;
    if (axis >= 0) {
      split = static_cast<float>(best_split);
      const auto part = std::partition(items.begin(), items.end(), [&](const OctItem& it) {
        return centre(it, axis) < static_cast<double>(split);
      });
      mid = static_cast<std::size_t>(part - items.begin());
    }
    if (mid == 0 || mid == count) {
      // Rounding emptied a side (or the centres overflow the bins): split
      // at the median of the widest axis instead.
      axis = widest;
      mid = count / 2;
      std::nth_element(
          items.begin(), items.begin() + static_cast<std::ptrdiff_t>(mid), items.end(),
          [&](const OctItem& x, const OctItem& y) { return centre(x, axis) < centre(y, axis); });
      split = static_cast<float>(centre(items[mid], axis));
    }
    const std::uint32_t left = new_node(t.node);
    const std::uint32_t right = new_node(t.node);
    Node& n = nodes_[t.node];
    // An inner node holds no objects: give back the capacity it may have
    // kept from a life as a leaf (it was a third of the tree's memory).
    std::vector<OctItem>().swap(n.items);
    n.left = left;
    n.right = right;
    RayKids& kids = ray_kids_[t.node];
    kids.box[0] = kids.box[1] = kEmpty;
    kids.child[0] = left;
    kids.child[1] = right;
    n.axis = static_cast<std::uint8_t>(axis);
    n.split = split;
    tasks.push({left, t.begin, t.begin + mid});
    tasks.push({right, t.begin + mid, t.end});
  }
}

void KdTree::set_box(std::uint32_t n, const AabbF& b) {
  nodes_[n].box = b;
  const std::uint32_t p = nodes_[n].parent;
  if (p != kNoNode) ray_kids_[p].box[nodes_[p].left == n ? 0 : 1] = b;
}

void KdTree::rebuild() {
  scratch_.clear();
  for (std::uint32_t slot = 0; slot < store_.slot_count(); ++slot)
    if (store_.slots().alive(slot)) scratch_.push_back({index_.item(nodes_, slot).box, slot});
  free_.clear();
  for (std::uint32_t i = static_cast<std::uint32_t>(nodes_.size()); i-- > 0;) free_.push_back(i);
  surface_ = 0;
  root_ = new_node(kNoNode);
  build(root_, 0, scratch_.size());
  built_surface_ = surface_;
  built_size_ = store_.size();
  ++rebuilds_;
}

void KdTree::split_leaf(std::uint32_t node) {
  std::vector<OctItem>& items = nodes_[node].items;
  scratch_.assign(items.begin(), items.end());
  items.clear();
  surface_ -= area(nodes_[node].box);
  build(node, 0, scratch_.size());
}

void KdTree::refit_path(std::uint32_t node) {
  for (std::uint32_t n = node; n != kNoNode; n = nodes_[n].parent) {
    Node& x = nodes_[n];
    const AabbF fresh =
        x.left == kNoNode ? union_of(x.items) : merged(nodes_[x.left].box, nodes_[x.right].box);
    if (detail::same_box(fresh, x.box)) return;
    surface_ += area(fresh) - area(x.box);
    set_box(n, fresh);
  }
}

void KdTree::refit_all() {
  // Children before parents. A build numbers every node after its parent
  // (new_node takes the lowest free index), and so does a leaf split onto
  // fresh nodes: then the live nodes in order of index, walked backwards,
  // are such an order, and the pass reads nodes_, ray_kids_ and (mostly)
  // the leaves' item blocks front to back. The reverse of a breadth-first
  // walk, the fallback, jumps about: that pass waited on the loads of each
  // node for most of its time (perf, 10^5 uniform spheres). The order is
  // kept until the tree's shape changes (new_node, remove).
  if (order_stale_) {
    scratch_order_.clear();
    scratch_order_.push_back(root_);
    bool numbered = true;  // every child's index above its parent's
    for (std::size_t i = 0; i < scratch_order_.size(); ++i) {
      const std::uint32_t p = scratch_order_[i];
      const Node& n = nodes_[p];
      if (n.left != kNoNode) {
        scratch_order_.push_back(n.left);
        scratch_order_.push_back(n.right);
        numbered = numbered && n.left > p && n.right > p;
      }
    }
    if (numbered) std::sort(scratch_order_.begin(), scratch_order_.end());
    order_stale_ = false;
  }
  // An inner node copies its children's boxes into its own ray record
  // (their boxes are final by then), not each child into its parent's
  // (set_box): that read the parent's node, a load waited on (perf). A
  // leaf's items are a block of their own: fetched a few nodes ahead.
  surface_ = 0;
  for (std::size_t i = scratch_order_.size(); i-- > 0;) {
    if (i >= kAhead1) {
      const Node& ahead = nodes_[scratch_order_[i - kAhead1]];
      const char* p = reinterpret_cast<const char*>(ahead.items.data());
      const std::size_t bytes = ahead.items.size() * sizeof(OctItem);
      for (std::size_t b = 0; b < bytes; b += 64) detail::prefetch(p + b);
    }
    const std::uint32_t n = scratch_order_[i];
    Node& x = nodes_[n];
    if (x.left == kNoNode) {
      x.box = union_of(x.items);
    } else {
      const AabbF& l = nodes_[x.left].box;
      const AabbF& r = nodes_[x.right].box;
      ray_kids_[n].box[0] = l;
      ray_kids_[n].box[1] = r;
      x.box = merged(l, r);
    }
    surface_ += area(x.box);
  }
}

void KdTree::after_motion() {
  if (policy_ == Policy::always || (policy_ == Policy::decay && surface_ > decay_ * built_surface_))
    rebuild();
}

void KdTree::after_resize() {
  const std::size_t n = store_.size();
  if ((n > 2 * built_size_ && n > leaf_size_) || 2 * n < built_size_) rebuild();
}

Handle KdTree::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  index_.fit(h.index);
  std::uint32_t n = root_;
  while (!leaf(n)) {
    const Node& x = nodes_[n];
    n = s.center[x.axis] < static_cast<double>(x.split) ? x.left : x.right;
  }
  const AabbF f = bounds_f(s);
  index_.attach(nodes_, n, h.index, f);
  sync_leaf(n);
  for (std::uint32_t m = n; m != kNoNode; m = nodes_[m].parent) {
    const AabbF grown = merged(nodes_[m].box, f);
    if (detail::same_box(grown, nodes_[m].box)) break;
    surface_ += area(grown) - area(nodes_[m].box);
    set_box(m, grown);
  }
  if (nodes_[n].items.size() > leaf_size_) split_leaf(n);
  after_resize();
  return h;
}

void KdTree::remove(Handle h) {
  const std::uint32_t slot = store_.erase(h);
  const std::uint32_t n = index_.node_of[slot];
  index_.detach(nodes_, slot);
  sync_leaf(n);
  refit_path(n);
  if (nodes_[n].items.empty() && n != root_) {
    // Replace the parent by the sibling: the parent's box equals the
    // sibling's now, so nothing above changes.
    const std::uint32_t parent = nodes_[n].parent;
    const std::uint32_t sibling =
        nodes_[parent].left == n ? nodes_[parent].right : nodes_[parent].left;
    const std::uint32_t grand = nodes_[parent].parent;
    surface_ -= area(nodes_[parent].box);
    nodes_[sibling].parent = grand;
    if (grand == kNoNode) {
      root_ = sibling;
    } else {
      const int side = nodes_[grand].left == parent ? 0 : 1;
      (side == 0 ? nodes_[grand].left : nodes_[grand].right) = sibling;
      ray_kids_[grand].child[side] = sibling;
      ray_kids_[grand].box[side] = nodes_[sibling].box;
    }
    free_.push_back(n);
    free_.push_back(parent);
    order_stale_ = true;
  }
  after_resize();
}

void KdTree::update(Handle h, const Shape& s) {
  const std::uint32_t slot = store_.set_shape(h, s);
  const std::uint32_t n = index_.node_of[slot];
  index_.item(nodes_, slot).box = bounds_f(s);
  refit_path(n);
  after_motion();
}

void KdTree::update(std::span<const Move> moves) {
  check_moves(*this, moves);  // all-or-nothing: nothing below fails on input
  // Each move's slot -> node -> item is a chain of three dependent loads at
  // random places (the movers lie all over the tree): the loop waited on
  // them for most of its time (perf). The links of the moves ahead are
  // fetched in stages, each from the line the previous stage brought in.
  const std::size_t count = moves.size();
  for (std::size_t k = 0; k < count; ++k) {
    if (k + kAhead3 < count) {
      const std::uint32_t s = moves[k + kAhead3].handle.index;
      detail::prefetch(&index_.node_of[s]);
      detail::prefetch(&index_.pos_of[s]);
      detail::prefetch(&store_.shape(s));
    }
    if (k + kAhead2 < count)
      detail::prefetch(&nodes_[index_.node_of[moves[k + kAhead2].handle.index]].items);
    if (k + kAhead1 < count) {
      const std::uint32_t s = moves[k + kAhead1].handle.index;
      detail::prefetch(nodes_[index_.node_of[s]].items.data() + index_.pos_of[s]);
    }
    const Move& m = moves[k];
    const std::uint32_t slot = store_.set_shape(m.handle, m.shape);
    index_.item(nodes_, slot).box = bounds_f(m.shape);
  }
  refit_all();
  after_motion();
}

std::size_t KdTree::memory_bytes() const {
  std::size_t bytes = store_.memory_bytes() + nodes_.capacity() * sizeof(Node) +
                      ray_kids_.capacity() * sizeof(RayKids) +
                      scratch_.capacity() * sizeof(OctItem) +
                      (free_.capacity() + scratch_order_.capacity()) * sizeof(std::uint32_t) +
                      index_.memory_bytes();
  return bytes + detail::items_bytes(nodes_);
}

void KdTree::validate() const {
  const auto fail = validate_store("kdtree");
  const std::size_t placed =
      detail::validate_items(store_, index_, nodes_, fail, [&](std::uint32_t, std::uint32_t n) {
        if (!leaf(n)) fail("an object held by an inner node");
      });
  std::size_t reachable = 0, items = 0;
  std::vector<std::uint32_t> stack{root_};
  if (nodes_[root_].parent != kNoNode) fail("root has a parent");
  while (!stack.empty()) {
    const std::uint32_t n = stack.back();
    stack.pop_back();
    ++reachable;
    const Node& x = nodes_[n];
    items += x.items.size();
    if (x.left == kNoNode) {
      if (x.right != kNoNode) fail("half a leaf");
      if (!detail::same_box(x.box, union_of(x.items)))
        fail("leaf box is not the union of its objects");
      if (x.items.empty() && n != root_) fail("empty leaf below the root");
      const RayKids& k = ray_kids_[n];
      if (k.child[0] != kNoNode || k.leaf.items != x.items.data() || k.leaf.count != x.items.size())
        fail("the ray walk's copy of a leaf");
      continue;
    }
    if (!x.items.empty()) fail("objects in an inner node");
    const RayKids& k = ray_kids_[n];
    if (k.child[0] != x.left || k.child[1] != x.right ||
        !detail::same_box(k.box[0], nodes_[x.left].box) ||
        !detail::same_box(k.box[1], nodes_[x.right].box))
      fail("the ray walk's copy of the children");
    if (nodes_[x.left].parent != n || nodes_[x.right].parent != n) fail("child links");
    if (!detail::same_box(x.box, merged(nodes_[x.left].box, nodes_[x.right].box)))
      fail("inner box is not the union of its children");
    stack.push_back(x.left);
    stack.push_back(x.right);
  }
  if (items != placed) fail("object count");
  if (reachable + free_.size() != nodes_.size()) fail("node pool and free list");
}

void KdTree::visit_cells(CellVisitor visitor) const {
  if (nodes_.empty()) return;
  std::vector<std::pair<std::uint32_t, int>> stack{{root_, 0}};
  while (!stack.empty()) {
    const auto [i, depth] = stack.back();
    stack.pop_back();
    const Node& n = nodes_[i];
    visitor(detail::to_double(n.box), depth, n.items.size());
    if (n.left != kNoNode) stack.push_back({n.left, depth + 1});
    if (n.right != kNoNode) stack.push_back({n.right, depth + 1});
  }
}

}  // namespace broadphase
