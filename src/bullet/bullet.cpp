// BulletBroadphase: Bullet's broad-phase interface over a registry
// structure. Compiled once against float Bullet (broadphase::bullet) and
// once with BT_USE_DOUBLE_PRECISION (broadphase::bullet_double).
//
// Exactness. The structure holds each proxy's btScalar box as a Shape::box
// whose extent is rounded up by one double ulp, a box that contains the
// btScalar box in real numbers: whenever two btScalar boxes overlap, their
// Shapes do in reals, and the structure's double predicate (monotone
// rounding) reports them. Every candidate then passes Bullet's own closed
// test on the btScalar boxes (`overlap` below), so the pairs are exactly
// the pairs of overlapping btScalar boxes: the same as a brute force over
// the proxies, whatever the magnitudes (a rounded centre only grows the
// stored box). Infinite coordinates are clamped to +-1e300 (monotone, so
// still a superset); NaN boxes are stored as a point and never pass.
#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/registry.hpp>
#include <cmath>
#include <cstdio>
#include <limits>

namespace broadphase {

struct BulletBroadphase::Proxy : btBroadphaseProxy {
  Handle handle;
  std::size_t live_index = 0;        // in live_
  std::size_t move_index = kNoMove;  // in moves_, kNoMove when none is pending
  Filter given{};                    // the filter the structure holds for it
  static constexpr std::size_t kNoMove = ~std::size_t{0};
};

namespace {

constexpr double kClamp = 1e300;

/// A box around the btScalar box [lo, hi] in reals (see the file comment).
Shape shape_of(const btVector3& lo, const btVector3& hi) {
  Vec3 c, h;
  for (int a = 0; a < 3; ++a) {
    double l = lo[a];
    double u = hi[a];
    if (std::isnan(l) || std::isnan(u)) {
      c[a] = 0;
      h[a] = 0;
      continue;
    }
    // An inverted box [l, u], l > u, overlaps by Bullet's test only boxes
    // that hold [u, l]: its hull is a superset.
    if (l > u) std::swap(l, u);
    l = std::clamp(l, -kClamp, kClamp);
    u = std::clamp(u, -kClamp, kClamp);
    c[a] = 0.5 * l + 0.5 * u;  // no overflow near the clamp
    const double half = std::max(u - c[a], c[a] - l);
    h[a] = std::nextafter(half, std::numeric_limits<double>::infinity());
  }
  return Shape::box(c, h);
}

/// Bullet's closed box test in btScalar (btDbvt's Intersect): touching
/// counts, NaN never overlaps.
bool overlap(const btVector3& lo0, const btVector3& hi0, const btVector3& lo1,
             const btVector3& hi1) {
  return lo0.x() <= hi1.x() && lo1.x() <= hi0.x() && lo0.y() <= hi1.y() && lo1.y() <= hi0.y() &&
         lo0.z() <= hi1.z() && lo1.z() <= hi0.z();
}

Filter filter_of(const btBroadphaseProxy& p) {
  return {static_cast<std::uint32_t>(p.m_collisionFilterGroup),
          static_cast<std::uint32_t>(p.m_collisionFilterMask)};
}

// What the structure holds when the cache filters alone: every default
// filter pairs with every other.
constexpr Filter kPassAll{};

Vec3 to_vec(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

BulletBroadphase::BulletBroadphase(btOverlappingPairCache* cache, const BulletOptions& options)
    : options_(options), owns_cache_(cache == nullptr) {
  make_structure();
  if (owns_cache_) {
    void* mem = btAlignedAlloc(sizeof(btHashedOverlappingPairCache), 16);
    cache_ = new (mem) btHashedOverlappingPairCache();
  } else {
    cache_ = cache;
  }
  filters_in_structure_ = cache_->getOverlapFilterCallback() == nullptr;
}

BulletBroadphase::~BulletBroadphase() {
  for (Proxy* p : live_) delete p;
  if (owns_cache_) {
    cache_->~btOverlappingPairCache();
    btAlignedFree(cache_);
  }
}

void BulletBroadphase::make_structure() {
  structure_ = broadphase::make_structure(options_.structure, options_.config);
}

btBroadphaseProxy* BulletBroadphase::createProxy(const btVector3& aabbMin, const btVector3& aabbMax,
                                                 int /*shapeType*/, void* userPtr,
                                                 int collisionFilterGroup, int collisionFilterMask,
                                                 btDispatcher* /*dispatcher*/) {
  auto* p = new Proxy();
  p->m_clientObject = userPtr;
  p->m_collisionFilterGroup = collisionFilterGroup;
  p->m_collisionFilterMask = collisionFilterMask;
  p->m_aabbMin = aabbMin;
  p->m_aabbMax = aabbMax;
  if (free_uids_.empty()) {
    p->m_uniqueId = next_uid_++;
  } else {
    p->m_uniqueId = free_uids_.back();
    free_uids_.pop_back();
  }
  // Bullet's static objects carry StaticFilter (btCollisionWorld's
  // default): a hint only, a fixed object that moves stays exact.
  const Motion motion = (collisionFilterGroup & btBroadphaseProxy::StaticFilter) != 0
                            ? Motion::fixed
                            : Motion::dynamic;
  p->given = filters_in_structure_ ? filter_of(*p) : kPassAll;
  p->handle = structure_->insert(shape_of(aabbMin, aabbMax), 0, motion, p->given);
  if (by_slot_.size() <= p->handle.index) by_slot_.resize(p->handle.index + 1, nullptr);
  by_slot_[p->handle.index] = p;
  p->live_index = live_.size();
  live_.push_back(p);
  settle_due_ = true;
  return p;
}

void BulletBroadphase::remove_move(Proxy& p) {
  if (p.move_index == Proxy::kNoMove) return;
  const std::size_t i = p.move_index;
  moves_[i] = moves_.back();
  moves_.pop_back();
  if (i < moves_.size()) by_slot_[moves_[i].handle.index]->move_index = i;
  p.move_index = Proxy::kNoMove;
}

void BulletBroadphase::destroyProxy(btBroadphaseProxy* proxy, btDispatcher* dispatcher) {
  auto* p = static_cast<Proxy*>(proxy);
  cache_->removeOverlappingPairsContainingProxy(p, dispatcher);
  remove_move(*p);
  structure_->remove(p->handle);
  by_slot_[p->handle.index] = nullptr;
  live_[p->live_index] = live_.back();
  live_[p->live_index]->live_index = p->live_index;
  live_.pop_back();
  free_uids_.push_back(p->m_uniqueId);
  delete p;
}

void BulletBroadphase::setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin,
                               const btVector3& aabbMax, btDispatcher* /*dispatcher*/) {
  auto* p = static_cast<Proxy*>(proxy);
  if (p->m_aabbMin == aabbMin && p->m_aabbMax == aabbMax) return;
  p->m_aabbMin = aabbMin;
  p->m_aabbMax = aabbMax;
  const Shape s = shape_of(aabbMin, aabbMax);
  if (p->move_index == Proxy::kNoMove) {
    p->move_index = moves_.size();
    moves_.push_back({p->handle, s});
  } else {
    moves_[p->move_index].shape = s;
  }
}

void BulletBroadphase::getAabb(btBroadphaseProxy* proxy, btVector3& aabbMin,
                               btVector3& aabbMax) const {
  aabbMin = proxy->m_aabbMin;
  aabbMax = proxy->m_aabbMax;
}

BulletBroadphase::Proxy* BulletBroadphase::live_proxy(Handle h) const {
  if (h.index >= by_slot_.size()) return nullptr;
  Proxy* p = by_slot_[h.index];
  return p != nullptr && p->handle == h ? p : nullptr;
}

// Group and mask live in the proxy, where users also change them directly
// (getBroadphaseHandle()->m_collisionFilterMask = ...): every pass compares
// them with what the structure holds, O(proxies), a few percent of a pass.
// With a user's filter callback the cache decides alone and the structure
// passes everything.
void BulletBroadphase::sync_filters() {
  const bool in_structure = cache_->getOverlapFilterCallback() == nullptr;
  for (Proxy* p : live_) {
    const Filter f = in_structure ? filter_of(*p) : kPassAll;
    if (!(f == p->given)) {
      structure_->set_filter(p->handle, f);
      p->given = f;
    }
  }
  filters_in_structure_ = in_structure;
}

void BulletBroadphase::calculateOverlappingPairs(btDispatcher* dispatcher) {
  sync_filters();
  if (!moves_.empty()) {
    structure_->update(moves_);
    for (const Move& m : moves_) by_slot_[m.handle.index]->move_index = Proxy::kNoMove;
    moves_.clear();
  } else if (settle_due_) {
    structure_->settle();
  }
  settle_due_ = false;
  pairs_.clear();
  structure_->find_pairs(pairs_);
  tracker_.begin_frame();
  for (const HandlePair& hp : pairs_) {
    const Proxy& a = *by_slot_[hp.a.index];
    const Proxy& b = *by_slot_[hp.b.index];
    if (overlap(a.m_aabbMin, a.m_aabbMax, b.m_aabbMin, b.m_aabbMax)) tracker_.add(hp.a, hp.b);
  }
  tracker_.end_frame();
  for (const HandlePair& hp : tracker_.begun())
    cache_->addOverlappingPair(by_slot_[hp.a.index], by_slot_[hp.b.index]);
  if (cache_->hasDeferredRemoval()) {
    remove_deferred(dispatcher);
    return;
  }
  // Ended pairs of a destroyed proxy left the cache with it.
  for (const HandlePair& hp : tracker_.ended()) {
    Proxy* a = live_proxy(hp.a);
    Proxy* b = live_proxy(hp.b);
    if (a != nullptr && b != nullptr) cache_->removeOverlappingPair(a, b, dispatcher);
  }
}

// A cache with deferred removal (btSortedOverlappingPairCache) ignores
// removeOverlappingPair and leaves the clean-up to the broad phase, as
// btAxisSweep3 does it: clean each pair that no longer overlaps, null its
// proxies, sort them to the end and cut them off. O(cached pairs) a pass
// when nothing ended.
void BulletBroadphase::remove_deferred(btDispatcher* dispatcher) {
  if (tracker_.ended().empty()) return;
  btBroadphasePairArray& pairs = cache_->getOverlappingPairArray();
  int invalid = 0;
  for (int i = 0; i < pairs.size(); ++i) {
    btBroadphasePair& pair = pairs[i];
    const auto* a = static_cast<const Proxy*>(pair.m_pProxy0);
    const auto* b = static_cast<const Proxy*>(pair.m_pProxy1);
    if (a != nullptr && b != nullptr && tracker_.contains(a->handle, b->handle)) continue;
    cache_->cleanOverlappingPair(pair, dispatcher);
    pair.m_pProxy0 = nullptr;
    pair.m_pProxy1 = nullptr;
    ++invalid;
  }
  if (invalid == 0) return;
  pairs.quickSort(btBroadphasePairSortPredicate());
  pairs.resize(pairs.size() - invalid);
}

void BulletBroadphase::rayTest(const btVector3& rayFrom, const btVector3& rayTo,
                               btBroadphaseRayCallback& callback, const btVector3& aabbMin,
                               const btVector3& aabbMax) {
  const Vec3 from = to_vec(rayFrom);
  const Ray ray{from, to_vec(rayTo) - from, 1.0, 0xffffffffu};
  if (!is_valid(ray)) {
    for (Proxy* p : live_) callback.process(p);
    return;
  }
  const btVector3 zero(0, 0, 0);
  if (aabbMin == zero && aabbMax == zero) {
    structure_->cast_ray(ray, [&](Handle h, double) {
      callback.process(by_slot_[h.index]);
      return kRayGoOn;
    });
    return;
  }
  // A swept box: the proxies near the hull of the swept box (in double,
  // one ulp outward), then the segment against each box grown by the sweep.
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const Vec3 to = to_vec(rayTo);
  Vec3 c, half;
  for (int a = 0; a < 3; ++a) {
    const double l = std::nextafter(std::min(from[a], to[a]) + double(aabbMin[a]), -kInf);
    const double u = std::nextafter(std::max(from[a], to[a]) + double(aabbMax[a]), kInf);
    c[a] = 0.5 * l + 0.5 * u;
    half[a] = std::nextafter(std::max(u - c[a], c[a] - l), kInf);
  }
  const Shape hull = Shape::box(c, half);
  if (!is_valid(hull)) {  // a NaN or inverted sweep box: every proxy, as a superset
    for (Proxy* p : live_) callback.process(p);
    return;
  }
  structure_->query(hull, [&](Handle h) {
    Proxy* p = by_slot_[h.index];
    Vec3 gc, gh;  // the proxy's box grown by the sweep
    for (int a = 0; a < 3; ++a) {
      const double l = std::nextafter(double(p->m_aabbMin[a]) - double(aabbMax[a]), -kInf);
      const double u = std::nextafter(double(p->m_aabbMax[a]) - double(aabbMin[a]), kInf);
      gc[a] = 0.5 * l + 0.5 * u;
      gh[a] = std::nextafter(std::max(u - gc[a], gc[a] - l), kInf);
    }
    const Shape grown = Shape::box(gc, gh);
    double t;
    if (!is_valid(grown) || ray_hit(ray, grown, t)) callback.process(p);  // invalid: a superset
    return true;
  });
}

void BulletBroadphase::aabbTest(const btVector3& aabbMin, const btVector3& aabbMax,
                                btBroadphaseAabbCallback& callback) {
  structure_->query(shape_of(aabbMin, aabbMax), [&](Handle h) {
    Proxy* p = by_slot_[h.index];
    if (overlap(p->m_aabbMin, p->m_aabbMax, aabbMin, aabbMax)) callback.process(p);
    return true;
  });
}

void BulletBroadphase::getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const {
  if (live_.empty()) {
    aabbMin = aabbMax = btVector3(0, 0, 0);
    return;
  }
  aabbMin = live_.front()->m_aabbMin;
  aabbMax = live_.front()->m_aabbMax;
  for (const Proxy* p : live_) {
    aabbMin.setMin(p->m_aabbMin);
    aabbMax.setMax(p->m_aabbMax);
  }
}

void BulletBroadphase::resetPool(btDispatcher* /*dispatcher*/) {
  if (!live_.empty()) return;
  make_structure();
  filters_in_structure_ = cache_->getOverlapFilterCallback() == nullptr;
  by_slot_.clear();
  moves_.clear();
  free_uids_.clear();
  next_uid_ = 1;
  settle_due_ = false;
  tracker_ = PairCache();
}

void BulletBroadphase::printStats() {
  std::printf("BulletBroadphase over %s: %zu proxies, %zu pairs in the last pass, %zu bytes\n",
              options_.structure.c_str(), live_.size(), tracker_.size(),
              structure_->memory_bytes());
}

}  // namespace broadphase
