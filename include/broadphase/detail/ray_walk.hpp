/// \file detail/ray_walk.hpp
/// The ray walks the structures share, written once per family:
///
///   - `ray_tree_walk`: front to back through a tree whose nodes have boxes
///     holding every object below them (the octrees, the k-d tree, the AABB
///     tree), on a growable stack, pruning nodes entered beyond the current
///     (clipped) tmax;
///   - `RayGridMarch`: the cells of a grid along a ray, conservative with
///     respect to the contract's evaluation, for the grids whose cells are a
///     monotone map of coordinates (grid-dense, grid-hashed, grid-hybrid,
///     grid-static, grid-implicit, the levels of the hierarchical grids);
///   - `RaySlots`: the objects a cast has tested already, so that an object
///     entered into several cells is tested and reported once per ray.
///
/// All of them cull with detail::RayCull (ray.hpp), never with real-number
/// geometry, and keep no state between calls: const casts may run
/// concurrently.
#pragma once

#include <algorithm>
#include <array>
#include <broadphase/detail/grid_common.hpp>
#include <broadphase/detail/inline_stack.hpp>
#include <broadphase/detail/node_items.hpp>
#include <broadphase/handle.hpp>
#include <broadphase/ray.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <utility>
#include <vector>

namespace broadphase::detail {

/// What one cast carries through a walk: the objects, the ray, its
/// culling, the live tmax (clipped by the visitor, negative once it
/// stopped) and the cost.
template <class V>
struct RayCast {
  RayCast(const ObjectStore& s, const Ray& r, V& v) : RayCast(&s, r, v) {}
  /// For a structure that keeps its objects itself (test_object only).
  RayCast(const ObjectStore* s, const Ray& r, V& v)
      : store(s), ray(r), cull(r), tmax(r.tmax), visitor(v) {}

  /// Tests object `slot` of the store exactly (mask first) and reports a
  /// hit; false when the visitor stopped the cast.
  bool test(std::uint32_t slot) {
    return test_object(store->handle(slot), store->shape(slot), store->filter(slot).group);
  }
  /// Tests an object given by its handle, shape and group (mask first).
  bool test_object(Handle h, const Shape& shape, std::uint32_t group) {
    if ((group & ray.mask) == 0) return true;
    ++cost.tests;
    double t;
    if (!ray_hit(ray.origin, ray.dir, tmax, shape, t)) return true;
    tmax = visit_hit(visitor, h, t, tmax);
    if (tmax < 0) {
      cost.stopped = true;
      return false;
    }
    return true;
  }
  /// As `test`, culling first by the object's stored float box (which holds
  /// its bounds, so the culling is conservative).
  bool test(std::uint32_t slot, const AabbF& box) { return test(slot, box, cull); }
  /// As `test`, culling by `box` with `c` (RayCull or RayCull::Within).
  template <class Cull>
  bool test(std::uint32_t slot, const AabbF& box, const Cull& c) {
    double t;
    if (!c.enter(box, tmax, t)) return true;
    return test(slot);
  }

  const ObjectStore* store;
  const Ray& ray;
  RayCull cull;
  double tmax;
  V& visitor;
  QueryCost cost;
};

/// The interval of axis `a` that every object hit by `r` at t <= `tl`
/// reaches: the points o + t·d for t in [0, tl], grown by RayCull's margin
/// of a box holding them, which is at most M0 + M1·t (M0 from |o|, M1 from
/// |d|: RayCull::margin); doubled against the rounding of the bound itself.
/// `tl` may be infinite: an end that runs off with t is then infinite, and
/// so is an end that the growing margin outruns.
inline void ray_axis_reach(const Ray& r, double tl, int a, double& lo, double& hi) {
  double om = 0, dm = 0;
  for (int k = 0; k < 3; ++k) {
    om = std::max(om, std::fabs(r.origin[k]));
    dm = std::max(dm, std::fabs(r.dir[k]));
  }
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double m0 = 2 * (2 * om * RayCull::kMargin + kBoundsFloor);
  const double m1 = 2 * dm * RayCull::kMargin;
  const double o = r.origin[a];
  const double d = r.dir[a];
  if (tl <= std::numeric_limits<double>::max()) {
    const double end = o + tl * d;
    const double m = m0 + m1 * tl;
    lo = std::min(o, end) - 2 * m;
    hi = std::max(o, end) + 2 * m;
    return;
  }
  lo = d - m1 >= 0 ? o - 2 * m0 : -kInf;
  hi = d + m1 <= 0 ? o + 2 * m0 : kInf;
}

/// The largest float at or below `v` (-inf below the floats' range).
inline float float_below(double v) {
  constexpr float kMax = std::numeric_limits<float>::max();
  if (!(v >= -static_cast<double>(kMax))) return -std::numeric_limits<float>::infinity();
  if (v >= static_cast<double>(kMax))
    return v == std::numeric_limits<double>::infinity() ? std::numeric_limits<float>::infinity()
                                                        : kMax;
  float f = static_cast<float>(v);
  if (static_cast<double>(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
/// The smallest float at or above `v` (+inf above the floats' range).
inline float float_above(double v) { return -float_below(-v); }

/// A set of slots, for the objects a cast has tested: open addressing in
/// an inline table of 64 entries, growing onto the heap beyond half of it,
/// so that a short ray never allocates and a long one never loses an entry.
class RaySlots {
 public:
  RaySlots() { inline_.fill(kEmpty); }
  RaySlots(const RaySlots&) = delete;
  RaySlots& operator=(const RaySlots&) = delete;

  /// Adds `slot`; true when it was not there yet.
  bool insert(std::uint32_t slot) {
    std::uint32_t* table = heap_.empty() ? inline_.data() : heap_.data();
    const std::size_t mask = capacity() - 1;
    for (std::size_t i = home(slot) & mask;; i = (i + 1) & mask) {
      if (table[i] == slot) return false;
      if (table[i] == kEmpty) {
        table[i] = slot;
        if (2 * ++size_ > capacity()) grow();
        return true;
      }
    }
  }
  /// True when `slot` is in the set.
  bool contains(std::uint32_t slot) const {
    const std::uint32_t* table = heap_.empty() ? inline_.data() : heap_.data();
    const std::size_t mask = capacity() - 1;
    for (std::size_t i = home(slot) & mask;; i = (i + 1) & mask) {
      if (table[i] == slot) return true;
      if (table[i] == kEmpty) return false;
    }
  }

 private:
  static constexpr std::uint32_t kEmpty = 0xffffffffu;
  static std::size_t home(std::uint32_t slot) {
    return static_cast<std::size_t>((slot * 0x9E3779B1u) >> 7);
  }
  std::size_t capacity() const { return heap_.empty() ? inline_.size() : heap_.size(); }
  void grow() {
    std::vector<std::uint32_t> next(2 * capacity(), kEmpty);
    const std::uint32_t* table = heap_.empty() ? inline_.data() : heap_.data();
    const std::size_t old = capacity();
    const std::size_t mask = next.size() - 1;
    for (std::size_t j = 0; j < old; ++j) {
      if (table[j] == kEmpty) continue;
      std::size_t i = home(table[j]) & mask;
      while (next[i] != kEmpty) i = (i + 1) & mask;
      next[i] = table[j];
    }
    heap_ = std::move(next);
  }

  std::array<std::uint32_t, 64> inline_;
  std::vector<std::uint32_t> heap_;
  std::size_t size_ = 0;
};

/// A node of a tree walk's stack and the parameter where the ray enters it.
struct RayStackEntry {
  std::uint32_t node;
  double t;
};

/// The stack both tree walks run on: pops the nearest-pushed node, drops it
/// when its entry lies beyond the live tmax, and hands it to
/// `open(node, stack)`, which pushes its children (far first) and returns
/// false when the visitor stopped. An InlineStack, which spills to the
/// heap: no depth drops a node.
template <class Cast, class Open>
void ray_stack_walk(Cast& cast, std::uint32_t root, double root_t, Open&& open) {
  InlineStack<RayStackEntry, 64> stack;
  stack.push({root, root_t});
  while (!stack.empty()) {
    const RayStackEntry e = stack.pop();
    if (e.t > cast.tmax) continue;
    if (!open(e.node, stack)) return;
  }
}

/// Walks a tree front to back. `root` is entered at parameter `root_t`
/// (0 for a root that is not culled: the octrees' roots also hold the
/// objects outside their cube). `for_each_child(n, f)` calls f(child, box)
/// for each child worth visiting, with a box (Aabb or AabbF) holding every
/// object below the child; `items(n)` tests node n's own objects through
/// the cast and returns false when the visitor stopped.
///
/// Nodes are popped nearest entry first: the children of a node are pushed
/// far to near, so the nearer is walked first, and a node whose entry lies
/// beyond the live tmax is dropped unopened (RayCull's entry is never
/// beyond the t of a hit inside it, so no hit is lost: hits at exactly the
/// clipped tmax are still reported), on ray_stack_walk's stack. Child
/// boxes are culled with
/// `cull`: the cast's RayCull, or a RayCull::Within of a box holding them.
template <class Cast, class Cull, class Children, class Items>
void ray_tree_walk(Cast& cast, const Cull& cull, std::uint32_t root, double root_t,
                   Children&& for_each_child, Items&& items) {
  ray_stack_walk(cast, root, root_t, [&](std::uint32_t node, auto& stack) {
    if (!items(node)) return false;
    // At most eight children (an octree's); any beyond go straight on the
    // stack unordered, still walked.
    RayStackEntry kids[8];
    int count = 0;
    for_each_child(node, [&](std::uint32_t c, const auto& b) {
      double t;
      if (!cull.enter(b, cast.tmax, t)) return;
      if (count < 8)
        kids[count++] = {c, t};
      else
        stack.push({c, t});
    });
    // Insertion sort, far first, so that the nearest is popped next.
    for (int i = 1; i < count; ++i)
      for (int j = i; j > 0 && kids[j - 1].t < kids[j].t; --j) std::swap(kids[j - 1], kids[j]);
    for (int i = 0; i < count; ++i) stack.push(kids[i]);
    return true;
  });
}
/// ray_tree_walk culling every box with the cast's RayCull, for a tree
/// whose `for_each_child(n, f)` calls f(child) and `box(child)` gives the
/// child's box (never asked of the root).
template <class Cast, class Box, class Children, class Items>
void ray_tree_walk(Cast& cast, std::uint32_t root, double root_t, Box&& box,
                   Children&& for_each_child, Items&& items) {
  ray_tree_walk(
      cast, cast.cull, root, root_t,
      [&](std::uint32_t n, auto&& f) { for_each_child(n, [&](std::uint32_t c) { f(c, box(c)); }); },
      std::forward<Items>(items));
}

/// The two children of a binary tree's inner node and their float boxes,
/// as ray_binary_walk asks for them.
struct RayChildren {
  std::uint32_t node[2];
  const AabbF* box[2];
};

/// One step of ray_binary_walk at an inner node: culls both children at
/// once (RayCull::Within::enter2) against the live `tmax` and pushes those
/// the ray enters, the nearer on top (the second child on a tie).
template <class Stack>
void ray_push_children(double tmax, const RayCull::Within& cull, const RayChildren& kids,
                       Stack& stack) {
  double t0 = 0, t1 = 0;
  switch (cull.enter2(*kids.box[0], *kids.box[1], tmax, t0, t1)) {
    case 1:
      stack.push({kids.node[0], t0});
      break;
    case 2:
      stack.push({kids.node[1], t1});
      break;
    case 3:
      if (t0 < t1) {
        stack.push({kids.node[1], t1});
        stack.push({kids.node[0], t0});
      } else {
        stack.push({kids.node[0], t0});
        stack.push({kids.node[1], t1});
      }
      break;
    default:
      break;
  }
}

/// ray_tree_walk for a binary tree (the k-d tree, the AABB tree) whose
/// boxes all lie in the box `cull` was made for: `children(n, kids)` fills
/// `kids` and returns true for an inner node, false for a leaf, whose
/// objects `items(n)` tests (false when the visitor stopped). Both
/// children's boxes are culled at once (RayCull::Within::enter2), and
/// walked in ray_tree_walk's order: the nearer first, the second child
/// first on a tie.
template <class Cast, class Children, class Items>
void ray_binary_walk(Cast& cast, const RayCull::Within& cull, std::uint32_t root, double root_t,
                     Children&& children, Items&& items) {
  RayChildren kids;
  ray_stack_walk(cast, root, root_t, [&](std::uint32_t node, auto& stack) {
    if (!children(node, kids)) return items(node);
    ray_push_children(cast.tmax, cull, kids, stack);
    return true;
  });
}

/// An object a batch walk found in a leaf (its box entered by the ray):
/// its slot, and a box holding it, to cull it again after a clip.
struct RayFound {
  std::uint32_t slot;
  const AabbF* box;
};

/// Rays a batch walk keeps in flight. Measured on the k-d tree (10^5
/// uniform spheres, 10^5 random rays, closest hits, one thread, Intel Xeon,
/// quiet): 4, 8 and 16 cast 1.20-1.24, 1.26-1.29 and 1.28-1.29 times as
/// many rays a second as one ray at a time; 8 keeps the rays' state (about
/// 1.2 KiB each) inside L1.
inline constexpr std::size_t kRayFlights = 8;
/// The objects from which a tree's batch walks several rays at once. Below,
/// its nodes and objects stay in the caches, and one ray at a time is
/// faster (the k-d tree, as above: 0.84-0.87 times at 10^3 objects, 0.94 at
/// 10^4, 1.06 at 3·10^4, 1.12-1.15 at 5·10^4).
inline constexpr std::size_t kRayFlightsFrom = std::size_t{1} << 15;

/// The closest hits of many rays through a binary tree: for each ray,
/// closest_hit's result bit for bit, by ray_binary_walk's nodes, order and
/// tests, but kRayFlights rays in flight, each taking one step in turn, so
/// that one ray's loads arrive while the others work. A step opens a node
/// (`children(n, kids)` as ray_binary_walk's, which starts the loads of the
/// children's records), or culls a popped leaf's objects
/// (`stage_leaf(n)` started their loads a step before; `cull_leaf(n,
/// within, tmax, found)` pushes a RayFound for each object whose box the
/// ray enters before tmax, in the leaf's order), or tests the objects found
/// (their shapes loaded since), culling one again if a hit clipped the ray
/// since. `rays` are valid, `out` as long; the tree's root `root`, its box
/// `root_box` holding every box below it.
template <class Children, class StageLeaf, class CullLeaf>
void ray_binary_closest_hits(const ObjectStore& store, std::uint32_t root, const AabbF& root_box,
                             std::span<const Ray> rays, std::span<RayHit> out, Children&& children,
                             StageLeaf&& stage_leaf, CullLeaf&& cull_leaf) {
  constexpr std::uint32_t kNoLeaf = 0xffffffffu;
  struct Flight {
    ClosestHit closest;  // closest_hit's visitor, kept with its cast
    std::optional<RayCast<ClosestHit>> cast;
    RayCull::Within within;
    InlineStack<RayStackEntry, 64> stack;
    std::uint32_t leaf = kNoLeaf;     // popped, its objects on their way
    InlineStack<RayFound, 16> found;  // culled in, their shapes on their way
    double found_tmax = 0;            // the tmax they were culled with
    std::size_t ray = 0;
  };
  // Starts ray i in f; false when it is done at once (it misses the root).
  const auto start = [&](Flight& f, std::size_t i) {
    f.ray = i;
    f.closest = ClosestHit{};
    f.cast.emplace(store, rays[i], f.closest);
    f.stack.clear();
    f.leaf = kNoLeaf;
    double t0;
    if (!f.cast->cull.enter(root_box, f.cast->tmax, t0)) return false;
    f.within = f.cast->cull.within(root_box);
    f.stack.push({root, t0});
    return true;
  };
  // One step; false when the ray is done.
  const auto step = [&](Flight& f) {
    RayCast<ClosestHit>& cast = *f.cast;
    if (!f.found.empty()) {
      for (std::size_t j = 0; j < f.found.size(); ++j) {
        const RayFound& o = f.found[j];
        if (!(cast.tmax == f.found_tmax ? cast.test(o.slot) : cast.test(o.slot, *o.box, f.within)))
          return false;
      }
      f.found.clear();
      return !f.stack.empty();
    }
    if (f.leaf != kNoLeaf) {
      f.found_tmax = cast.tmax;
      cull_leaf(std::exchange(f.leaf, kNoLeaf), f.within, f.found_tmax, f.found);
      for (std::size_t j = 0; j < f.found.size(); ++j) store.prefetch(f.found[j].slot);
      return !f.found.empty() || !f.stack.empty();
    }
    while (!f.stack.empty()) {
      const RayStackEntry e = f.stack.pop();
      if (e.t > cast.tmax) continue;
      RayChildren kids;
      if (!children(e.node, kids)) {
        stage_leaf(e.node);
        f.leaf = e.node;
        return true;
      }
      ray_push_children(cast.tmax, f.within, kids, f.stack);
      return !f.stack.empty();
    }
    return false;
  };
  std::array<Flight, kRayFlights> flights;
  std::array<bool, kRayFlights> live{};
  std::size_t next = 0;
  // Starts the next ray that is not done at once in slot k.
  const auto refill = [&](std::size_t k) {
    while (next < rays.size()) {
      const std::size_t i = next++;
      if (start(flights[k], i)) return true;
      out[i] = flights[k].closest.best;
    }
    return false;
  };
  std::size_t flying = 0;
  for (std::size_t k = 0; k < kRayFlights; ++k) flying += (live[k] = refill(k));
  while (flying > 0)
    for (std::size_t k = 0; k < kRayFlights; ++k) {
      if (!live[k] || step(flights[k])) continue;
      out[flights[k].ray] = flights[k].closest.best;
      if (!(live[k] = refill(k))) --flying;
    }
}

/// A box holding every object a grid has placed since it was last
/// cleared: grown on each placement, never shrunk (so always conservative,
/// O(1) to keep), cleared when the grid re-enters all its objects. It ends
/// a ray's march where the ray leaves the occupied space, instead of at the
/// edge of an unbounded cell map.
struct OccupiedBox {
  AabbF box{{kEmptyLo, kEmptyLo, kEmptyLo}, {-kEmptyLo, -kEmptyLo, -kEmptyLo}};

  void add(const AabbF& b) {
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = std::min(box.lo[a], b.lo[a]);
      box.hi[a] = std::max(box.hi[a], b.hi[a]);
    }
  }
  void clear() { *this = OccupiedBox{}; }
  bool empty() const { return !(box.lo[0] <= box.hi[0]); }
  /// True when `b` lies inside (for validate()).
  bool holds(const AabbF& b) const {
    for (int a = 0; a < 3; ++a)
      if (!(box.lo[a] <= b.lo[a] && b.hi[a] <= box.hi[a])) return false;
    return true;
  }
  Aabb as_double() const {
    return {{box.lo[0], box.lo[1], box.lo[2]}, {box.hi[0], box.hi[1], box.hi[2]}};
  }

 private:
  static constexpr float kEmptyLo = std::numeric_limits<float>::infinity();
};

/// The parameters [tn, tf] within [0, tmax] over which the ray is inside
/// `b` grown by twice RayCull's margin; false when it never is. No object
/// inside `b` is hit at a t outside them: a hit's point lies within the
/// margin of the object (RayCull), and the slab's own rounding is a few
/// ulps of t, far below the second margin.
inline bool ray_span(const RayCull& c, const Aabb& b, double tmax, double& tn, double& tf) {
  const double m = 2 * c.margin(b);
  tn = 0;
  tf = tmax;
  for (int a = 0; a < 3; ++a) {
    const double lo = (b.lo[a] - m) - c.origin()[a];
    const double hi = (b.hi[a] + m) - c.origin()[a];
    const double d = c.dir()[a];
    if (d == 0) {
      if (lo > 0 || hi < 0) return false;
      continue;
    }
    double t1 = lo / d;
    double t2 = hi / d;
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > tn) tn = t1;
    if (t2 < tf) tf = t2;
  }
  return tn <= tf;
}

/// The cells of one grid (or one level of a hierarchy) that a ray passes,
/// conservatively, for grids whose cell coordinates are a non-decreasing
/// function of the coordinates, clamped (grid_common.hpp, CellMap).
///
/// What it guarantees: if `ray_hit` reports object X at t <= the live tmax,
/// some cell in which X is entered is visited. The argument: the point
/// P = o + t·d lies within RayCull's margin of X's bounds (the errors of
/// the evaluation are a few ulps of |o| + |P|, which the margin, 2^-20 of
/// that, covers more than thirtyfold: see RayCull), so the cell coordinate
/// of some point of X's bounds, and hence (monotone map) a cell X is
/// entered in, lies in the cell range of the box of the ray's points over
/// [ta, tb] grown by that margin, for the step [ta, tb] that holds t. The
/// steps cover [0, tmax] without a gap: the march steps through the grid's
/// own region one cell of the fastest axis at a time, and takes what lies
/// beyond it (where the clamped coordinates no longer change) in one
/// stretch, whose margin grows with the distance, bounded analytically
/// when tmax is infinite. Grids that enter objects by the cell of their
/// centre give `reach`, the largest distance from a point of an object's
/// bounds to its centre, and every box is grown by it too.
///
/// Bounded cost: a march that would visit more cells than `budget` stops
/// and asks for a scan of every object instead (`scan`), never more work
/// than the brute force it replaces. Each object is tested once per ray
/// (RaySlots), however many of the visited cells it is entered in.
struct RayGridLevel {
  Vec3 origin;         ///< corner of cell (0, 0, 0)
  double cell = 1;     ///< cell edge
  double index_lo[3];  ///< lowest cell coordinate per axis (the clamp)
  double index_hi[3];  ///< highest cell coordinate per axis
  double reach = 0;    ///< see RayGridMarch (0: objects entered by their bounds)
};

/// The march's view of a CellMap (objects entered by their bounds).
inline RayGridLevel ray_level(const CellMap& m) {
  RayGridLevel l;
  l.origin = m.origin();
  l.cell = m.cell();
  for (int a = 0; a < 3; ++a) {
    l.index_lo[a] = m.index_lo(a);
    l.index_hi[a] = m.index_hi(a);
  }
  return l;
}

/// How a march of RayGridMarch ended.
enum class RayMarchOutcome {
  finished,  ///< every cell up to the live tmax visited
  stopped,   ///< the visitor stopped the cast
  scan,      ///< out of budget: the caller tests the objects not yet tested
};

/// See RayGridLevel. `coord(x, axis)` is the grid's own monotone map;
/// `cell(key)` visits the objects of one cell, calling back `f(slot)`
/// (through the cast's test) and returning false when the cast stopped.
template <class Coord, class Cell>
class RayGridMarch {
 public:
  RayGridMarch(const RayGridLevel& level, Coord coord, Cell cell)
      : level_(level), coord_(coord), cell_(cell) {}

  /// How a march ended (RayMarchOutcome).
  using Outcome = RayMarchOutcome;

  /// Marches `cast`'s ray from t = 0 to its live tmax (only over the part
  /// inside `occupied`, when given: see OccupiedBox), visiting at most
  /// `budget` cells (see the class comment).
  template <class Cast>
  Outcome march(Cast& cast, double budget, const OccupiedBox* occupied = nullptr) const {
    if (occupied == nullptr) return march_within(cast, budget, nullptr);
    if (occupied->empty()) return Outcome::finished;
    const Aabb box = occupied->as_double();
    return march_within(cast, budget, &box);
  }

  /// As `march`, over the part of the ray inside `within` (a box holding
  /// every object the march must find; null: the whole ray).
  template <class Cast>
  Outcome march_within(Cast& cast, double budget, const Aabb* within) const {
    const Vec3& o = cast.ray.origin;
    const Vec3& d = cast.ray.dir;
    // Where the ray is inside the box, when there is one: no object inside
    // it is hit before t_from or after t_end.
    double t_from = 0;
    double t_end = std::numeric_limits<double>::infinity();
    if (within != nullptr && !ray_span(cast.cull, *within, cast.tmax, t_from, t_end))
      return Outcome::finished;
    // The grid's own region, one cell wider each side: beyond it on every
    // axis the clamped coordinates stop changing. It only guides the step
    // sizes; correctness rests on the boxes' ranges alone.
    double enter_at[3], leave_at[3];
    double t_all = 0;
    for (int a = 0; a < 3; ++a) {
      const double glo = level_.origin[a] + (level_.index_lo[a] - 1) * level_.cell;
      const double ghi = level_.origin[a] + (level_.index_hi[a] + 2) * level_.cell;
      if (d[a] == 0) {
        enter_at[a] = kInf;
        leave_at[a] = -kInf;
        continue;
      }
      double t1 = (glo - o[a]) / d[a];
      double t2 = (ghi - o[a]) / d[a];
      if (t1 > t2) std::swap(t1, t2);
      enter_at[a] = t1;
      leave_at[a] = t2;
      if (t2 > t_all) t_all = t2;
    }
    t_all = std::min(t_all, t_end);
    if (!(t_all <= std::numeric_limits<double>::max())) t_all = std::numeric_limits<double>::max();
    CellRange prev;  // empty
    double visited = 0;
    double t = t_from;
    // The first step always runs: a ray with tmax = 0 (or leaving the
    // region at once) still meets the cells about its origin.
    for (bool first = true; first || (t < cast.tmax && t < t_all); first = false) {
      // One cell of the fastest axis inside the region, or a jump to where
      // an axis enters it.
      double tb = std::min(t_all, cast.tmax);
      for (int a = 0; a < 3; ++a) {
        if (d[a] == 0) continue;
        if (t >= enter_at[a] && t < leave_at[a])
          tb = std::min(tb, t + level_.cell / std::fabs(d[a]));
        else if (enter_at[a] > t)
          tb = std::min(tb, enter_at[a]);
      }
      if (!(tb > t)) tb = std::nextafter(t, kInf);  // cells below the ulps of t
      CellRange r;
      segment_range(o, d, t, tb, cast.cull, r);
      if (visited + r.cells() > budget) return Outcome::scan;
      if (!visit_range(r, prev, visited)) return Outcome::stopped;
      prev = r;
      t = tb;
    }
    const double last = std::min(cast.tmax, t_end);
    if (!(t < last)) return Outcome::finished;
    // Beyond the region: the rest of the ray in one stretch.
    CellRange r;
    if (last <= std::numeric_limits<double>::max())
      segment_range(o, d, t, last, cast.cull, r);
    else
      tail_range(o, d, t, r);
    if (visited + r.cells() > budget) return Outcome::scan;
    if (!visit_range(r, prev, visited)) return Outcome::stopped;
    return Outcome::finished;
  }

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();

  std::int32_t coord(double x, int a) const { return coord_(x, a); }

  // The cells of the box of the ray's points over [ta, tb], grown by the
  // margin and the reach.
  void segment_range(const Vec3& o, const Vec3& d, double ta, double tb, const RayCull& cull,
                     CellRange& r) const {
    Aabb box;
    for (int a = 0; a < 3; ++a) {
      const double p = d[a] == 0 ? o[a] : o[a] + ta * d[a];
      const double q = d[a] == 0 ? o[a] : o[a] + tb * d[a];
      box.lo[a] = std::min(p, q);
      box.hi[a] = std::max(p, q);
    }
    const double m = cull.margin(box) + level_.reach;
    for (int a = 0; a < 3; ++a) {
      r.lo[a] = coord(box.lo[a] - m, a);
      r.hi[a] = coord(box.hi[a] + m, a);
    }
  }

  // The cells of every point o + s·d, s >= t, grown by a margin that grows
  // with the distance: RayCull's margin of a box of such points is at most
  // M0 + M1·s (|o|, |d| the largest components), so on each axis the grown
  // box's low end is at least o + s·(d - M1) - M0, which has its least
  // value at s = t when d >= M1 and none (-inf) otherwise; the high end
  // likewise. The constants are doubled against their own rounding.
  void tail_range(const Vec3& o, const Vec3& d, double t, CellRange& r) const {
    double om = 0, dm = 0;
    for (int a = 0; a < 3; ++a) {
      om = std::max(om, std::fabs(o[a]));
      dm = std::max(dm, std::fabs(d[a]));
    }
    const double m1 = 2 * RayCull::kMargin * dm;
    const double m0 = 2 * (2 * om * RayCull::kMargin + kBoundsFloor) + level_.reach;
    for (int a = 0; a < 3; ++a) {
      const double at_t = d[a] == 0 ? o[a] : o[a] + t * d[a];
      const double grow = m0 + m1 * t;
      const double lo = d[a] - m1 >= 0 ? at_t - 2 * grow : -kInf;
      const double hi = d[a] + m1 <= 0 ? at_t + 2 * grow : kInf;
      r.lo[a] = coord(lo, a);
      r.hi[a] = coord(hi, a);
    }
  }

  // Visits the cells of `r` not in `prev` (the previous step's, whose
  // objects are all in the cast's tested set already).
  bool visit_range(const CellRange& r, const CellRange& prev, double& visited) const {
    CellKey k;
    for (k.c[2] = r.lo[2]; k.c[2] <= r.hi[2]; ++k.c[2])
      for (k.c[1] = r.lo[1]; k.c[1] <= r.hi[1]; ++k.c[1])
        for (k.c[0] = r.lo[0]; k.c[0] <= r.hi[0]; ++k.c[0]) {
          if (prev.contains(k)) continue;
          visited += 1;
          if (!cell_(k)) return false;
        }
    return true;
  }

  RayGridLevel level_;
  Coord coord_;
  Cell cell_;
};

/// A cast through a nested tree (the octrees' interface of tree_walk.hpp:
/// `root()`, `items(n)` of OctItem, `box(n)`, `for_each_child(n, f)`),
/// whose root is not culled: it also holds the objects outside the cube.
template <class Tree, class V>
QueryCost tree_cast_ray(const Tree& tree, const ObjectStore& store, const Ray& r, V& visitor) {
  require_valid(r);
  RayCast<V> cast(store, r, visitor);
  ray_tree_walk(
      cast, tree.root(), 0.0, [&](std::uint32_t n) -> decltype(auto) { return tree.box(n); },
      [&](std::uint32_t n, auto&& f) { tree.for_each_child(n, f); },
      [&](std::uint32_t n) {
        for (const OctItem& it : tree.items(n))
          if (!cast.test(it.slot, it.box)) return false;
        return true;
      });
  return cast.cost;
}

/// One grid (or one level of a hierarchy) of a cast: the march of
/// RayGridMarch over `level` with the grid's `coord(x, axis)`, each object
/// tested once (`tested`, shared by the levels of a hierarchy). The grid
/// gives `for_cell(key, f)`, calling f(slot) for the objects entered in
/// cell `key` and false as soon as f does, `for_all(f)` likewise over
/// every object of the grid (the scan of a march out of budget), and
/// `box_of(slot)`, a float box holding the object (its stored bounds);
/// `occupied`, when not null, holds every object of the grid
/// (OccupiedBox). `budget`: cells worth visiting before a scan is cheaper
/// (about the grid's object count). False when the visitor stopped the cast.
template <class Cast, class Coord, class ForCell, class ForAll, class BoxOf>
bool ray_level_cast(Cast& cast, RaySlots& tested, const RayGridLevel& level, double budget,
                    const OccupiedBox* occupied, Coord&& coord, ForCell&& for_cell,
                    ForAll&& for_all, BoxOf&& box_of) {
  auto test = [&](std::uint32_t s) { return !tested.insert(s) || cast.test(s, box_of(s)); };
  auto cell = [&](const CellKey& k) { return for_cell(k, test); };
  const RayGridMarch march(
      level, [&](double x, int a) { return coord(x, a); }, cell);
  using Outcome = typename decltype(march)::Outcome;
  switch (march.march(cast, budget, occupied)) {
    case Outcome::finished:
      return true;
    case Outcome::stopped:
      return false;
    case Outcome::scan:
      break;
  }
  return for_all([&](std::uint32_t s) { return tested.contains(s) || cast.test(s, box_of(s)); });
}

/// A grid's cast, the opening every grid shares: the ray checked (throws
/// InvalidRay), the objects the grid keeps outside its cells (`loose`: an
/// overflow or oversize list of slots) tested first, each culled by
/// `box_of(slot)` (as in ray_level_cast), then `levels(cast, tested)`,
/// which marches the grid's levels (ray_level_cast, each object tested
/// once through `tested`) and may stop when the cast stopped.
template <class V, class Loose, class BoxOf, class Levels>
QueryCost ray_grid_cast(const ObjectStore& store, const Ray& r, V& visitor, const Loose& loose,
                        BoxOf&& box_of, Levels&& levels) {
  require_valid(r);
  RayCast<V> cast(store, r, visitor);
  for (std::uint32_t b : loose)
    if (!cast.test(b, box_of(b))) return cast.cost;
  RaySlots tested;
  levels(cast, tested);
  return cast.cost;
}

}  // namespace broadphase::detail
