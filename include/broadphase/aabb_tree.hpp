/// \file aabb_tree.hpp
/// `aabb-tree`: a dynamic bounding-volume hierarchy of float boxes, in the
/// manner of Box2D's and Bullet's dynamic trees: enlarged ("fat") leaf boxes
/// so that small moves cost nothing, insertion at the sibling of least
/// surface-area cost (branch and bound), tree rotations on the way up, and
/// all pairs by one simultaneous traversal of the tree against itself, with
/// an optional front kept between frames.
#pragma once

#include <array>
#include <atomic>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/inline_stack.hpp>
#include <broadphase/detail/pair_table.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <limits>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace broadphase {

/// What a tree traversal cost beyond the exact tests.
struct TraversalStats {
  std::uint64_t node_tests = 0;   ///< box-versus-box tests of node pairs (or node vs query)
  std::uint64_t brute_pairs = 0;  ///< leaf pairs tested below `max_depth`
  std::uint64_t front_size = 0;   ///< terminal node pairs in the front (front tracking)
  bool front_rebuilt = false;     ///< the front was rebuilt from the root this pass
};

/// Which child every AabbTree traversal descends into first (option `order`).
enum class AabbTreeOrder : std::uint8_t { none, leaves_first, smaller_first, hit_ratio, near_far };
/// Front tracking between an AabbTree's all-pairs passes (option `front`).
enum class AabbTreeFront : std::uint8_t { off, basic, deferred };

/// The options of AabbTree, as described above its class.
struct AabbTreeOptions {
  /// World units around a moving object's box, in [0, 1e30]. Default (empty):
  /// 0.002 x the largest edge of Config::world.
  std::optional<double> margin{};
  /// Displacements a refreshed fat box is stretched by, in [0, 1e6]. Default 2.
  double predict = 2;
  /// Which child every traversal descends into first. Default leaves_first.
  AabbTreeOrder order = AabbTreeOrder::leaves_first;
  /// Depth below which leaf pairs are tested directly, in [0, 1000000];
  /// 0 (default): none.
  std::uint32_t max_depth = 0;
  /// Front tracking between all-pairs passes. Default off.
  AabbTreeFront front = AabbTreeFront::off;
  /// Throws InvalidConfig for a value out of range.
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static AabbTreeOptions from(const OptionText& text);
};

/// A dynamic AABB tree (BVH).
///
/// Options (`aabb-tree:key=value,...`):
/// - `margin=M` (default 0.002 x the largest edge of Config::world): world
///   units added around a moving object's box; moves inside it cost O(1).
///   Objects inserted as Motion::fixed get no margin until first moved.
/// - `predict=K` (default 2): when a leaf is refreshed its fat box is also
///   stretched by K times the object's last displacement, in the direction
///   of motion (0: no prediction).
/// - `order=leaves-first|smaller-first|hit-ratio|near-far|none` (default
///   leaves-first): which child every traversal descends into first, fixed
///   whenever a node is (re)built: a leaf before a subtree, the subtree with
///   fewer leaves, the child whose box hit more often in past traversals
///   (hits per test, counted while traversing), or the child nearer along the
///   longest axis of the world.
/// - `max_depth=D` (default 0: none): node pairs at depth D are not split
///   further; all leaf pairs below them are tested directly (still exact).
/// - `front=off|basic|deferred` (default off): keep the front of the
///   self-traversal between frames and restart from it. `basic` lowers the
///   front where node pairs now overlap and raises it where they separate;
///   `deferred` only lowers it and rebuilds it from the root when it has
///   grown to twice its rebuilt size. With a front, a leaf that leaves its
///   fat box is refitted in place (no reinsertion) so the topology, and the
///   front, survive moves; once half the leaves have been refitted they are
///   all reinserted to restore the tree's quality, which, like insert and
///   remove, discards the front.
///
/// Complexity: insert O(log n) typical (branch and bound over the tree);
/// remove O(depth); update O(1) inside the fat box, else O(log n) typical;
/// for_each_pair O(node pairs whose boxes overlap); query O(log n + k).
/// Handles stay valid until their object is removed. Thread-safety: const
/// members may run concurrently; with a front, all-pairs passes serialise
/// on an internal mutex (they update the front); with order=hit-ratio,
/// traversals update per-node counters atomically.
class AabbTree : public detail::StoreBase<AabbTree> {
 public:
  /// Which child every traversal descends into first (option `order`).
  using Order = AabbTreeOrder;
  /// Front tracking between all-pairs passes (option `front`).
  using FrontMode = AabbTreeFront;

  using Options = AabbTreeOptions;
  /// Reads the deprecated Config::options map into AabbTreeOptions.
  /// Throws InvalidConfig.
  explicit AabbTree(const Config& c = {})
      : AabbTree(without_options(c), AabbTreeOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (AabbTreeOptions::check).
  AabbTree(const Config& c, const AabbTreeOptions& o);
  AabbTree(const AabbTree&) = delete;
  AabbTree& operator=(const AabbTree&) = delete;

  /// Adds an object as a new leaf. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object's leaf. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves an object; free while its box stays inside its fat box.
  /// Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);
  /// Moves many objects (each as `update`). All-or-nothing: throws
  /// InvalidHandle, InvalidShape before moving anything; a repeated handle
  /// takes its last move.
  void update(std::span<const Move> moves);

  /// Visits every object overlapping `q` exactly.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    TraversalStats stats;
    return query(q, visitor, stats);
  }
  /// As `query`, also counting node tests into `stats`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor, TraversalStats& stats) const;

  /// Visits every overlapping pair once (self-traversal of the tree).
  template <class V>
  QueryCost for_each_pair(V&& visitor) const {
    TraversalStats stats;
    return for_each_pair(visitor, stats);
  }
  /// As `for_each_pair`, also reporting node tests and the front into `stats`.
  /// The filters are tested at the leaf pairs: the front is a cut through
  /// node pairs, which no filter changes.
  template <class V>
  QueryCost for_each_pair(V&& visitor, TraversalStats& stats) const {
    if (unfiltered()) return walk_pairs(visitor, stats);
    detail::FilteredVisitor<std::remove_reference_t<V>> f(visitor, store_, pair_filter_);
    return walk_pairs(f, stats);
  }
  /// Changes an object's filter (HasFilters); a never-moved fixed object's
  /// cached pairs follow it (the cache holds only pairs that pass). Throws
  /// InvalidHandle. O(log n + the leaves its box overlaps).
  void set_filter(Handle h, Filter f);
  /// Installs or removes the pair filter and re-caches the fixed pairs.
  void set_pair_filter(PairFilter pf);
  /// Casts a ray (HasRayCast): front to back through the nodes whose fat
  /// boxes the ray enters before its live tmax (detail/ray_walk.hpp), each
  /// leaf culled by its object's own box. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const;
  /// The closest hit of each ray into `out` (as long as `rays`,
  /// std::invalid_argument): closest_hit(*this, rays[i]) bit for bit,
  /// several rays walked at once (detail::ray_binary_closest_hits). Throws
  /// InvalidRay, naming the first invalid ray, before casting any.
  /// From `flights_from` objects on (detail::kRayFlightsFrom: where it was
  /// measured faster); below, one ray at a time.
  void closest_hits(std::span<const Ray> rays, std::span<RayHit> out,
                    std::size_t flights_from = detail::kRayFlightsFrom) const;

  /// Bytes held (capacities of every array and table).
  std::size_t memory_bytes() const;
  /// Height of the tree (0 when empty, 1 for a single leaf).
  int height() const { return root_ == kNull ? 0 : nodes_[root_].height + 1; }
  /// The child ordering chosen at construction.
  Order order() const { return order_; }
  /// The front-tracking mode chosen at construction.
  FrontMode front_mode() const { return front_mode_; }

  /// Checks links, boxes (each parent holds its children, each leaf holds
  /// its object's box), leaf counts, heights, child order, the free list.
  void validate() const;
  /// Reports every node: its box (a leaf's box is its object's fattened box),
  /// its depth, the objects it holds (1 for a leaf, 0 inside). O(nodes).
  void visit_cells(CellVisitor visitor) const;

 private:
  static constexpr std::uint32_t kNull = 0xffffffffu;
  static constexpr int kSiblingBudget = 64;  // nodes the sibling search may visit

  // One cache line: the box first (what every traversal step reads), then
  // the links. Leaves carry the object's slot; internal nodes kNull.
  struct alignas(64) Node {
    AabbF box;
    std::uint32_t parent;  // next free node while free
    std::uint32_t child[2];
    std::uint32_t object;
    std::uint32_t leaves;
    std::uint16_t height;  // 0 for a leaf
    std::uint8_t first;    // index of the child to descend first
    std::uint8_t live;
    float area;          // area(box), cached for the traversal's split choice
    std::uint8_t fixed;  // every leaf below is a never-moved Motion::fixed object
    bool is_leaf() const { return object != kNull; }
  };
  static_assert(sizeof(Node) == 64, "a node is one cache line");

  struct HitStats {
    std::uint32_t hits = 0, tests = 0;
  };

  // A node pair still to be examined; a == b is a subtree against itself.
  struct Task {
    std::uint32_t a, b, depth, parent;
  };
  // A node pair of the front (terminal) or above it (inner), for front
  // tracking; `parent` indexes the inner pair it came from.
  struct FrontPair {
    std::uint32_t a, b, depth, parent;
  };

  std::uint32_t allocate_node();
  void free_node(std::uint32_t n);
  AabbF fat_box(std::uint32_t slot, const Vec3& displacement) const;
  void insert_leaf(std::uint32_t leaf);
  void remove_leaf(std::uint32_t leaf);
  std::uint32_t best_sibling(const AabbF& box) const;
  // Recomputes box, leaf count and height of n from its children.
  void refit(std::uint32_t n);
  // Refits from n to the root, rotating on the way when `rotate` is set.
  void walk_up(std::uint32_t n, bool rotate);
  void rotate(std::uint32_t n);
  void set_order(std::uint32_t n);
  void count_hit(std::uint32_t n, bool hit) const;
  void discard_front() { front_valid_ = false; }
  // Calls f(slot) for every object whose tight box overlaps b.
  template <class F>
  void for_each_overlapping_leaf(const AabbF& b, F&& f) const;
  // A fixed object moves for the first time: its cached pairs go, and the
  // traversal must now look at it.
  void make_dynamic(std::uint32_t slot);
  // Brings the cached pairs of a never-moved fixed object in line with the
  // filters.
  void recache_fixed(std::uint32_t slot);
  // The self-traversal behind for_each_pair; `visitor` may carry the filters.
  template <class V>
  QueryCost walk_pairs(V& visitor, TraversalStats& stats) const;
  void set_fixed_flags(std::uint32_t leaf);

  static bool boxes_overlap(const AabbF& a, const AabbF& b) { return a.overlaps(b); }
  // Half the surface area; only compared, so the factor 2 is dropped.
  static float area(const AabbF& b) {
    const float x = b.hi[0] - b.lo[0], y = b.hi[1] - b.lo[1], z = b.hi[2] - b.lo[2];
    return x * y + y * z + z * x;
  }
  static AabbF merged(const AabbF& a, const AabbF& b) {
    AabbF m;
    for (int k = 0; k < 3; ++k) {
      m.lo[k] = a.lo[k] < b.lo[k] ? a.lo[k] : b.lo[k];
      m.hi[k] = a.hi[k] > b.hi[k] ? a.hi[k] : b.hi[k];
    }
    return m;
  }
  static bool holds(const AabbF& outer, const AabbF& inner) {
    for (int k = 0; k < 3; ++k)
      if (!(outer.lo[k] <= inner.lo[k] && inner.hi[k] <= outer.hi[k])) return false;
    return true;
  }

  // Tests two leaves' objects: tight boxes, then the exact predicate.
  template <class V>
  bool leaf_pair(std::uint32_t x, std::uint32_t y, V& visitor, QueryCost& cost) const;
  // Every leaf pair below the node pair (a, b) (a == b: within one subtree).
  template <class V>
  bool brute(std::uint32_t a, std::uint32_t b, V& visitor, QueryCost& cost,
             TraversalStats& stats) const;
  // The self-traversal from `start`; records inner and terminal pairs when
  // `Record` (front tracking). Returns false when the visitor stopped.
  template <bool Record, class V>
  // `start_hits`: the start pair is already known to overlap.
  bool descend(Task start, V& visitor, QueryCost& cost, TraversalStats& stats,
               bool start_hits = false) const;
  template <class V>
  QueryCost pairs_with_front(V& visitor, TraversalStats& stats) const;

  std::vector<Node> nodes_;
  std::vector<std::uint32_t> leaf_;  // slot -> leaf node
  std::vector<AabbF> tight_;         // slot -> the object's own float box
  std::vector<std::uint8_t> moved_;  // slot -> has been updated (gets the margin)
  // Leaves refitted in place (front tracking) since the last reinsertion.
  std::vector<std::uint32_t> refitted_;
  std::vector<std::uint8_t> refitted_flag_;
  std::size_t refits_ = 0;
  static constexpr std::size_t kRefitsPerLeaf = 1;
  std::uint32_t root_ = kNull;
  std::uint32_t free_ = kNull;
  std::uint32_t node_count_ = 0;
  double margin_ = 0;
  double predict_ = 2;
  Order order_ = Order::leaves_first;
  FrontMode front_mode_ = FrontMode::off;
  std::uint32_t max_depth_ = 0;
  int near_axis_ = 0;
  mutable std::vector<HitStats> hit_stats_;  // per node, order=hit-ratio only
  // Exactly overlapping pairs of never-moved fixed objects: they cannot
  // change until one of the two moves or goes, so the traversal skips node
  // pairs that hold only such objects and all-pairs reports these directly.
  detail::PairTable fixed_pairs_;

  // Front tracking state: a cache of the last traversal, guarded by the
  // mutex because const all-pairs passes rewrite it.
  mutable std::mutex front_mutex_;
  mutable bool front_valid_ = false;
  mutable std::size_t front_built_size_ = 0;
  mutable std::vector<FrontPair> inner_, front_, next_inner_, next_front_;
  mutable std::vector<std::uint8_t> inner_state_;  // per inner pair: see pairs_with_front
  mutable std::vector<std::uint32_t> inner_map_;
  mutable std::vector<std::uint8_t> front_hits_;  // per terminal pair, this pass
};

// ---------------------------------------------------------------------------
// Traversals (templates: the visitor is inlined into the loops).

template <class V>
QueryCost AabbTree::query(const Shape& q, V&& visitor, TraversalStats& stats) const {
  require_valid(q);
  QueryCost cost;
  if (root_ == kNull) return cost;
  const AabbF qb = bounds_f(q);
  detail::InlineStack<std::uint32_t, 64> stack;
  stack.push(root_);
  while (!stack.empty()) {
    const std::uint32_t n = stack.pop();
    const Node& node = nodes_[n];
    ++stats.node_tests;
    const bool hit = boxes_overlap(node.box, qb);
    if (order_ == Order::hit_ratio) count_hit(n, hit);
    if (!hit) continue;
    if (node.is_leaf()) {
      const std::uint32_t o = node.object;
      if (!boxes_overlap(tight_[o], qb)) continue;
      ++cost.tests;
      if (overlaps(q, store_.shape(o)) && !visit(visitor, store_.handle(o))) {
        cost.stopped = true;
        return cost;
      }
      continue;
    }
    stack.push(node.child[1 - node.first]);
    stack.push(node.child[node.first]);
  }
  return cost;
}

template <class V>
QueryCost AabbTree::cast_ray(const Ray& r, V&& visitor) const {
  require_valid(r);
  detail::RayCast<std::remove_reference_t<V>> cast(store_, r, visitor);
  double t0;
  if (root_ == kNull || !cast.cull.enter(nodes_[root_].box, cast.tmax, t0)) return cast.cost;
  // Every node's box, and every object's tight box, lies inside the root's.
  const auto within = cast.cull.within(nodes_[root_].box);
  detail::ray_binary_walk(
      cast, within, root_, t0,
      [&](std::uint32_t n, detail::RayChildren& kids) {
        const Node& node = nodes_[n];
        if (node.is_leaf()) return false;
        kids = {{node.child[0], node.child[1]},
                {&nodes_[node.child[0]].box, &nodes_[node.child[1]].box}};
        return true;
      },
      [&](std::uint32_t n) {
        const Node& node = nodes_[n];
        return cast.test(node.object, tight_[node.object], within);
      });
  return cast.cost;
}

inline void AabbTree::closest_hits(std::span<const Ray> rays, std::span<RayHit> out,
                                   std::size_t flights_from) const {
  detail::require_valid_batch(rays, out.size(), "AabbTree::closest_hits");
  if (store_.size() < flights_from) {
    for (std::size_t i = 0; i < rays.size(); ++i) out[i] = closest_hit(*this, rays[i]);
    return;
  }
  if (root_ == kNull) {
    for (RayHit& h : out) h = {Handle{}, std::numeric_limits<double>::infinity()};
    return;
  }
  detail::ray_binary_closest_hits(
      store_, root_, nodes_[root_].box, rays, out,
      [&](std::uint32_t n, detail::RayChildren& kids) {
        const Node& node = nodes_[n];
        if (node.is_leaf()) return false;
        __builtin_prefetch(&nodes_[node.child[0]]);
        __builtin_prefetch(&nodes_[node.child[1]]);
        kids = {{node.child[0], node.child[1]},
                {&nodes_[node.child[0]].box, &nodes_[node.child[1]].box}};
        return true;
      },
      [&](std::uint32_t n) { __builtin_prefetch(&tight_[nodes_[n].object]); },
      [&](std::uint32_t n, const detail::RayCull::Within& within, double tmax, auto& found) {
        const std::uint32_t o = nodes_[n].object;
        double t;
        if (within.enter(tight_[o], tmax, t)) found.push({o, &tight_[o]});
      });
}

template <class V>
bool AabbTree::leaf_pair(std::uint32_t x, std::uint32_t y, V& visitor, QueryCost& cost) const {
  if (nodes_[x].fixed && nodes_[y].fixed) return true;  // in fixed_pairs_
  const std::uint32_t ox = nodes_[x].object, oy = nodes_[y].object;
  if (!boxes_overlap(tight_[ox], tight_[oy]) || !detail::admits(visitor, ox, oy)) return true;
  ++cost.tests;
  if (overlaps(store_.shape(ox), store_.shape(oy)) &&
      !visit(visitor, store_.handle(ox), store_.handle(oy))) {
    cost.stopped = true;
    return false;
  }
  return true;
}

template <class V>
bool AabbTree::brute(std::uint32_t a, std::uint32_t b, V& visitor, QueryCost& cost,
                     TraversalStats& stats) const {
  // Rare (only below max_depth), so plain vectors are fine here.
  auto leaves_of = [&](std::uint32_t n) {
    std::vector<std::uint32_t> out, stack{n};
    while (!stack.empty()) {
      const std::uint32_t m = stack.back();
      stack.pop_back();
      if (nodes_[m].is_leaf()) {
        out.push_back(m);
      } else {
        stack.push_back(nodes_[m].child[0]);
        stack.push_back(nodes_[m].child[1]);
      }
    }
    return out;
  };
  const std::vector<std::uint32_t> la = leaves_of(a);
  if (a == b) {
    for (std::size_t i = 0; i < la.size(); ++i)
      for (std::size_t j = i + 1; j < la.size(); ++j) {
        ++stats.brute_pairs;
        if (!leaf_pair(la[i], la[j], visitor, cost)) return false;
      }
    return true;
  }
  const std::vector<std::uint32_t> lb = leaves_of(b);
  for (const std::uint32_t x : la)
    for (const std::uint32_t y : lb) {
      ++stats.brute_pairs;
      if (!leaf_pair(x, y, visitor, cost)) return false;
    }
  return true;
}

template <bool Record, class V>
bool AabbTree::descend(Task start, V& visitor, QueryCost& cost, TraversalStats& stats,
                       bool start_hits) const {
  // Without a front to record, child pairs are tested before they are
  // pushed, so the stack only ever holds overlapping pairs (half the pushes
  // and pops, and each node is read while its parent is still in cache).
  // `parent` then marks a pair as already tested.
  constexpr std::uint32_t kTested = 0xfffffffeu;
  detail::InlineStack<Task, 128> stack;
  stack.push(start);
  bool first = start_hits;
  const bool limited = max_depth_ != 0;
  const bool count = order_ == Order::hit_ratio;
  auto test = [&](std::uint32_t a, std::uint32_t b) {
    ++stats.node_tests;
    const bool hit = boxes_overlap(nodes_[a].box, nodes_[b].box);
    if (count) {
      count_hit(a, hit);
      count_hit(b, hit);
    }
    return hit;
  };
  auto push = [&](std::uint32_t a, std::uint32_t b, std::uint32_t depth, std::uint32_t parent) {
    if (nodes_[a].fixed && nodes_[b].fixed) return;
    if constexpr (Record) {
      stack.push({a, b, depth, parent});
    } else if (test(a, b)) {
      stack.push({a, b, depth, kTested});
    }
  };
  while (!stack.empty()) {
    const Task t = stack.pop();
    const Node& na = nodes_[t.a];
    if (t.a == t.b) {
      first = false;
      // A subtree against itself always "overlaps": split it into both
      // children against themselves and the children against each other.
      if (na.is_leaf() || na.fixed) continue;
      if (limited && t.depth >= max_depth_) {
        if constexpr (Record) next_front_.push_back({t.a, t.b, t.depth, t.parent});
        if (!brute(t.a, t.b, visitor, cost, stats)) return false;
        continue;
      }
      std::uint32_t me = t.parent;
      if constexpr (Record) {
        me = static_cast<std::uint32_t>(next_inner_.size());
        next_inner_.push_back({t.a, t.b, t.depth, t.parent});
      }
      const std::uint32_t c0 = na.child[na.first], c1 = na.child[1 - na.first];
      push(c0, c1, t.depth + 1, me);
      if (!nodes_[c1].fixed) stack.push({c1, c1, t.depth + 1, me});
      if (!nodes_[c0].fixed) stack.push({c0, c0, t.depth + 1, me});
      continue;
    }
    const Node& nb = nodes_[t.b];
    if (na.fixed && nb.fixed) continue;
    const bool hit = (!Record && t.parent == kTested) || first || test(t.a, t.b);
    first = false;
    const bool terminal =
        !hit || (na.is_leaf() && nb.is_leaf()) || (limited && t.depth >= max_depth_);
    if (terminal) {
      if constexpr (Record) next_front_.push_back({t.a, t.b, t.depth, t.parent});
      if (!hit) continue;
      if (na.is_leaf() && nb.is_leaf()) {
        if (!leaf_pair(t.a, t.b, visitor, cost)) return false;
      } else if (!brute(t.a, t.b, visitor, cost, stats)) {
        return false;
      }
      continue;
    }
    std::uint32_t me = t.parent;
    if constexpr (Record) {
      me = static_cast<std::uint32_t>(next_inner_.size());
      next_inner_.push_back({t.a, t.b, t.depth, t.parent});
    }
    // Split the larger box (a leaf cannot be split), so that the two sides
    // of each test stay of similar size.
    if (nb.is_leaf() || (!na.is_leaf() && na.area >= nb.area)) {
      push(na.child[1 - na.first], t.b, t.depth + 1, me);
      push(na.child[na.first], t.b, t.depth + 1, me);
    } else {
      push(t.a, nb.child[1 - nb.first], t.depth + 1, me);
      push(t.a, nb.child[nb.first], t.depth + 1, me);
    }
  }
  return true;
}

template <class V>
QueryCost AabbTree::walk_pairs(V& visitor, TraversalStats& stats) const {
  QueryCost cost;
  for (const detail::PairTable::Pair& p : fixed_pairs_.pairs()) {
    if (!visit(visitor, store_.handle(p.a), store_.handle(p.b))) {
      cost.stopped = true;
      return cost;
    }
  }
  if (root_ == kNull) return cost;
  if (front_mode_ != FrontMode::off) {
    const QueryCost c = pairs_with_front(visitor, stats);
    return {cost.tests + c.tests, c.stopped};
  }
  descend<false>({root_, root_, 0, kNull}, visitor, cost, stats);
  return cost;
}

template <class V>
QueryCost AabbTree::pairs_with_front(V& visitor, TraversalStats& stats) const {
  std::lock_guard<std::mutex> lock(front_mutex_);
  QueryCost cost;
  const bool rebuild = !front_valid_ || (front_mode_ == FrontMode::deferred &&
                                         front_.size() > 2 * front_built_size_ + 64);
  next_inner_.clear();
  next_front_.clear();
  if (rebuild) {
    stats.front_rebuilt = true;
    front_valid_ = descend<true>({root_, root_, 0, kNull}, visitor, cost, stats);
    std::swap(inner_, next_inner_);
    std::swap(front_, next_front_);
    front_built_size_ = front_.size();
    stats.front_size = front_.size();
    return cost;
  }
  // The front is a cut through the tree of node pairs: every leaf pair lies
  // below exactly one terminal pair, and the inner pairs above the cut are
  // the ones whose boxes overlapped. The topology has not changed since it
  // was built (insert and remove discard it), only boxes have.
  //
  // inner_state_ per inner pair: 0 not yet known, 1 overlaps, 2 separated,
  // 3 raised (separated, parent overlaps: becomes terminal), 4 dropped (below
  // a raised pair).
  const std::size_t ni = inner_.size();
  inner_state_.assign(ni, 0);
  // Every terminal pair is tested once. One that overlaps proves that all
  // the inner pairs above it overlap (boxes nest), so they need no test.
  front_hits_.resize(front_.size());
  for (std::size_t k = 0; k < front_.size(); ++k) {
    const FrontPair& e = front_[k];
    ++stats.node_tests;
    const bool hit = boxes_overlap(nodes_[e.a].box, nodes_[e.b].box);
    front_hits_[k] = hit;
    if (hit && front_mode_ == FrontMode::basic)
      for (std::uint32_t p = e.parent; p != kNull && inner_state_[p] != 1; p = inner_[p].parent)
        inner_state_[p] = 1;
  }
  auto test_inner = [&](std::uint32_t i) {
    if (inner_state_[i] == 0) {
      const FrontPair& p = inner_[i];
      bool hit = true;
      if (p.a != p.b) {
        ++stats.node_tests;
        hit = boxes_overlap(nodes_[p.a].box, nodes_[p.b].box);
      }
      inner_state_[i] = hit ? 1 : 2;
    }
    return inner_state_[i] == 1;
  };
  // Raising (basic): from every terminal pair that separated, climb while
  // the parent pair separated too; the highest separated one is raised.
  if (front_mode_ == FrontMode::basic) {
    for (std::size_t k = 0; k < front_.size(); ++k) {
      const FrontPair& e = front_[k];
      if (front_hits_[k] || e.parent == kNull) continue;
      std::uint32_t i = e.parent;
      if (inner_state_[i] >= 3 || test_inner(i)) continue;
      while (inner_[i].parent != kNull && !test_inner(inner_[i].parent) &&
             inner_state_[inner_[i].parent] < 3)
        i = inner_[i].parent;
      inner_state_[i] = 3;
    }
  }
  // Parents come before children in inner_, so one pass settles which pairs
  // stay inner, which become terminal and which vanish under a raised pair.
  inner_map_.assign(ni, kNull);
  for (std::uint32_t i = 0; i < ni; ++i) {
    const FrontPair& p = inner_[i];
    const std::uint32_t up = p.parent;
    if (up != kNull && (inner_state_[up] == 3 || inner_state_[up] == 4)) {
      inner_state_[i] = 4;
      continue;
    }
    const std::uint32_t mapped_up = up == kNull ? kNull : inner_map_[up];
    if (inner_state_[i] == 3) {
      next_front_.push_back({p.a, p.b, p.depth, mapped_up});
      continue;
    }
    inner_map_[i] = static_cast<std::uint32_t>(next_inner_.size());
    next_inner_.push_back({p.a, p.b, p.depth, mapped_up});
  }
  // Lowering: terminal pairs that overlap again descend from where they are.
  bool go_on = true;
  for (std::size_t k = 0; k < front_.size(); ++k) {
    const FrontPair& e = front_[k];
    if (e.parent != kNull && inner_state_[e.parent] >= 3) continue;
    const std::uint32_t up = e.parent == kNull ? kNull : inner_map_[e.parent];
    if (!go_on || !front_hits_[k]) {
      next_front_.push_back({e.a, e.b, e.depth, up});
      continue;
    }
    go_on = descend<true>({e.a, e.b, e.depth, up}, visitor, cost, stats, true);
  }
  std::swap(inner_, next_inner_);
  std::swap(front_, next_front_);
  // A visitor that stopped early leaves a partly lowered front behind.
  front_valid_ = go_on;
  stats.front_size = front_.size();
  return cost;
}

}  // namespace broadphase
