// BulletBroadphase: Bullet's broad-phase interface over a registry
// structure. Compiled once against float Bullet (broadphase::bullet) and
// once with BT_USE_DOUBLE_PRECISION (broadphase::bullet_double).
//
// Exactness. The structure holds each proxy's btScalar box, grown by the
// margin, as a Shape::box whose extent is rounded up by one double ulp: a
// box that contains the btScalar box in real numbers. So whenever two
// btScalar boxes overlap, the structure's double predicate (monotone
// rounding) reports the one's Shape to a query with the other's. Every
// candidate then passes Bullet's own closed test on the btScalar boxes
// (`overlap` below), so the pairs are exactly the pairs of overlapping
// btScalar boxes: the same as a brute force over the proxies, whatever the
// magnitudes. Infinite coordinates are clamped to +-1e300 (monotone, so
// still a superset); NaN boxes never pass.
//
// Pairs. Each proxy keeps its partners (the proxies its box overlaps and
// whose filters pass). A pass looks only at the proxies whose box or
// filter changed since the last one: their partners that no longer
// overlap leave the cache, and of the structure's pairs (of fat boxes)
// those with a changed proxy in them are tested. No pair is hashed: every
// pair of every pass through a hash of pairs (PairCache) took 2.6-4.9 ms a
// pass on 3 000 boxes falling onto a plane, 2 to 4 times btDbvtBroadphase;
// a query of the structure per changed proxy, 5-20 ms.
#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/config_error.hpp>
#include <broadphase/registry.hpp>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace broadphase {

struct BulletBroadphase::Proxy : btBroadphaseProxy {
  Handle handle;                        // in the structure; null for a huge proxy
  double fat_lo[3], fat_hi[3];          // the box the structure holds (within its Shape)
  std::vector<Proxy*> partners;         // the pairs it is in
  std::size_t live_index = 0;           // in live_
  std::size_t move_index = kNoMove;     // in moves_, kNoMove when none is pending
  std::size_t changed_index = kNoMove;  // in changed_, kNoMove when unchanged
  std::size_t huge_index = kNoMove;     // in huge_, kNoMove when in the structure
  Filter given{};                       // group and mask as of the last pass
  static constexpr std::size_t kNoMove = ~std::size_t{0};
  bool huge() const { return huge_index != kNoMove; }
};

namespace {

constexpr double kClamp = 1e300;

/// A box around the box [lo, hi] in reals (see the file comment).
Shape shape_of(const double (&lo)[3], const double (&hi)[3]) {
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

Shape shape_of(const btVector3& lo, const btVector3& hi) {
  const double l[3] = {lo.x(), lo.y(), lo.z()};
  const double u[3] = {hi.x(), hi.y(), hi.z()};
  return shape_of(l, u);
}

/// Boxes this wide on some axis stay out of the structure (huge_). Bullet
/// itself disables any non-static object whose box diagonal passes 1e6
/// (btCollisionWorld::updateSingleAabb), so these are static: planes
/// (+-1e18 on every axis), terrains. In a structure, one such box is near
/// every object: with btStaticPlaneShape under 3 000 falling boxes it made
/// grid-verlet's pair pass 3.6 times as long (0.86 -> 3.1 ms a step);
/// tested against every proxy by the adapter it costs 3 000 box tests.
constexpr double kHugeSide = 1e6;

bool is_huge(const btVector3& lo, const btVector3& hi) {
  for (int a = 0; a < 3; ++a)
    if (!(double(hi[a]) - double(lo[a]) < kHugeSide) && !(lo[a] > hi[a])) return true;
  return false;
}

/// True when [lo, hi] is a box (not inverted, no NaN) inside [fat_lo, fat_hi].
bool inside(const btVector3& lo, const btVector3& hi, const double (&fat_lo)[3],
            const double (&fat_hi)[3]) {
  for (int a = 0; a < 3; ++a)
    if (!(fat_lo[a] <= lo[a] && lo[a] <= hi[a] && hi[a] <= fat_hi[a])) return false;
  return true;
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

Vec3 to_vec(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

/// Removes one `p` from `list` (which holds it), order not kept.
template <class P>
void erase_one(std::vector<P*>& list, const P* p) {
  const auto it = std::find(list.begin(), list.end(), p);
  *it = list.back();
  list.pop_back();
}

}  // namespace

BulletBroadphase::BulletBroadphase(btOverlappingPairCache* cache, const BulletOptions& options)
    : options_(options), owns_cache_(cache == nullptr) {
  if (!(options_.margin >= 0 && std::isfinite(options_.margin)))
    throw InvalidConfig("broadphase::BulletBroadphase: margin must be finite and >= 0, not " +
                        std::to_string(options_.margin));
  make_structure();
  if (owns_cache_) {
    void* mem = btAlignedAlloc(sizeof(btHashedOverlappingPairCache), 16);
    cache_ = new (mem) btHashedOverlappingPairCache();
  } else {
    cache_ = cache;
  }
  filters_apply_ = cache_->getOverlapFilterCallback() == nullptr;
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
  p->given = filter_of(*p);
  if (free_uids_.empty()) {
    p->m_uniqueId = next_uid_++;
  } else {
    p->m_uniqueId = free_uids_.back();
    free_uids_.pop_back();
  }
  p->live_index = live_.size();
  live_.push_back(p);
  if (is_huge(aabbMin, aabbMax)) {
    add_huge(*p);
  } else {
    // Bullet's static objects carry StaticFilter (btCollisionWorld's
    // default): a hint only, a fixed object that moves stays exact.
    enter_structure(*p, (collisionFilterGroup & btBroadphaseProxy::StaticFilter) != 0
                            ? Motion::fixed
                            : Motion::dynamic);
  }
  mark_changed(*p);
  return p;
}

void BulletBroadphase::enter_structure(Proxy& p, Motion motion) {
  p.handle = structure_->insert(fatten(p), 0, motion);
  if (by_slot_.size() <= p.handle.index) by_slot_.resize(p.handle.index + 1, nullptr);
  by_slot_[p.handle.index] = &p;
  settle_due_ = true;
}

void BulletBroadphase::leave_structure(Proxy& p) {
  remove_move(p);
  structure_->remove(p.handle);
  by_slot_[p.handle.index] = nullptr;
  p.handle = Handle{};
}

void BulletBroadphase::add_huge(Proxy& p) {
  p.huge_index = huge_.size();
  huge_.push_back(&p);
}

void BulletBroadphase::drop_huge(Proxy& p) {
  huge_[p.huge_index] = huge_.back();
  huge_[p.huge_index]->huge_index = p.huge_index;
  huge_.pop_back();
  p.huge_index = Proxy::kNoMove;
}

void BulletBroadphase::mark_changed(Proxy& p) {
  if (p.changed_index != Proxy::kNoMove) return;
  p.changed_index = changed_.size();
  changed_.push_back(&p);
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
  // A cache with deferred removal ignores removeOverlappingPair; the
  // others lose the proxy's pairs one by one, O(its pairs) where
  // removeOverlappingPairsContainingProxy reads every pair of the cache.
  if (cache_->hasDeferredRemoval()) {
    cache_->removeOverlappingPairsContainingProxy(p, dispatcher);
  } else {
    for (Proxy* q : p->partners) cache_->removeOverlappingPair(p, q, dispatcher);
  }
  for (Proxy* q : p->partners) erase_one(q->partners, p);
  pair_count_ -= p->partners.size();
  if (p->huge()) {
    drop_huge(*p);
  } else {
    leave_structure(*p);
  }
  if (p->changed_index != Proxy::kNoMove) {
    changed_[p->changed_index] = changed_.back();
    changed_[p->changed_index]->changed_index = p->changed_index;
    changed_.pop_back();
  }
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
  mark_changed(*p);
  const bool huge = is_huge(aabbMin, aabbMax);
  if (huge != p->huge()) {
    if (huge) {
      leave_structure(*p);
      add_huge(*p);
    } else {
      drop_huge(*p);
      enter_structure(*p, Motion::dynamic);
    }
    return;
  }
  if (huge) return;
  if (inside(aabbMin, aabbMax, p->fat_lo, p->fat_hi)) return;  // the structure's box holds it
  const Shape s = fatten(*p);
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

// The structure holds each proxy's box grown by the margin, and is told of
// a new box only when it leaves that one (btDbvtBroadphase's fat leaves):
// a body resting in a pile moves by far less than the margin each step.
Shape BulletBroadphase::fatten(Proxy& p) const {
  for (int a = 0; a < 3; ++a) {
    p.fat_lo[a] = double(p.m_aabbMin[a]) - options_.margin;
    p.fat_hi[a] = double(p.m_aabbMax[a]) + options_.margin;
  }
  return shape_of(p.fat_lo, p.fat_hi);
}

bool BulletBroadphase::pairs(const Proxy& a, const Proxy& b) const {
  return overlap(a.m_aabbMin, a.m_aabbMax, b.m_aabbMin, b.m_aabbMax) &&
         (!filters_apply_ || filters_pass(filter_of(a), filter_of(b)));
}

// Group and mask live in the proxy, where users also change them directly
// (getBroadphaseHandle()->m_collisionFilterMask = ...): every pass compares
// them with the last pass's, O(proxies), and a proxy whose filter changed
// is looked at again. With a user's filter callback the cache decides
// alone, when a pair begins (as btAxisSweep3 asks it).
void BulletBroadphase::sync_filters() {
  const bool apply = cache_->getOverlapFilterCallback() == nullptr;
  const bool all = apply != filters_apply_;
  filters_apply_ = apply;
  for (Proxy* p : live_) {
    const Filter f = filter_of(*p);
    if (all || !(f == p->given)) {
      p->given = f;
      mark_changed(*p);
    }
  }
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
  const bool deferred = cache_->hasDeferredRemoval();
  bool removed = false;
  // Pairs that end: a changed proxy's partners that no longer pair.
  for (Proxy* p : changed_) {
    std::vector<Proxy*>& list = p->partners;
    for (std::size_t i = 0; i < list.size();) {
      Proxy* q = list[i];
      if (pairs(*p, *q)) {
        ++i;
        continue;
      }
      list[i] = list.back();
      list.pop_back();
      erase_one(q->partners, p);
      --pair_count_;
      removed = true;
      if (!deferred) cache_->removeOverlappingPair(p, q, dispatcher);
    }
  }
  // Pairs that begin: the structure's pairs of fat boxes (incremental in
  // sap: its pass only reads its cache) with a changed proxy in them, and
  // the changed proxies against the huge ones.
  auto meet = [&](Proxy* p, Proxy* q) {
    if (!pairs(*p, *q)) return;
    const Proxy* shorter = p->partners.size() <= q->partners.size() ? p : q;
    const Proxy* other = shorter == p ? q : p;
    for (const Proxy* r : shorter->partners)
      if (r == other) return;  // persisting
    p->partners.push_back(q);
    q->partners.push_back(p);
    ++pair_count_;
    cache_->addOverlappingPair(p, q);
  };
  if (!changed_.empty()) {
    candidates_.clear();
    structure_->find_pairs(candidates_);
    for (const HandlePair& hp : candidates_) {
      Proxy* a = by_slot_[hp.a.index];
      Proxy* b = by_slot_[hp.b.index];
      if (a->changed_index != Proxy::kNoMove || b->changed_index != Proxy::kNoMove) meet(a, b);
    }
  }
  for (Proxy* p : changed_) {
    if (p->huge()) {
      for (Proxy* q : live_)
        if (q != p && (!q->huge() || q->changed_index > p->changed_index)) meet(p, q);
    } else {
      for (Proxy* q : huge_)
        if (q->changed_index == Proxy::kNoMove) meet(p, q);  // a changed huge q meets p itself
    }
  }
  for (Proxy* p : changed_) p->changed_index = Proxy::kNoMove;
  changed_.clear();
  if (deferred && removed) remove_deferred(dispatcher);
}

// A cache with deferred removal (btSortedOverlappingPairCache) ignores
// removeOverlappingPair and leaves the clean-up to the broad phase, as
// btAxisSweep3 does it: clean each pair that no longer overlaps, null its
// proxies, sort them to the end and cut them off. O(cached pairs), only in
// a pass where some pair ended.
void BulletBroadphase::remove_deferred(btDispatcher* dispatcher) {
  btBroadphasePairArray& array = cache_->getOverlappingPairArray();
  int invalid = 0;
  for (int i = 0; i < array.size(); ++i) {
    btBroadphasePair& pair = array[i];
    const auto* a = static_cast<const Proxy*>(pair.m_pProxy0);
    const auto* b = static_cast<const Proxy*>(pair.m_pProxy1);
    if (a != nullptr && b != nullptr &&
        std::find(a->partners.begin(), a->partners.end(), b) != a->partners.end())
      continue;
    cache_->cleanOverlappingPair(pair, dispatcher);
    pair.m_pProxy0 = nullptr;
    pair.m_pProxy1 = nullptr;
    ++invalid;
  }
  if (invalid == 0) return;
  array.quickSort(btBroadphasePairSortPredicate());
  array.resize(array.size() - invalid);
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
    // The structure hits the fat boxes; each is tested on the proxy's own.
    structure_->cast_ray(ray, [&](Handle h, double) {
      Proxy* p = by_slot_[h.index];
      double t;
      if (ray_hit(ray, shape_of(p->m_aabbMin, p->m_aabbMax), t)) callback.process(p);
      return kRayGoOn;
    });
    for (Proxy* p : huge_) {
      double t;
      if (ray_hit(ray, shape_of(p->m_aabbMin, p->m_aabbMax), t)) callback.process(p);
    }
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
  for (Proxy* p : huge_) callback.process(p);  // a superset: few, and hit by most sweeps
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
  for (Proxy* p : huge_)
    if (overlap(p->m_aabbMin, p->m_aabbMax, aabbMin, aabbMax)) callback.process(p);
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
  by_slot_.clear();
  huge_.clear();
  moves_.clear();
  changed_.clear();
  free_uids_.clear();
  next_uid_ = 1;
  settle_due_ = false;
  pair_count_ = 0;
}

void BulletBroadphase::printStats() {
  std::printf("BulletBroadphase over %s: %zu proxies, %zu pairs in the last pass, %zu bytes\n",
              options_.structure.c_str(), live_.size(), pair_count_, structure_->memory_bytes());
}

}  // namespace broadphase
