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
// Pairs. The adapter keeps the structure's pairs of fat boxes as its own
// list of candidates, each with a bit: begun (in Bullet's cache) or not.
// Every pass tests every candidate on the proxies' btScalar boxes, read
// from one array by proxy id, and begins or ends the pairs whose bit
// changes: a resting pile stays awake in Bullet and gives every proxy a
// new box each step, but few leave their fat box, so the candidates stay.
// Only the proxies that are new or left their fat box ("fresh") change the
// list: their candidates leave it and come back from one structure query
// each, or, when many are fresh, from the structure's whole pair list.
// Measured on 3 000 boxes falling onto a plane (docs/bullet.md): each
// proxy keeping its partners and every pass looking at every changed
// proxy's pairs took twice btDbvtBroadphase's time; hashing every pair of
// every pass (PairCache), 2 to 4 times.
#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/config_error.hpp>
#include <broadphase/registry.hpp>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

#include "quantized_sweep.hpp"

namespace broadphase {

struct BulletBroadphase::Proxy : btBroadphaseProxy {
  Handle handle;                // in the structure; null for a huge proxy
  double fat_lo[3], fat_hi[3];  // the box the structure holds (within its Shape)
  // The pairs it is in: the other proxy, and where that one's link back
  // is in its own list, so that a pair leaves both lists in O(1) (a plane
  // under 100 000 boxes is in 100 000 pairs; a search of its list per
  // removed box made removing them all quadratic).
  struct Link {
    Proxy* other;
    std::uint32_t back;  // other->partners[back].other == this
  };
  std::vector<Link> partners;
  /// The index of the link to `q` in partners, or npos (a scan of it).
  std::size_t find(const Proxy* q) const {
    for (std::size_t i = 0; i < partners.size(); ++i)
      if (partners[i].other == q) return i;
    return kNoMove;
  }
  /// Removes partners[i] alone (the link back must go too, see unlink).
  void drop_link(std::size_t i) {
    const Link last = partners.back();
    partners.pop_back();
    if (i == partners.size()) return;
    partners[i] = last;
    last.other->partners[last.back].back = static_cast<std::uint32_t>(i);
  }
  /// Removes the pair of partners[i], from both lists.
  void unlink(std::size_t i) {
    const Link l = partners[i];
    l.other->drop_link(l.back);
    drop_link(i);
  }
  std::uint32_t id = 0;              // index of its box, filter and flag
  std::size_t live_index = 0;        // in live_
  std::size_t move_index = kNoMove;  // in moves_, kNoMove when none is pending
  std::size_t huge_index = kNoMove;  // in huge_, kNoMove when in the structure
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

template <class Box>
void set_box(Box& box, const btVector3& aabbMin, const btVector3& aabbMax) {
  for (int a = 0; a < 3; ++a) {
    box.lo[a] = aabbMin[a];
    box.hi[a] = aabbMax[a];
  }
}

// A proxy id's flag between two passes.
constexpr std::uint8_t kSteady = 0;  // in its fat box since the last pass
constexpr std::uint8_t kFresh = 1;   // new, or left its fat box
constexpr std::uint8_t kDead = 2;    // destroyed: its id is freed by the pass

// A pass reads the structure's whole pair list when more than one proxy in
// this many is fresh, and queries the structure once per fresh proxy below.
constexpr std::size_t kWholeListShare = 8;

}  // namespace

BulletBroadphase::BulletBroadphase(btOverlappingPairCache* cache, const BulletOptions& options)
    : options_(options), owns_cache_(cache == nullptr) {
  if (!(options_.margin >= 0 && std::isfinite(options_.margin)))
    throw InvalidConfig("broadphase::BulletBroadphase: margin must be finite and >= 0, not " +
                        std::to_string(options_.margin));
  if (options_.quantized_bits != 0 && options_.quantized_bits != 16 &&
      options_.quantized_bits != 32)
    throw InvalidConfig(
        "broadphase::BulletBroadphase: quantized_bits must be 0 (exact), 16 or 32, not " +
        std::to_string(options_.quantized_bits));
  make_structure();
  if (owns_cache_) {
    void* mem = btAlignedAlloc(sizeof(btHashedOverlappingPairCache), 16);
    cache_ = new (mem) btHashedOverlappingPairCache();
  } else {
    cache_ = cache;
  }
  filters_apply_ = cache_->getOverlapFilterCallback() == nullptr;
  if (options_.quantized_bits != 0) {
    try {
      sweep_ = std::make_unique<bullet_detail::QuantizedSweep>(
          options_.world_min, options_.world_max, options_.max_proxies, options_.quantized_bits,
          cache_);
    } catch (...) {
      if (owns_cache_) {
        cache_->~btOverlappingPairCache();
        btAlignedFree(cache_);
      }
      throw;
    }
  }
}

BulletBroadphase::~BulletBroadphase() {
  sweep_.reset();  // before the cache it uses
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
                                                 int shapeType, void* userPtr,
                                                 int collisionFilterGroup, int collisionFilterMask,
                                                 btDispatcher* dispatcher) {
  if (sweep_)
    return sweep_->createProxy(aabbMin, aabbMax, shapeType, userPtr, collisionFilterGroup,
                               collisionFilterMask, dispatcher);
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
  if (free_ids_.empty()) {
    p->id = static_cast<std::uint32_t>(proxy_of_.size());
    proxy_of_.push_back(nullptr);
    boxes_.emplace_back();
    fresh_.push_back(kSteady);
    moved_.push_back(0);
  } else {
    p->id = free_ids_.back();
    free_ids_.pop_back();
  }
  proxy_of_[p->id] = p;
  set_box(boxes_[p->id], aabbMin, aabbMax);
  boxes_[p->id].filter = filter_of(*p);
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
  mark_fresh(*p);
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

void BulletBroadphase::mark_fresh(const Proxy& p) {
  if (fresh_[p.id] != kSteady) return;
  fresh_[p.id] = kFresh;
  fresh_ids_.push_back(p.id);
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
  if (sweep_) return sweep_->destroyProxy(proxy, dispatcher);
  auto* p = static_cast<Proxy*>(proxy);
  // A cache with deferred removal ignores removeOverlappingPair; the
  // others lose the proxy's pairs one by one, O(its pairs) where
  // removeOverlappingPairsContainingProxy reads every pair of the cache.
  if (cache_->hasDeferredRemoval()) {
    cache_->removeOverlappingPairsContainingProxy(p, dispatcher);
  } else {
    for (const Proxy::Link& l : p->partners) cache_->removeOverlappingPair(p, l.other, dispatcher);
  }
  for (const Proxy::Link& l : p->partners) l.other->drop_link(l.back);
  pair_count_ -= p->partners.size();
  if (p->huge()) {
    drop_huge(*p);
  } else {
    leave_structure(*p);
  }
  // The id is freed by the next pass, which drops its candidates.
  if (fresh_[p->id] == kSteady) fresh_ids_.push_back(p->id);
  fresh_[p->id] = kDead;
  proxy_of_[p->id] = nullptr;
  live_[p->live_index] = live_.back();
  live_[p->live_index]->live_index = p->live_index;
  live_.pop_back();
  free_uids_.push_back(p->m_uniqueId);
  delete p;
}

void BulletBroadphase::setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin,
                               const btVector3& aabbMax, btDispatcher* dispatcher) {
  if (sweep_) return sweep_->setAabb(proxy, aabbMin, aabbMax, dispatcher);
  auto* p = static_cast<Proxy*>(proxy);
  if (p->m_aabbMin == aabbMin && p->m_aabbMax == aabbMax) return;  // a body asleep or at rest
  p->m_aabbMin = aabbMin;
  p->m_aabbMax = aabbMax;
  set_box(boxes_[p->id], aabbMin, aabbMax);
  moved_[p->id] = 1;
  any_moved_ = true;
  const bool huge = is_huge(aabbMin, aabbMax);
  if (huge != p->huge()) {
    mark_fresh(*p);
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
  mark_fresh(*p);
  // The new fat box is stretched by the box's travel since its last one,
  // on the side it travelled to (btDbvtBroadphase predicts the same way
  // from its leaf's displacement): a falling body leaves its fat box half
  // as often. Measured against no stretch and twice the travel, each world
  // of the engines' lab on kdtree (dbvt's broad phase over ours, one run
  // each): 100 000 falling boxes (60 steps) 2.80x, 4.86x, 5.42x; 10 000
  // 2.10x, 4.22x; 3 000 1.48x, 1.50x, 1.41x; four groups 1.36x, 1.80x,
  // 1.55x; the ghost 1.01x, 1.30x, 1.21x; mixed 2.10x, 2.06x, 1.82x.
  double travel[3];
  for (int a = 0; a < 3; ++a)
    travel[a] =
        0.5 * (double(aabbMin[a]) + double(aabbMax[a])) - 0.5 * (p->fat_lo[a] + p->fat_hi[a]);
  fatten(*p);
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(travel[a])) continue;
    p->fat_lo[a] += std::min(travel[a], 0.0);
    p->fat_hi[a] += std::max(travel[a], 0.0);
  }
  const Shape s = shape_of(p->fat_lo, p->fat_hi);
  if (p->move_index == Proxy::kNoMove) {
    p->move_index = moves_.size();
    moves_.push_back({p->handle, s});
  } else {
    moves_[p->move_index].shape = s;
  }
}

void BulletBroadphase::getAabb(btBroadphaseProxy* proxy, btVector3& aabbMin,
                               btVector3& aabbMax) const {
  if (sweep_) return sweep_->getAabb(proxy, aabbMin, aabbMax);
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

// Bullet's closed box test in btScalar, then group and mask unless the
// cache has a filter callback, all without a branch: about two candidates
// in three overlap, in no order a predictor could learn, and a branch on it
// made the pass over the candidates half again as long (3 000 boxes).
inline bool BulletBroadphase::begins(std::uint32_t a, std::uint32_t b) const {
  const Box& p = boxes_[a];
  const Box& q = boxes_[b];
  const bool touch = (p.lo[0] <= q.hi[0]) & (q.lo[0] <= p.hi[0]) & (p.lo[1] <= q.hi[1]) &
                     (q.lo[1] <= p.hi[1]) & (p.lo[2] <= q.hi[2]) & (q.lo[2] <= p.hi[2]);
  const bool pass =
      ((p.filter.group & q.filter.mask) != 0) & ((q.filter.group & p.filter.mask) != 0);
  return touch & (pass | !filters_apply_);
}

void BulletBroadphase::begin_pair(Proxy* p, Proxy* q) {
  p->partners.push_back({q, static_cast<std::uint32_t>(q->partners.size())});
  q->partners.push_back({p, static_cast<std::uint32_t>(p->partners.size() - 1)});
  ++pair_count_;
  cache_->addOverlappingPair(p, q);
}

void BulletBroadphase::end_pair(Proxy* p, Proxy* q, btDispatcher* dispatcher) {
  // Found from the shorter list (a box's, not the plane's).
  if (p->partners.size() <= q->partners.size()) {
    end_link(p, p->find(q), dispatcher);
  } else {
    end_link(q, q->find(p), dispatcher);
  }
}

void BulletBroadphase::end_link(Proxy* p, std::size_t i, btDispatcher* dispatcher) {
  Proxy* q = p->partners[i].other;
  p->unlink(i);
  --pair_count_;
  removed_ = true;
  if (!cache_->hasDeferredRemoval()) cache_->removeOverlappingPair(p, q, dispatcher);
}

// A candidate for a fresh proxy: its pairs that ended are gone already, so
// a pair that begins is new unless it is among the shorter partner list.
void BulletBroadphase::add_candidate(Proxy* p, Proxy* q) {
  const bool in = begins(p->id, q->id);
  if (in) {
    const Proxy* shorter = p->partners.size() <= q->partners.size() ? p : q;
    const Proxy* other = shorter == p ? q : p;
    if (shorter->find(other) == Proxy::kNoMove) begin_pair(p, q);
  }
  candidates_.push_back({p->id, q->id, in});
}

// Group and mask live in the proxy, where users also change them directly
// (getBroadphaseHandle()->m_collisionFilterMask = ...): every pass copies
// them, O(proxies), and the candidates' test reads the copy. With a user's
// filter callback the cache decides alone, when a pair begins (as
// btAxisSweep3 asks it).
void BulletBroadphase::calculateOverlappingPairs(btDispatcher* dispatcher) {
  if (sweep_) return sweep_->calculateOverlappingPairs(dispatcher);
  const bool apply = cache_->getOverlapFilterCallback() == nullptr;
  if (apply != filters_apply_) {  // every candidate's answer may change
    filters_apply_ = apply;
    std::fill(moved_.begin(), moved_.end(), 1);
    any_moved_ = true;
  }
  if (filters_apply_) {
    for (const Proxy* p : live_) {
      const Filter f = filter_of(*p);
      if (f == boxes_[p->id].filter) continue;
      boxes_[p->id].filter = f;
      moved_[p->id] = 1;
      any_moved_ = true;
    }
  }
  if (!moves_.empty()) {
    structure_->update(moves_);
    for (const Move& m : moves_) by_slot_[m.handle.index]->move_index = Proxy::kNoMove;
    moves_.clear();
  } else if (settle_due_) {
    structure_->settle();
  }
  settle_due_ = false;
  removed_ = false;
  // One structure query per fresh proxy, or its whole pair list: on 3 000
  // boxes the queries cost less while fewer than an eighth were fresh.
  if (fresh_ids_.size() * kWholeListShare > live_.size()) {
    full_pass(dispatcher);
  } else {
    incremental_pass(dispatcher);
  }
  for (const std::uint32_t id : fresh_ids_) {
    if (fresh_[id] == kDead) free_ids_.push_back(id);
    fresh_[id] = kSteady;
  }
  fresh_ids_.clear();
  if (any_moved_) std::fill(moved_.begin(), moved_.end(), 0);
  any_moved_ = false;
  if (cache_->hasDeferredRemoval() && removed_) remove_deferred(dispatcher);
}

void BulletBroadphase::incremental_pass(btDispatcher* dispatcher) {
  // A fresh proxy's pairs that ended: after this, every pair it is in
  // overlaps, so its fat box meets the other's and its query finds it.
  for (const std::uint32_t id : fresh_ids_) {
    Proxy* p = proxy_of_[id];
    if (fresh_[id] == kDead) continue;  // its pairs ended with it
    for (std::size_t i = 0; i < p->partners.size();) {
      if (begins(p->id, p->partners[i].other->id)) {
        ++i;
      } else {
        end_link(p, i, dispatcher);  // swaps the last partner into i
      }
    }
  }
  // The candidates between steady proxies: each tested where a box or a
  // filter changed, the rest dropped (written and not counted: a branch on
  // the fresh ones cost more). With no box changed (a world asleep) the
  // pass has nothing to do.
  if (!any_moved_ && fresh_ids_.empty()) return;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    Candidate c = candidates_[i];
    const bool steady = (fresh_[c.a] | fresh_[c.b]) == kSteady;
    const std::uint32_t in = (moved_[c.a] | moved_[c.b]) != 0 ? begins(c.a, c.b) : c.in;
    if (in != c.in && steady) {
      if (in) {
        begin_pair(proxy_of_[c.a], proxy_of_[c.b]);
      } else {
        end_pair(proxy_of_[c.a], proxy_of_[c.b], dispatcher);
      }
      c.in = in;
    }
    candidates_[kept] = c;
    kept += steady;
  }
  candidates_.resize(kept);
  // The fresh proxies' candidates. A pair of two fresh proxies comes from
  // the one with the smaller id; a huge proxy meets every proxy, and a
  // fresh one meets the steady huge ones.
  for (const std::uint32_t id : fresh_ids_) {
    Proxy* p = proxy_of_[id];
    if (fresh_[id] == kDead) continue;
    auto meets = [&](const Proxy* q) {
      return q != p && !(fresh_[q->id] != kSteady && q->id < id);
    };
    if (p->huge()) {  // every other proxy but a fresh huge one with a smaller id
      for (Proxy* q : live_)
        if (q != p && !(q->huge() && fresh_[q->id] != kSteady && q->id < id)) add_candidate(p, q);
      continue;
    }
    structure_->query(shape_of(p->fat_lo, p->fat_hi), [&](Handle h) {
      Proxy* q = by_slot_[h.index];
      if (meets(q)) add_candidate(p, q);
      return true;
    });
    for (Proxy* q : huge_)
      if (fresh_[q->id] == kSteady) add_candidate(p, q);
  }
}

void BulletBroadphase::full_pass(btDispatcher* dispatcher) {
  // The pairs that ended, from the candidates that had begun.
  for (const Candidate& c : candidates_) {
    if (!c.in || fresh_[c.a] == kDead || fresh_[c.b] == kDead) continue;
    if (!begins(c.a, c.b)) end_pair(proxy_of_[c.a], proxy_of_[c.b], dispatcher);
  }
  candidates_.clear();
  found_.clear();
  structure_->find_pairs(found_);
  for (const HandlePair& hp : found_) add_candidate(by_slot_[hp.a.index], by_slot_[hp.b.index]);
  for (Proxy* h : huge_)
    for (Proxy* q : live_)
      if (q != h && !(q->huge() && q->id < h->id)) add_candidate(h, q);
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
        (a->partners.size() <= b->partners.size() ? a->find(b) : b->find(a)) != Proxy::kNoMove)
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
  if (sweep_) return sweep_->rayTest(rayFrom, rayTo, callback, aabbMin, aabbMax);
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
  if (sweep_) return sweep_->aabbTest(aabbMin, aabbMax, callback);
  structure_->query(shape_of(aabbMin, aabbMax), [&](Handle h) {
    Proxy* p = by_slot_[h.index];
    if (overlap(p->m_aabbMin, p->m_aabbMax, aabbMin, aabbMax)) callback.process(p);
    return true;
  });
  for (Proxy* p : huge_)
    if (overlap(p->m_aabbMin, p->m_aabbMax, aabbMin, aabbMax)) callback.process(p);
}

void BulletBroadphase::getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const {
  if (sweep_) return sweep_->getBroadphaseAabb(aabbMin, aabbMax);
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

void BulletBroadphase::resetPool(btDispatcher* dispatcher) {
  if (sweep_) return sweep_->resetPool(dispatcher);
  if (!live_.empty()) return;
  make_structure();
  by_slot_.clear();
  huge_.clear();
  moves_.clear();
  free_uids_.clear();
  next_uid_ = 1;
  settle_due_ = false;
  pair_count_ = 0;
  fresh_.clear();
  moved_.clear();
  any_moved_ = false;
  boxes_.clear();
  proxy_of_.clear();
  fresh_ids_.clear();
  free_ids_.clear();
  candidates_.clear();
}

void BulletBroadphase::validate() const {
  if (sweep_) return;
  structure_->validate();
  auto fail = [](const std::string& what) {
    throw std::logic_error("BulletBroadphase::validate: " + what);
  };
  std::size_t links = 0;
  for (std::size_t i = 0; i < live_.size(); ++i) {
    const Proxy* p = live_[i];
    if (p->live_index != i) fail("a proxy's live_index is wrong");
    if (proxy_of_.at(p->id) != p) fail("proxy_of_ does not name proxy " + std::to_string(p->id));
    if (fresh_.at(p->id) != kSteady) fail("a fresh flag outlived its pass");
    for (std::size_t k = 0; k < p->partners.size(); ++k) {
      const Proxy::Link& l = p->partners[k];
      if (l.other == p) fail("a proxy is its own partner");
      if (l.back >= l.other->partners.size() || l.other->partners[l.back].other != p ||
          l.other->partners[l.back].back != k)
        fail("the link back of a pair of proxy " + std::to_string(p->id) + " is wrong");
      if (l.other->id > p->id && !begins(p->id, l.other->id))
        fail("a pair whose boxes do not overlap (or whose filters fail) is kept");
    }
    links += p->partners.size();
  }
  if (links != 2 * pair_count_) fail("pair_count_ is not the pairs in the lists");
  std::size_t begun = 0;
  for (const Candidate& c : candidates_) {
    if (c.a == c.b) fail("a candidate pairs a proxy with itself");
    const Proxy* a = proxy_of_.at(c.a);
    const Proxy* b = proxy_of_.at(c.b);
    if (a == nullptr || b == nullptr) fail("a candidate names a destroyed proxy");
    const bool listed = a->find(b) != Proxy::kNoMove;
    if (listed != (c.in != 0)) fail("a candidate's bit disagrees with the partner lists");
    begun += listed;
  }
  if (begun != pair_count_) fail("a begun pair is not among the candidates, or twice");
}

std::size_t BulletBroadphase::proxy_count() const {
  return sweep_ ? sweep_->proxy_count() : live_.size();
}

void BulletBroadphase::printStats() {
  if (sweep_) {
    std::printf("BulletBroadphase over btAxisSweep3's %d-bit grid: %u proxies\n",
                options_.quantized_bits, sweep_->proxy_count());
    return;
  }
  std::printf("BulletBroadphase over %s: %zu proxies, %zu pairs in the last pass, %zu bytes\n",
              options_.structure.c_str(), live_.size(), pair_count_, structure_->memory_bytes());
}

}  // namespace broadphase
