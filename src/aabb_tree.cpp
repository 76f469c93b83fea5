#include <algorithm>
#include <broadphase/aabb_tree.hpp>
#include <cmath>
#include <stdexcept>

namespace broadphase {

void AabbTreeOptions::check() const {
  if (margin) detail::check_number("aabb-tree", "margin", *margin, 0, 1e30);
  detail::check_number("aabb-tree", "predict", predict, 0, 1e6);
  if (order != AabbTreeOrder::none && order != AabbTreeOrder::leaves_first &&
      order != AabbTreeOrder::smaller_first && order != AabbTreeOrder::hit_ratio &&
      order != AabbTreeOrder::near_far)
    throw InvalidConfig("aabb-tree: option 'order' is not an AabbTreeOrder");
  detail::check_integer("aabb-tree", "max_depth", max_depth, 0, 1000000);
  if (front != AabbTreeFront::off && front != AabbTreeFront::basic &&
      front != AabbTreeFront::deferred)
    throw InvalidConfig("aabb-tree: option 'front' is not an AabbTreeFront");
}

AabbTree::AabbTree(const Config& c, const AabbTreeOptions& o) {
  check_config(c, "aabb-tree");
  o.check();
  double edge = 0;
  for (int a = 0; a < 3; ++a) {
    const double e = c.world.hi[a] - c.world.lo[a];
    if (e > edge) {
      edge = e;
      near_axis_ = a;
    }
  }
  margin_ = o.margin ? *o.margin : 0.002 * edge;
  order_ = o.order;
  predict_ = o.predict;
  max_depth_ = o.max_depth;
  front_mode_ = o.front;
  if (c.expected_objects > 0) {
    nodes_.reserve(2 * c.expected_objects);
    leaf_.reserve(c.expected_objects);
    tight_.reserve(c.expected_objects);
  }
}

std::uint32_t AabbTree::allocate_node() {
  std::uint32_t n;
  if (free_ != kNull) {
    n = free_;
    free_ = nodes_[n].parent;
  } else {
    n = static_cast<std::uint32_t>(nodes_.size());
    if (n == kNull) throw std::length_error("aabb-tree: too many nodes");
    nodes_.emplace_back();
    if (order_ == Order::hit_ratio) hit_stats_.emplace_back();
  }
  Node& node = nodes_[n];
  node.parent = node.child[0] = node.child[1] = node.object = kNull;
  node.leaves = 1;
  node.height = 0;
  node.first = 0;
  node.live = 1;
  node.fixed = 0;
  if (order_ == Order::hit_ratio) hit_stats_[n] = {};
  ++node_count_;
  return n;
}

void AabbTree::free_node(std::uint32_t n) {
  nodes_[n].live = 0;
  nodes_[n].parent = free_;
  free_ = n;
  --node_count_;
}

AabbF AabbTree::fat_box(std::uint32_t slot, const Vec3& displacement) const {
  const AabbF& t = tight_[slot];
  if (!moved_[slot] || (margin_ == 0 && predict_ == 0)) return t;
  AabbF f;
  for (int a = 0; a < 3; ++a) {
    // Stretched along the last displacement, as Box2D and Bullet do, so an
    // object moving steadily keeps its box for several frames.
    const double ahead = predict_ * displacement[a];
    f.lo[a] = round_down(static_cast<double>(t.lo[a]) - margin_ + std::min(ahead, 0.0));
    f.hi[a] = round_up(static_cast<double>(t.hi[a]) + margin_ + std::max(ahead, 0.0));
  }
  return f;
}

void AabbTree::count_hit(std::uint32_t n, bool hit) const {
  HitStats& s = hit_stats_[n];
  std::atomic_ref<std::uint32_t>(s.tests).fetch_add(1, std::memory_order_relaxed);
  if (hit) std::atomic_ref<std::uint32_t>(s.hits).fetch_add(1, std::memory_order_relaxed);
}

void AabbTree::set_order(std::uint32_t n) {
  Node& node = nodes_[n];
  const Node& c0 = nodes_[node.child[0]];
  const Node& c1 = nodes_[node.child[1]];
  bool second_first = false;
  switch (order_) {
    case Order::none:
      break;
    case Order::leaves_first:
      second_first = c1.is_leaf() && !c0.is_leaf();
      break;
    case Order::smaller_first:
      second_first = c1.leaves < c0.leaves;
      break;
    case Order::hit_ratio: {
      // Laplace-smoothed hits per test, compared without dividing.
      const HitStats s0 = hit_stats_[node.child[0]], s1 = hit_stats_[node.child[1]];
      second_first = (std::uint64_t(s1.hits) + 1) * (std::uint64_t(s0.tests) + 2) >
                     (std::uint64_t(s0.hits) + 1) * (std::uint64_t(s1.tests) + 2);
      break;
    }
    case Order::near_far: {
      const int a = near_axis_;
      second_first = c1.box.lo[a] + c1.box.hi[a] < c0.box.lo[a] + c0.box.hi[a];
      break;
    }
  }
  node.first = second_first ? 1 : 0;
}

void AabbTree::refit(std::uint32_t n) {
  Node& node = nodes_[n];
  const Node& c0 = nodes_[node.child[0]];
  const Node& c1 = nodes_[node.child[1]];
  node.box = merged(c0.box, c1.box);
  node.area = area(node.box);
  node.leaves = c0.leaves + c1.leaves;
  node.fixed = c0.fixed & c1.fixed;
  node.height = static_cast<std::uint16_t>(1 + std::max(c0.height, c1.height));
}

// Box2D v3's rotations: at node A with children B and C, try swapping one
// child with a grandchild on the other side, and keep the swap that most
// shrinks the surface area of the grandchild's new parent:
//   B <-> F or B <-> G (C internal, children F, G): C's area becomes B+G or B+F
//   C <-> D or C <-> E (B internal, children D, E): B's area becomes C+E or C+D
// A's own box never changes (it keeps the same leaves).
void AabbTree::rotate(std::uint32_t a) {
  Node& na = nodes_[a];
  const std::uint32_t b = na.child[0], c = na.child[1];
  const Node& nb = nodes_[b];
  const Node& nc = nodes_[c];
  float best_gain = 0;
  std::uint32_t swap_child = kNull, swap_grand = kNull, pivot = kNull;
  auto consider = [&](std::uint32_t child, std::uint32_t side, int g) {
    const Node& ns = nodes_[side];
    const std::uint32_t grand = ns.child[g];
    const std::uint32_t kept = ns.child[1 - g];
    const float gain = area(ns.box) - area(merged(nodes_[child].box, nodes_[kept].box));
    if (gain > best_gain) {
      best_gain = gain;
      swap_child = child;
      swap_grand = grand;
      pivot = side;
    }
  };
  if (!nc.is_leaf()) {
    consider(b, c, 0);
    consider(b, c, 1);
  }
  if (!nb.is_leaf()) {
    consider(c, b, 0);
    consider(c, b, 1);
  }
  // A relative threshold keeps float noise from swapping back and forth.
  if (pivot == kNull || best_gain <= 1e-6f * area(na.box)) return;
  Node& np = nodes_[pivot];
  const int gi = np.child[0] == swap_grand ? 0 : 1;
  const int ci = na.child[0] == swap_child ? 0 : 1;
  np.child[gi] = swap_child;
  nodes_[swap_child].parent = pivot;
  na.child[ci] = swap_grand;
  nodes_[swap_grand].parent = a;
  refit(pivot);
  set_order(pivot);
  refit(a);
  discard_front();
}

void AabbTree::walk_up(std::uint32_t n, bool rotate_nodes) {
  while (n != kNull) {
    refit(n);
    if (rotate_nodes) rotate(n);
    set_order(n);
    n = nodes_[n].parent;
  }
}

std::uint32_t AabbTree::best_sibling(const AabbF& box) const {
  // Branch and bound (Bittner et al., as in Box2D v3 and Bullet's dbvt
  // successors). Making node S the sibling costs the area of S + box, plus
  // the growth this causes in every ancestor of S (inherited cost). Below S
  // the cost is at least area(box) + inherited + growth of S itself, so a
  // subtree whose lower bound is not below the best cost found is skipped.
  // Depth first, the child that grows less first, so the first path is the
  // greedy one; a visit budget bounds the search in crowded regions (an
  // explosion's core), where the bound prunes little and any sibling is
  // still a valid choice.
  const float leaf_area = area(box);
  std::uint32_t best = root_;
  float best_cost = area(merged(nodes_[root_].box, box));
  struct Item {
    std::uint32_t node;
    float inherited;
  };
  detail::InlineStack<Item, 64> stack;
  stack.push({root_, 0.0f});
  for (int budget = kSiblingBudget; !stack.empty() && budget > 0; --budget) {
    const Item it = stack.pop();
    const Node& node = nodes_[it.node];
    const float direct = area(merged(node.box, box));
    const float cost = direct + it.inherited;
    if (cost < best_cost) {
      best_cost = cost;
      best = it.node;
    }
    if (node.is_leaf()) continue;
    const float inherited = it.inherited + direct - area(node.box);
    if (leaf_area + inherited >= best_cost) continue;
    // Visit the child that grows less first, so good bounds come early.
    const std::uint32_t c0 = node.child[0], c1 = node.child[1];
    const float g0 = area(merged(nodes_[c0].box, box)) - area(nodes_[c0].box);
    const float g1 = area(merged(nodes_[c1].box, box)) - area(nodes_[c1].box);
    stack.push({g0 <= g1 ? c1 : c0, inherited});
    stack.push({g0 <= g1 ? c0 : c1, inherited});
  }
  return best;
}

void AabbTree::insert_leaf(std::uint32_t leaf) {
  discard_front();
  if (root_ == kNull) {
    root_ = leaf;
    nodes_[leaf].parent = kNull;
    return;
  }
  const std::uint32_t sibling = best_sibling(nodes_[leaf].box);
  const std::uint32_t old_parent = nodes_[sibling].parent;
  const std::uint32_t parent = allocate_node();
  Node& np = nodes_[parent];
  np.parent = old_parent;
  np.child[0] = sibling;
  np.child[1] = leaf;
  nodes_[sibling].parent = parent;
  nodes_[leaf].parent = parent;
  if (old_parent == kNull) {
    root_ = parent;
  } else {
    Node& op = nodes_[old_parent];
    op.child[op.child[0] == sibling ? 0 : 1] = parent;
  }
  walk_up(parent, true);
}

void AabbTree::remove_leaf(std::uint32_t leaf) {
  discard_front();
  if (leaf == root_) {
    root_ = kNull;
    return;
  }
  const std::uint32_t parent = nodes_[leaf].parent;
  const std::uint32_t grand = nodes_[parent].parent;
  const std::uint32_t sibling = nodes_[parent].child[nodes_[parent].child[0] == leaf ? 1 : 0];
  nodes_[sibling].parent = grand;
  if (grand == kNull) {
    root_ = sibling;
  } else {
    Node& g = nodes_[grand];
    g.child[g.child[0] == parent ? 0 : 1] = sibling;
  }
  free_node(parent);
  walk_up(grand, true);
}

Handle AabbTree::insert(const Shape& s, std::uint64_t user, Motion m) {
  const Handle h = store_.insert(s, user);
  const std::uint32_t i = h.index;
  if (i >= leaf_.size()) {
    leaf_.resize(i + 1);
    tight_.resize(i + 1);
    moved_.resize(i + 1);
    refitted_flag_.resize(i + 1);
  }
  tight_[i] = bounds_f(s);
  moved_[i] = m == Motion::dynamic ? 1 : 0;
  const std::uint32_t leaf = allocate_node();
  nodes_[leaf].object = i;
  nodes_[leaf].box = fat_box(i, {});
  nodes_[leaf].area = area(nodes_[leaf].box);
  nodes_[leaf].fixed = moved_[i] ? 0 : 1;
  leaf_[i] = leaf;
  insert_leaf(leaf);
  if (!moved_[i]) {
    const Shape& me = store_.shape(i);
    for_each_overlapping_leaf(tight_[i], [&](std::uint32_t o) {
      if (o != i && !moved_[o] && may_pair(i, o) && overlaps(me, store_.shape(o)))
        fixed_pairs_.insert(i, o);
    });
  }
  return h;
}

template <class F>
void AabbTree::for_each_overlapping_leaf(const AabbF& b, F&& f) const {
  if (root_ == kNull) return;
  detail::InlineStack<std::uint32_t, 64> stack;
  stack.push(root_);
  while (!stack.empty()) {
    const Node& node = nodes_[stack.pop()];
    if (!boxes_overlap(node.box, b)) continue;
    if (node.is_leaf()) {
      if (boxes_overlap(tight_[node.object], b)) f(node.object);
      continue;
    }
    stack.push(node.child[0]);
    stack.push(node.child[1]);
  }
}

void AabbTree::set_fixed_flags(std::uint32_t leaf) {
  nodes_[leaf].fixed = moved_[nodes_[leaf].object] ? 0 : 1;
  for (std::uint32_t n = nodes_[leaf].parent; n != kNull; n = nodes_[n].parent) {
    const std::uint8_t f = nodes_[nodes_[n].child[0]].fixed & nodes_[nodes_[n].child[1]].fixed;
    if (nodes_[n].fixed == f) break;
    nodes_[n].fixed = f;
  }
}

void AabbTree::make_dynamic(std::uint32_t i) {
  for_each_overlapping_leaf(tight_[i], [&](std::uint32_t o) {
    if (o != i) fixed_pairs_.erase(i, o);
  });
  moved_[i] = 1;
  set_fixed_flags(leaf_[i]);
  discard_front();
}

void AabbTree::recache_fixed(std::uint32_t i) {
  const Shape& me = store_.shape(i);
  for_each_overlapping_leaf(tight_[i], [&](std::uint32_t o) {
    if (o == i || moved_[o]) return;
    if (may_pair(i, o) && overlaps(me, store_.shape(o))) {
      fixed_pairs_.insert(i, o);
    } else {
      fixed_pairs_.erase(i, o);
    }
  });
}

void AabbTree::set_filter(Handle h, Filter f) {
  const std::uint32_t i = store_.set_filter(h, f);
  if (!moved_[i]) recache_fixed(i);
}

void AabbTree::set_pair_filter(PairFilter pf) {
  pair_filter_ = std::move(pf);
  for (std::uint32_t o = 0; o < store_.slot_count(); ++o)
    if (store_.slots().alive(o) && !moved_[o]) recache_fixed(o);
}

void AabbTree::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  if (!moved_[i]) make_dynamic(i);
  const std::uint32_t leaf = leaf_[i];
  remove_leaf(leaf);
  free_node(leaf);
  store_.erase(h);
}

void AabbTree::update(Handle h, const Shape& s) {
  const Vec3 before = store_.shape_of(h).center;
  if (const std::uint32_t k = store_.index_of(h); !moved_[k]) {
    require_valid(s);
    make_dynamic(k);
  }
  const std::uint32_t i = store_.set_shape(h, s);
  tight_[i] = bounds_f(s);
  const std::uint32_t leaf = leaf_[i];
  if (holds(nodes_[leaf].box, tight_[i])) return;
  // A jump far beyond the box size is a teleport, not a motion to predict.
  Vec3 d = s.center - before;
  for (int a = 0; a < 3; ++a)
    if (!(std::fabs(d[a]) <= 4 * (s.half[a] + margin_))) d = {};
  if (front_mode_ != FrontMode::off) {
    // Refit in place: the topology, and so the front, stays valid. Stop as
    // soon as an ancestor's box does not change.
    nodes_[leaf].box = fat_box(i, d);
    nodes_[leaf].area = area(nodes_[leaf].box);
    for (std::uint32_t n = nodes_[leaf].parent; n != kNull; n = nodes_[n].parent) {
      const AabbF before = nodes_[n].box;
      refit(n);
      set_order(n);
      const AabbF& after = nodes_[n].box;
      if (std::equal(before.lo, before.lo + 3, after.lo) &&
          std::equal(before.hi, before.hi + 3, after.hi))
        break;
    }
    // Refitting never restructures, so the tree slowly loses quality as
    // objects travel. After as many refits as there are leaves, reinsert
    // the refitted leaves (here, not later) and start a new front.
    if (!refitted_flag_[i]) {
      refitted_flag_[i] = 1;
      refitted_.push_back(i);
    }
    if (++refits_ > std::max<std::size_t>(64, kRefitsPerLeaf * store_.size())) {
      refits_ = 0;
      for (const std::uint32_t o : refitted_) {
        refitted_flag_[o] = 0;
        if (!store_.slots().alive(o)) continue;
        remove_leaf(leaf_[o]);
        insert_leaf(leaf_[o]);
      }
      refitted_.clear();
    }
    return;
  }
  remove_leaf(leaf);
  nodes_[leaf].box = fat_box(i, d);
  nodes_[leaf].area = area(nodes_[leaf].box);
  insert_leaf(leaf);
}

void AabbTree::update(std::span<const Move> moves) {
  check_moves(*this, moves);
  for (const Move& m : moves) update(m.handle, m.shape);
}

std::size_t AabbTree::memory_bytes() const {
  return store_.memory_bytes() + nodes_.capacity() * sizeof(Node) +
         leaf_.capacity() * sizeof(std::uint32_t) + tight_.capacity() * sizeof(AabbF) +
         moved_.capacity() + hit_stats_.capacity() * sizeof(HitStats) +
         (inner_.capacity() + front_.capacity() + next_inner_.capacity() + next_front_.capacity()) *
             sizeof(FrontPair) +
         inner_state_.capacity() + front_hits_.capacity() +
         inner_map_.capacity() * sizeof(std::uint32_t) + fixed_pairs_.memory_bytes() +
         refitted_.capacity() * sizeof(std::uint32_t) + refitted_flag_.capacity();
}

void AabbTree::validate() const {
  const auto fail = validate_store("aabb-tree");
  std::size_t free_count = 0;
  for (std::uint32_t n = free_; n != kNull; n = nodes_[n].parent) {
    if (n >= nodes_.size() || nodes_[n].live || ++free_count > nodes_.size())
      fail("corrupt free list");
  }
  if (free_count + node_count_ != nodes_.size()) fail("node count disagrees with the free list");
  if (root_ == kNull) {
    if (node_count_ != 0 || store_.size() != 0) fail("empty tree holds nodes");
    return;
  }
  if (nodes_[root_].parent != kNull) fail("root has a parent");
  std::size_t reached = 0, leaves = 0;
  std::vector<std::uint32_t> stack{root_};
  while (!stack.empty()) {
    const std::uint32_t n = stack.back();
    stack.pop_back();
    const Node& node = nodes_[n];
    if (!node.live) fail("reached a free node");
    if (node.area != area(node.box)) fail("cached area");
    if (++reached > node_count_) fail("cycle");
    if (node.is_leaf()) {
      ++leaves;
      const std::uint32_t o = node.object;
      if (!store_.slots().alive(o) || leaf_[o] != n) fail("leaf and object disagree");
      const AabbF t = bounds_f(store_.shape(o));
      if (!std::equal(t.lo, t.lo + 3, tight_[o].lo) || !std::equal(t.hi, t.hi + 3, tight_[o].hi))
        fail("tight box is not the shape's bounds");
      if (!holds(node.box, t)) fail("fat box does not hold the object");
      if (node.leaves != 1 || node.height != 0) fail("leaf count or height of a leaf");
      if (node.fixed != (moved_[o] ? 0 : 1)) fail("fixed flag of a leaf");
      continue;
    }
    for (int k = 0; k < 2; ++k) {
      if (node.child[k] >= nodes_.size() || nodes_[node.child[k]].parent != n)
        fail("child and parent links disagree");
      stack.push_back(node.child[k]);
    }
    const Node& c0 = nodes_[node.child[0]];
    const Node& c1 = nodes_[node.child[1]];
    const AabbF m = merged(c0.box, c1.box);
    if (!std::equal(m.lo, m.lo + 3, node.box.lo) || !std::equal(m.hi, m.hi + 3, node.box.hi))
      fail("node box is not the union of its children");
    if (node.leaves != c0.leaves + c1.leaves) fail("leaf count");
    if (node.fixed != (c0.fixed & c1.fixed)) fail("fixed flag");
    if (node.height != 1 + std::max(c0.height, c1.height)) fail("height");
    if (node.first > 1) fail("child order");
  }
  if (reached != node_count_) fail("unreachable nodes");
  if (leaves != store_.size()) fail("leaf count differs from object count");
  fixed_pairs_.validate();
  for (const auto& p : fixed_pairs_.pairs())
    if (!store_.slots().alive(p.a) || !store_.slots().alive(p.b) || moved_[p.a] || moved_[p.b] ||
        !overlaps(store_.shape(p.a), store_.shape(p.b)) || !may_pair(p.a, p.b))
      fail("cached fixed pair is not an overlapping pair of fixed objects");
  std::size_t fixed_overlaps = 0;
  for (std::uint32_t o = 0; o < store_.slot_count(); ++o) {
    if (!store_.slots().alive(o) || moved_[o]) continue;
    for_each_overlapping_leaf(tight_[o], [&](std::uint32_t x) {
      fixed_overlaps +=
          x != o && !moved_[x] && may_pair(o, x) && overlaps(store_.shape(o), store_.shape(x));
    });
  }
  if (fixed_overlaps != 2 * fixed_pairs_.size()) fail("cached fixed pairs incomplete");
  std::lock_guard<std::mutex> lock(front_mutex_);
  if (front_valid_) {
    for (const auto* list : {&inner_, &front_})
      for (const FrontPair& p : *list)
        if (p.a >= nodes_.size() || p.b >= nodes_.size() || !nodes_[p.a].live || !nodes_[p.b].live)
          fail("front names a free node");
  }
}

void AabbTree::visit_cells(CellVisitor visitor) const {
  if (root_ == kNull) return;
  std::vector<std::pair<std::uint32_t, int>> stack{{root_, 0}};
  while (!stack.empty()) {
    const auto [i, depth] = stack.back();
    stack.pop_back();
    const Node& n = nodes_[i];
    const Aabb box{{n.box.lo[0], n.box.lo[1], n.box.lo[2]},
                   {n.box.hi[0], n.box.hi[1], n.box.hi[2]}};
    visitor(box, depth, n.is_leaf() ? 1 : 0);
    if (!n.is_leaf()) {
      stack.push_back({n.child[0], depth + 1});
      stack.push_back({n.child[1], depth + 1});
    }
  }
}

}  // namespace broadphase
