// QuantizedSweep (see quantized_sweep.hpp): the grid, the end-point walks
// and the pair events, written to issue Bullet's calls in Bullet's order.
// Compiled once against float Bullet and once against double Bullet, like
// bullet.cpp: the grid positions are computed in btScalar with the same
// operations as Bullet's (a subtraction and a product per coordinate, the
// scale a quotient), so they are the same numbers.
#include "quantized_sweep.hpp"

#include <broadphase/config_error.hpp>
#include <cmath>
#include <string>
#include <utility>

namespace broadphase::bullet_detail {

/// A proxy of the sweep: Bullet's proxy (box, filters, number) and where
/// its end points are on each axis.
struct QuantizedSweep::Proxy : btBroadphaseProxy {
  std::uint32_t low[3];   // index of its low end point on each axis
  std::uint32_t high[3];  // index of its high end point on each axis

  // A free proxy links the free list through low[0], as Bullet's handles
  // do: with a deferred cache, the pairs of a destroyed proxy stay in the
  // cache until the next calculateOverlappingPairs, which tests them with
  // the freed proxy's indices, and keeps or drops them as Bullet does only
  // if those indices are Bullet's too.
  std::uint32_t next_free() const { return low[0]; }
  void set_next_free(std::uint32_t number) { low[0] = number; }

  std::uint32_t& index(End end, int axis) { return end == End::low ? low[axis] : high[axis]; }
};

namespace {

[[noreturn]] void refuse(const std::string& what) {
  throw InvalidConfig("quantized sweep (Bullet's btAxisSweep3): " + what);
}

bool is_high(const QuantizedSweep::EndPoint& e) { return (e.position & 1) != 0; }

}  // namespace

QuantizedSweep::QuantizedSweep(const btVector3& world_min, const btVector3& world_max,
                               std::uint32_t max_proxies, int bits, btOverlappingPairCache* cache)
    : bits_(bits), world_min_(world_min), world_max_(world_max), cache_(cache) {
  if (bits == 16) {
    top_ = 0xffff;
    // Bullet asserts maxHandles < 32767: edge indices, up to 2 * (n + 1),
    // must fit its 16-bit integers.
    if (max_proxies < 1 || max_proxies > 32766)
      refuse("max proxies must be in [1, 32766] for a 16-bit grid, not " +
             std::to_string(max_proxies));
  } else if (bits == 32) {
    top_ = 0x7fffffff;
    if (max_proxies < 1 || max_proxies > 0x7ffffffe)
      refuse("max proxies must be in [1, 2147483646] for a 32-bit grid, not " +
             std::to_string(max_proxies));
  } else {
    refuse("bits must be 16 or 32, not " + std::to_string(bits));
  }
  even_mask_ = top_ - 1;  // top is odd in both: all ones below its top bit
  for (int a = 0; a < 3; ++a) {
    const btScalar lo = world_min[a], hi = world_max[a];
    if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi) || !std::isfinite(hi - lo))
      refuse("the world box must be finite with min < max on each axis (axis " + std::to_string(a) +
             ": [" + std::to_string(lo) + ", " + std::to_string(hi) + "])");
  }
  // The same expression as Bullet's constructor, so the same rounding.
  const btScalar top = static_cast<btScalar>(top_);
  scale_ = btVector3(top, top, top) / (world_max_ - world_min_);
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(scale_[a]))
      refuse("the world box is too thin for the grid on axis " + std::to_string(a));

  if (cache_ == nullptr) {
    owned_cache_ = std::make_unique<btHashedOverlappingPairCache>();
    cache_ = owned_cache_.get();
  }

  capacity_ = max_proxies + 1;                                  // number 0 is the sentinels'
  proxies_ = std::unique_ptr<Proxy[]>(new Proxy[capacity_]());  // zeroed
  resetPool(nullptr);
  // Number 0 owns the sentinels: a proxy without a client, never paired.
  proxies_[0].m_clientObject = nullptr;
  proxies_[0].m_uniqueId = 0;
  for (auto& axis : axes_) {
    axis.assign(2 * static_cast<std::size_t>(capacity_), EndPoint{0, 0});
    // The low sentinel at 0 stops every walk down (no position is below
    // 0), the high one at `top` with number 0 every walk up.
    axis[0] = EndPoint{0, 0};
    axis[1] = EndPoint{top_, 0};
  }
}

QuantizedSweep::~QuantizedSweep() = default;

QuantizedSweep::Proxy& QuantizedSweep::proxy(std::uint32_t number) const {
  return proxies_[number];
}

void QuantizedSweep::quantize(const btVector3& point, End end, std::uint32_t (&out)[3]) const {
  const std::uint32_t odd = end == End::high ? 1 : 0;
  const btVector3 cells = (point - world_min_) * scale_;
  for (int a = 0; a < 3; ++a) {
    const btScalar c = cells[a];
    std::uint32_t position;
    if (c >= static_cast<btScalar>(top_)) {
      position = top_ & even_mask_;
    } else if (c > 0) {
      position = static_cast<std::uint32_t>(c) & even_mask_;
    } else {
      // At or below the world's low side; also NaN, which Bullet converts
      // to an integer undefinedly and x86-64 turns into 0.
      position = 0;
    }
    out[a] = position | odd;
  }
}

void QuantizedSweep::grid_box(const btVector3& lo, const btVector3& hi, std::uint32_t (&low)[3],
                              std::uint32_t (&high)[3]) const {
  quantize(lo, End::low, low);
  quantize(hi, End::high, high);
  // An inverted box (min > max) is taken as flat at its min. Bullet's sweep
  // takes it as given: its low end then walks past its own high end, the
  // proxy pairs with itself, and the next setAabb walks an end point by an
  // index that the first walk made stale, so its edge indices go wrong
  // (the arrays are then read out of bounds). Boxes with min <= max, all a
  // collision world makes, never take this branch: quantize is monotone.
  for (int a = 0; a < 3; ++a)
    if (low[a] > high[a]) high[a] = low[a] | 1;
}

bool QuantizedSweep::overlap_off_axis(const Proxy& a, const Proxy& b, int axis) const {
  // End-point indices order as positions do, and are cheaper to reach.
  for (int other = 0; other < 3; ++other) {
    if (other == axis) continue;
    if (a.high[other] < b.low[other] || b.high[other] < a.low[other]) return false;
  }
  return true;
}

std::uint32_t QuantizedSweep::end_point_index(const btBroadphaseProxy* proxy_base, int axis,
                                              bool high) const {
  const Proxy& p = *static_cast<const Proxy*>(proxy_base);
  return high ? p.high[axis] : p.low[axis];
}

bool QuantizedSweep::grid_boxes_overlap(const btBroadphaseProxy* a,
                                        const btBroadphaseProxy* b) const {
  const Proxy& p = *static_cast<const Proxy*>(a);
  const Proxy& q = *static_cast<const Proxy*>(b);
  for (int axis = 0; axis < 3; ++axis)
    if (p.high[axis] < q.low[axis] || q.high[axis] < p.low[axis]) return false;
  return true;
}

void QuantizedSweep::begin_pair(Proxy& a, Proxy& b) {
  cache_->addOverlappingPair(&a, &b);
  if (pair_callback_ != nullptr) pair_callback_->addOverlappingPair(&a, &b);
}

void QuantizedSweep::end_pair(Proxy& a, Proxy& b, btDispatcher* dispatcher) {
  cache_->removeOverlappingPair(&a, &b, dispatcher);
  if (pair_callback_ != nullptr) pair_callback_->removeOverlappingPair(&a, &b, dispatcher);
}

// Walks the end point at `index` on `axis` (the `end` of its proxy) down
// while it is strictly below the one before it. Passing a high end with a
// low end can only start an overlap, passing a low end with a high end
// only end one; with `report`, the pair is added or removed when the boxes
// also overlap on the other two axes (a removal of a pair the cache does
// not hold is harmless, but Bullet tests first, and so do we: the test
// decides whether the cache is called at all).
void QuantizedSweep::walk_down(int axis, std::uint32_t index, End end, bool report,
                               btDispatcher* dispatcher) {
  std::vector<EndPoint>& points = axes_[axis];
  Proxy& moving = proxy(points[index].proxy);
  while (points[index].position < points[index - 1].position) {
    EndPoint& below = points[index - 1];
    Proxy& other = proxy(below.proxy);
    if (is_high(below)) {
      if (report && end == End::low && overlap_off_axis(moving, other, axis))
        begin_pair(moving, other);
      ++other.high[axis];
    } else {
      if (report && end == End::high && overlap_off_axis(moving, other, axis))
        end_pair(moving, other, dispatcher);
      ++other.low[axis];
    }
    --moving.index(end, axis);
    std::swap(points[index], below);
    --index;
  }
}

// The mirror of walk_down: up while at or above the next end point (an
// equal position is passed), stopping at the high sentinel (number 0).
void QuantizedSweep::walk_up(int axis, std::uint32_t index, End end, bool report,
                             btDispatcher* dispatcher) {
  std::vector<EndPoint>& points = axes_[axis];
  Proxy& moving = proxy(points[index].proxy);
  while (points[index + 1].proxy != 0 && points[index].position >= points[index + 1].position) {
    EndPoint& above = points[index + 1];
    Proxy& other = proxy(above.proxy);
    if (is_high(above)) {
      if (report && end == End::low && overlap_off_axis(moving, other, axis))
        end_pair(moving, other, dispatcher);
      --other.high[axis];
    } else {
      if (report && end == End::high && overlap_off_axis(moving, other, axis))
        begin_pair(moving, other);
      --other.low[axis];
    }
    ++moving.index(end, axis);
    std::swap(points[index], above);
    ++index;
  }
}

btBroadphaseProxy* QuantizedSweep::createProxy(const btVector3& aabbMin, const btVector3& aabbMax,
                                               int /*shapeType*/, void* userPtr,
                                               int collisionFilterGroup, int collisionFilterMask,
                                               btDispatcher* dispatcher) {
  if (first_free_ == 0)
    refuse("all " + std::to_string(max_proxies()) +
           " proxies are live; make the sweep with more (max proxies)");
  std::uint32_t lo[3], hi[3];
  grid_box(aabbMin, aabbMax, lo, hi);

  const std::uint32_t number = first_free_;
  Proxy& p = proxy(number);
  first_free_ = p.next_free();
  ++live_;
  p.m_uniqueId = static_cast<int>(number);
  p.m_clientObject = userPtr;
  p.m_collisionFilterGroup = collisionFilterGroup;
  p.m_collisionFilterMask = collisionFilterMask;
  // Bullet leaves the box of a new handle unset until setAabb; ours holds
  // the box it was made with (no pair depends on it).
  p.m_aabbMin = aabbMin;
  p.m_aabbMax = aabbMax;

  // The two new end points go just below the high sentinel, which moves up
  // two places, and walk down to their places.
  const std::uint32_t last = 2 * live_;  // the new high end's index
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<EndPoint>& points = axes_[axis];
    points[last + 1] = points[last - 1];
    points[last - 1] = EndPoint{lo[axis], number};
    points[last] = EndPoint{hi[axis], number};
    p.low[axis] = last - 1;
    p.high[axis] = last;
  }
  // Pairs are found on z alone, once x and y are in place: the new box
  // starts above every other on z, its low end walking down passes the
  // high end of each box reaching above its bottom (a pair, when x and y
  // overlap), its high end walking down the low end of each box wholly
  // above it (that pair ends again).
  for (int axis = 0; axis < 3; ++axis) {
    const bool report = axis == 2;
    walk_down(axis, p.low[axis], End::low, report, dispatcher);
    walk_down(axis, p.high[axis], End::high, report, dispatcher);
  }
  return &p;
}

void QuantizedSweep::destroyProxy(btBroadphaseProxy* proxy_base, btDispatcher* dispatcher) {
  Proxy& p = *static_cast<Proxy*>(proxy_base);
  if (!cache_->hasDeferredRemoval()) cache_->removeOverlappingPairsContainingProxy(&p, dispatcher);

  // Both end points get the top position and walk up to the high
  // sentinel, silently (the pairs are gone, or left to the deferred
  // cleanup); the high end first, so the low end, walking up after it,
  // passes it too. The end point just below them becomes the new high
  // sentinel.
  const std::uint32_t last = 2 * live_;  // the index of the last proxy end point
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<EndPoint>& points = axes_[axis];
    points[p.high[axis]].position = top_;
    walk_up(axis, p.high[axis], End::high, false, dispatcher);
    points[p.low[axis]].position = top_;
    walk_up(axis, p.low[axis], End::low, false, dispatcher);
    points[last - 1] = EndPoint{top_, 0};
  }

  p.set_next_free(first_free_);
  first_free_ = static_cast<std::uint32_t>(p.m_uniqueId);
  --live_;
}

void QuantizedSweep::setAabb(btBroadphaseProxy* proxy_base, const btVector3& aabbMin,
                             const btVector3& aabbMax, btDispatcher* dispatcher) {
  Proxy& p = *static_cast<Proxy*>(proxy_base);
  p.m_aabbMin = aabbMin;
  p.m_aabbMax = aabbMax;
  std::uint32_t lo[3], hi[3];
  grid_box(aabbMin, aabbMax, lo, hi);
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<EndPoint>& points = axes_[axis];
    // The indices before any walk, as Bullet takes them: with low <= high
    // (grid_box) neither end point's walk moves the other.
    const std::uint32_t low = p.low[axis], high = p.high[axis];
    const auto low_shift =
        static_cast<std::int64_t>(lo[axis]) - static_cast<std::int64_t>(points[low].position);
    const auto high_shift =
        static_cast<std::int64_t>(hi[axis]) - static_cast<std::int64_t>(points[high].position);
    points[low].position = lo[axis];
    points[high].position = hi[axis];
    // Growing first (pairs can only begin), then shrinking (pairs can
    // only end): Bullet's order, which decides the order of the events.
    if (low_shift < 0) walk_down(axis, low, End::low, true, dispatcher);
    if (high_shift > 0) walk_up(axis, high, End::high, true, dispatcher);
    if (low_shift > 0) walk_up(axis, low, End::low, true, dispatcher);
    if (high_shift < 0) walk_down(axis, high, End::high, true, dispatcher);
  }
}

void QuantizedSweep::getAabb(btBroadphaseProxy* proxy_base, btVector3& aabbMin,
                             btVector3& aabbMax) const {
  aabbMin = proxy_base->m_aabbMin;
  aabbMax = proxy_base->m_aabbMax;
}

void QuantizedSweep::rayTest(const btVector3& /*rayFrom*/, const btVector3& /*rayTo*/,
                             btBroadphaseRayCallback& callback, const btVector3& /*aabbMin*/,
                             const btVector3& /*aabbMax*/) {
  const std::vector<EndPoint>& points = axes_[0];
  for (std::uint32_t i = 1; i <= 2 * live_; ++i)
    if (is_high(points[i])) callback.process(&proxy(points[i].proxy));
}

void QuantizedSweep::aabbTest(const btVector3& aabbMin, const btVector3& aabbMax,
                              btBroadphaseAabbCallback& callback) {
  const std::vector<EndPoint>& points = axes_[0];
  for (std::uint32_t i = 1; i <= 2 * live_; ++i) {
    if (!is_high(points[i])) continue;
    Proxy& p = proxy(points[i].proxy);
    if (TestAabbAgainstAabb2(aabbMin, aabbMax, p.m_aabbMin, p.m_aabbMax)) callback.process(&p);
  }
}

void QuantizedSweep::calculateOverlappingPairs(btDispatcher* dispatcher) {
  if (!cache_->hasDeferredRemoval()) return;
  // A deferred cache holds every pair added since the last pass, removed
  // or not, some twice. Sorting by proxy numbers puts a pair's copies side
  // by side (and the emptied pairs, numbered -1, last); each pair is kept
  // once if the grid boxes still overlap. The two sorts are Bullet's, and
  // so is the order they leave.
  btBroadphasePairArray& pairs = cache_->getOverlappingPairArray();
  pairs.quickSort(btBroadphasePairSortPredicate());
  int emptied = 0;
  btBroadphasePair previous;
  for (int i = 0; i < pairs.size(); ++i) {
    btBroadphasePair& pair = pairs[i];
    const bool duplicate = pair == previous;
    previous = pair;
    if (duplicate || !grid_boxes_overlap(pair.m_pProxy0, pair.m_pProxy1)) {
      cache_->cleanOverlappingPair(pair, dispatcher);
      pair.m_pProxy0 = nullptr;
      pair.m_pProxy1 = nullptr;
      ++emptied;
    }
  }
  pairs.quickSort(btBroadphasePairSortPredicate());
  pairs.resize(pairs.size() - emptied);
}

void QuantizedSweep::getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const {
  aabbMin = world_min_;
  aabbMax = world_max_;
}

void QuantizedSweep::resetPool(btDispatcher* /*dispatcher*/) {
  if (live_ != 0) return;
  // The free list in number order, 1 first, ending at 0 (none free).
  first_free_ = 1;
  for (std::uint32_t n = 1; n < capacity_; ++n) proxy(n).set_next_free(n + 1);
  proxy(capacity_ - 1).set_next_free(0);
}

}  // namespace broadphase::bullet_detail
