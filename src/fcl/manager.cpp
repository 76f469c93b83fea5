// FclCollisionManager: FCL's broad-phase manager interface over a structure
// of the library (include/broadphase/fcl.hpp says what it reports).
#include <algorithm>
#include <broadphase/detail/level_grid.hpp>
#include <broadphase/fcl.hpp>
#include <broadphase/geometry.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace broadphase {

namespace {

/// FCL's `AABB::overlap` (fcl/math/bv/AABB-inl.h), written out so that it
/// is inlined in the pair loops: closed boxes, no overlap as soon as one
/// bound lies beyond the other's on an axis (a NaN bound never does). The
/// library's is out of line in libfcl, a call per candidate; measured
/// together with the fetching ahead in collide (docs/fcl.md).
template <class S>
bool fcl_overlap(const ::fcl::AABB<S>& a, const ::fcl::AABB<S>& b) {
  for (int k = 0; k < 3; ++k)
    if (a.min_[k] > b.max_[k] || a.max_[k] < b.min_[k]) return false;
  return true;
}

/// AABBs with a coordinate beyond this are kept apart from the structure:
/// the box around them (centre ± half) stays far from overflow, and FCL's
/// planes and half-spaces (±max) land there.
constexpr double kFar = 0x1p1000;

/// Relative growth of a distance search's reach, so that every pair whose
/// AABB distance FCL computes as at most `reach` is inside the grown query
/// box: AABB::distance rounds each gap, square, sum and the square root by
/// at most a few ulps of S (2^-23 relative in float); 2^-20 covers float
/// and double with a margin.
constexpr double kReachSlack = 0x1p-20;

/// A box of the library's shape vocabulary that contains FCL's AABB `b`
/// grown by `reach` on every side, with the slack of `bounds()` (geometry.hpp)
/// so that the structure's own rounded box test never misses a pair whose
/// FCL AABBs overlap. False for an AABB that is not finite, is inverted or
/// reaches beyond kFar: such objects are tested apart.
template <class S>
bool box_around(const ::fcl::AABB<S>& b, double reach, Shape& out) {
  Vec3 c, h;
  for (int a = 0; a < 3; ++a) {
    const double lo = static_cast<double>(b.min_[a]);
    const double hi = static_cast<double>(b.max_[a]);
    if (!(lo <= hi) || !(std::fabs(lo) <= kFar) || !(std::fabs(hi) <= kFar)) return false;
    c[a] = lo * 0.5 + hi * 0.5;
    const double half = hi * 0.5 - lo * 0.5;
    h[a] = half + (std::fabs(c[a]) + half) * kBoundsSlack + kBoundsFloor + reach;
  }
  out = Shape::box(c, h);
  return true;
}

template <class S>
bool same_box(const ::fcl::AABB<S>& a, const ::fcl::AABB<S>& b) {
  for (int k = 0; k < 3; ++k)
    if (!(a.min_[k] == b.min_[k]) || !(a.max_[k] == b.max_[k])) return false;
  return true;
}

}  // namespace

/// One side of a pair search: an object with the AABB to test it by, its
/// registration order and its slot when it is one of ours (else kNone).
template <class S>
struct FclCollisionManager<S>::Probe {
  Object* object;
  ::fcl::AABB<S> box;
  std::uint64_t order;
  std::uint32_t slot;
};

/// A pair found by a distance search, with FCL's AABB distance.
template <class S>
struct FclCollisionManager<S>::Candidate {
  S d;
  std::uint64_t first_order, second_order;
  Object* first;
  Object* second;
  friend bool operator<(const Candidate& x, const Candidate& y) {
    if (x.d != y.d) return x.d < y.d;
    if (x.first_order != y.first_order) return x.first_order < y.first_order;
    return x.second_order < y.second_order;
  }
};

template <class S>
FclCollisionManager<S>::FclCollisionManager(std::string_view spec)
    : FclCollisionManager(spec, Config{}) {
  fit_world_ = true;
}

template <class S>
FclCollisionManager<S>::FclCollisionManager(std::string_view spec, const Config& config)
    : FclCollisionManager(make_structure(spec, config)) {
  spec_ = spec;
  config_ = config;
}

template <class S>
FclCollisionManager<S>::FclCollisionManager(std::unique_ptr<AnyBroadPhase> structure)
    : structure_(std::move(structure)) {
  if (!structure_)
    throw std::invalid_argument("broadphase::FclCollisionManager: the structure is null");
  if (structure_->size() != 0)
    throw std::invalid_argument("broadphase::FclCollisionManager: the structure holds " +
                                std::to_string(structure_->size()) +
                                " objects; it must start empty");
}

template <class S>
FclCollisionManager<S>::~FclCollisionManager() = default;

template <class S>
std::uint32_t FclCollisionManager<S>::add(Object* obj) {
  std::uint32_t slot;
  if (!free_.empty()) {
    slot = free_.back();
    free_.pop_back();
  } else {
    slot = static_cast<std::uint32_t>(records_.size());
    records_.emplace_back();
  }
  Record& r = records_[slot];
  r = Record{};
  r.object = obj;
  r.box = obj->getAABB();
  aabb_offset_ =
      reinterpret_cast<const char*>(&obj->getAABB()) - reinterpret_cast<const char*>(obj);
  r.order = next_order_++;
  slot_of_.emplace(obj, slot);
  ++count_;
  place(slot, false);
  return slot;
}

// Objects enter the structure as `fixed` and become `dynamic` at their first
// move (a removal and an insertion): FCL does not say which objects move, and
// the default structure caches the pairs among fixed objects and keeps Verlet
// lists for the moving ones (docs/performance.md), so a world whose objects
// all entered as dynamic re-sorted all of them every update.
template <class S>
void FclCollisionManager<S>::place(std::uint32_t slot, bool moving) {
  Record& r = records_[slot];
  r.moving = moving;
  Shape shape;
  if (box_around(r.box, 0.0, shape)) {
    r.handle = structure_->insert(shape, slot, moving ? Motion::dynamic : Motion::fixed);
    if (slot_of_handle_.size() <= r.handle.index) {
      slot_of_handle_.resize(r.handle.index + 1, kNone);
      hot_.resize(r.handle.index + 1);
    }
    slot_of_handle_[r.handle.index] = slot;
    hot_[r.handle.index] = {r.box, r.object, r.order};
    mark_fixed(r.handle, !moving);
    if (!moving) fixed_complete_ = false;
  } else {
    r.apart = static_cast<std::uint32_t>(apart_.size());
    apart_.push_back(slot);
  }
}

template <class S>
void FclCollisionManager<S>::unplace(std::uint32_t slot) {
  Record& r = records_[slot];
  if (!r.handle.is_null()) {
    structure_->remove(r.handle);
    if (!r.moving) fixed_dropped_ = true;
    mark_fixed(r.handle, false);
    slot_of_handle_[r.handle.index] = kNone;
    r.handle = Handle{};
  } else {
    const std::uint32_t last = apart_.back();
    apart_[r.apart] = last;
    records_[last].apart = r.apart;
    apart_.pop_back();
    r.apart = kNone;
  }
}

template <class S>
void FclCollisionManager<S>::registerObjects(const std::vector<Object*>& objs) {
  for (std::size_t i = 0; i < objs.size(); ++i) {
    if (objs[i] == nullptr)
      throw std::invalid_argument("broadphase::FclCollisionManager::registerObjects: object " +
                                  std::to_string(i) + " of the batch is null");
    if (slot_of_.count(objs[i]) != 0)
      throw std::invalid_argument("broadphase::FclCollisionManager::registerObjects: object " +
                                  std::to_string(i) + " of the batch is already registered");
  }
  std::vector<const Object*> seen(objs.begin(), objs.end());
  std::sort(seen.begin(), seen.end());
  if (std::adjacent_find(seen.begin(), seen.end()) != seen.end())
    throw std::invalid_argument(
        "broadphase::FclCollisionManager::registerObjects: an object appears twice in the batch");
  for (Object* o : objs) add(o);
  fit_world();
  structure_->settle();
  renew_fixed_pairs();
}

template <class S>
void FclCollisionManager<S>::registerObject(Object* obj) {
  if (obj == nullptr)
    throw std::invalid_argument("broadphase::FclCollisionManager::registerObject: null object");
  if (slot_of_.count(obj) != 0)
    throw std::invalid_argument(
        "broadphase::FclCollisionManager::registerObject: the object is already registered");
  add(obj);
}

template <class S>
void FclCollisionManager<S>::unregisterObject(Object* obj) {
  const auto it = slot_of_.find(obj);
  if (it == slot_of_.end()) return;
  const std::uint32_t slot = it->second;
  unplace(slot);
  records_[slot].object = nullptr;
  free_.push_back(slot);
  slot_of_.erase(it);
  --count_;
}

template <class S>
void FclCollisionManager<S>::setup() {
  fit_world();
  structure_->settle();
  renew_fixed_pairs();
}

// The structures size their grids and trees by Config::world; objects
// outside it stay exact but crowd its border cells (see the constructor's
// comment for what it cost), and a world far larger than the objects
// gives them few, crowded cells. One pass over the records decides, O(n)
// against settle()'s O(n log n) or more; a refit places every object
// again, about what registering them cost.
template <class S>
void FclCollisionManager<S>::fit_world() {
  if (!fit_world_) return;
  constexpr std::size_t kOutsideShare = 16;  // refit when more than 1 in 16 lie outside
  constexpr double kVolumeRatio = 64;        // or the world is 64 times what they need
  Aabb bounds{};
  std::size_t placed = 0, outside = 0;
  for (const Record& r : records_) {
    if (r.object == nullptr || r.handle.is_null()) continue;
    const Aabb b{{double(r.box.min_[0]), double(r.box.min_[1]), double(r.box.min_[2])},
                 {double(r.box.max_[0]), double(r.box.max_[1]), double(r.box.max_[2])}};
    bounds = placed == 0 ? b : bounds.merged(b);
    ++placed;
    outside += !config_.world.contains(b);
  }
  if (placed == 0) return;
  const Vec3 size = bounds.hi - bounds.lo;
  const double pad = std::max({size.x, size.y, size.z, 1.0}) / 8;
  const Aabb fit{bounds.lo - Vec3{pad, pad, pad}, bounds.hi + Vec3{pad, pad, pad}};
  auto volume = [](const Aabb& a) {
    const Vec3 e = a.hi - a.lo;
    return e.x * e.y * e.z;
  };
  if (outside * kOutsideShare <= placed && volume(config_.world) <= kVolumeRatio * volume(fit))
    return;
  if (!std::isfinite(volume(fit)) || !(volume(fit) > 0)) return;  // beyond double's range: keep
  Config c = config_;
  c.world = fit;
  std::unique_ptr<AnyBroadPhase> fresh = make_structure(spec_, c);
  config_ = c;
  structure_ = std::move(fresh);
  forget_handles();
  for (std::uint32_t slot = 0; slot < records_.size(); ++slot) {
    Record& r = records_[slot];
    if (r.object == nullptr || r.handle.is_null()) continue;
    r.handle = Handle{};
    place(slot, r.moving);
  }
}

// FCL's tree skips an object whose AABB equals the stored one within 100
// epsilon (AABB::equal); here any change of a bit counts, so the AABBs
// tested are always the ones read at the last update.
template <class S>
bool FclCollisionManager<S>::refresh(std::uint32_t slot, std::vector<Move>& moves) {
  Record& r = records_[slot];
  const ::fcl::AABB<S>& now = r.object->getAABB();
  if (same_box(now, r.box)) return false;
  r.box = now;
  Shape shape;
  if (r.moving && !r.handle.is_null() && box_around(r.box, 0.0, shape)) {
    moves.push_back({r.handle, shape});
    hot_[r.handle.index].box = r.box;
  } else {
    unplace(slot);
    place(slot, true);
    replaced_ = true;
  }
  return true;
}

// An object's first move re-inserts it (refresh). In the default structure
// single inserts wait on a short unsorted "loose" list that every pair pass
// and query scans (grid_verlet.hpp, "Mutations") until the structure
// rebuilds; settle() after such a frame files them at once.
template <class S>
void FclCollisionManager<S>::commit(std::vector<Move>& moves) {
  if (!moves.empty()) structure_->update(moves);
  if (replaced_) structure_->settle();
  replaced_ = false;
  renew_fixed_pairs();
}

template <class S>
void FclCollisionManager<S>::mark_fixed(Handle h, bool fixed) {
  const std::size_t word = h.index >> 6;
  if (fixed_bits_.size() <= word) fixed_bits_.resize(word + 1, 0);
  const std::uint64_t bit = std::uint64_t{1} << (h.index & 63);
  fixed_bits_[word] = fixed ? fixed_bits_[word] | bit : fixed_bits_[word] & ~bit;
}

template <class S>
void FclCollisionManager<S>::renew_fixed_pairs() {
  if (fixed_complete_ && !fixed_dropped_) return;
  if (fixed_complete_) {
    // Objects only left the fixed set: drop their pairs.
    std::size_t kept = 0;
    for (std::size_t i = 0; i < fixed_pairs_.size(); ++i) {
      const auto [a, b] = fixed_pair_index_[i];
      if (!is_fixed(Handle{a, 0}) || !is_fixed(Handle{b, 0})) continue;
      fixed_pairs_[kept] = fixed_pairs_[i];
      fixed_pair_index_[kept] = fixed_pair_index_[i];
      ++kept;
    }
    fixed_pairs_.resize(kept);
    fixed_pair_index_.resize(kept);
    fixed_dropped_ = false;
    return;
  }
  fixed_pairs_.clear();
  fixed_pair_index_.clear();
  std::vector<HandlePair> pairs;
  structure_->find_pairs(pairs);
  for (const HandlePair& hp : pairs) {
    if (!is_fixed(hp.a) || !is_fixed(hp.b)) continue;
    HandlePair p = hp;
    if (hot_[p.b.index].order < hot_[p.a.index].order) std::swap(p.a, p.b);
    const Hot& a = hot_[p.a.index];
    const Hot& b = hot_[p.b.index];
    if (!fcl_overlap(a.box, b.box)) continue;
    fixed_pairs_.push_back({a.object, b.object});
    fixed_pair_index_.emplace_back(p.a.index, p.b.index);
  }
  fixed_complete_ = true;
  fixed_dropped_ = false;
}

template <class S>
void FclCollisionManager<S>::update() {
  std::vector<Move> moves;
  for (std::uint32_t slot = 0; slot < records_.size(); ++slot)
    if (records_[slot].object != nullptr) refresh(slot, moves);
  commit(moves);
}

template <class S>
void FclCollisionManager<S>::update(Object* updated_obj) {
  const auto it = slot_of_.find(updated_obj);
  if (it == slot_of_.end()) return;
  std::vector<Move> moves;
  refresh(it->second, moves);
  commit(moves);
}

template <class S>
void FclCollisionManager<S>::update(const std::vector<Object*>& updated_objs) {
  // A program names the same objects in the same order frame after frame:
  // each position of the list remembers the slot it named last time, which
  // holds that object while the slot's record still names it (a record
  // names one object, an object has one slot). The hash lookups this saves
  // were most of the update: with them and without fetching the records
  // and the objects' AABBs ahead, fcl_bench's update of 20 000 movers among
  // 10^5 objects took 4.8 ms, 3.7 of them before the structure's update
  // (one run timed by parts); now 1.9 ms (medians of 4 runs).
  const std::size_t n = updated_objs.size();
  update_slots_.resize(n, kNone);
  constexpr std::size_t kAhead = 8;
  std::vector<Move> moves;
  moves.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) {
      detail::prefetch(aabb_of(updated_objs[i + kAhead]));
      const std::uint32_t ahead = update_slots_[i + kAhead];
      if (ahead < records_.size()) {
        const char* r = reinterpret_cast<const char*>(&records_[ahead]);
        detail::prefetch(r);
        detail::prefetch(r + sizeof(Record) - 1);
      }
    }
    Object* const o = updated_objs[i];
    std::uint32_t slot = update_slots_[i];
    if (slot >= records_.size() || records_[slot].object != o) {
      const auto it = slot_of_.find(o);
      slot = it == slot_of_.end() ? kNone : it->second;
      update_slots_[i] = slot;
    }
    if (slot != kNone) refresh(slot, moves);
  }
  commit(moves);
}

template <class S>
void FclCollisionManager<S>::clear() {
  for (std::uint32_t slot = 0; slot < records_.size(); ++slot)
    if (records_[slot].object != nullptr) unplace(slot);
  records_.clear();
  free_.clear();
  slot_of_.clear();
  apart_.clear();
  update_slots_.clear();
  forget_handles();
  count_ = 0;
}

// What is kept by the structure's handles: the copies, the fixed bits and
// the fixed pairs (clear, and a structure made anew by fit_world).
template <class S>
void FclCollisionManager<S>::forget_handles() {
  slot_of_handle_.clear();
  hot_.clear();
  fixed_bits_.clear();
  fixed_pairs_.clear();
  fixed_pair_index_.clear();
  fixed_complete_ = true;
  fixed_dropped_ = false;
}

template <class S>
void FclCollisionManager<S>::getObjects(std::vector<Object*>& objs) const {
  std::vector<std::pair<std::uint64_t, Object*>> by_order;
  by_order.reserve(count_);
  for (const Record& r : records_)
    if (r.object != nullptr) by_order.emplace_back(r.order, r.object);
  std::sort(by_order.begin(), by_order.end());
  objs.resize(by_order.size());
  for (std::size_t i = 0; i < by_order.size(); ++i) objs[i] = by_order[i].second;
}

template <class S>
bool FclCollisionManager<S>::empty() const {
  return count_ == 0;
}

template <class S>
std::size_t FclCollisionManager<S>::size() const {
  return count_;
}

template <class S>
std::vector<typename FclCollisionManager<S>::Probe> FclCollisionManager<S>::own_probes() const {
  std::vector<Probe> probes;
  probes.reserve(count_);
  for (std::uint32_t slot = 0; slot < records_.size(); ++slot) {
    const Record& r = records_[slot];
    if (r.object != nullptr) probes.push_back({r.object, r.box, r.order, slot});
  }
  return probes;
}

/// Visits the slot of every registered object that may lie within `reach`
/// of the probe's AABB (a superset: the structure's objects whose boxes meet
/// the probe's box grown by `reach`, and every object kept apart), or of
/// every object when the probe itself cannot be boxed. `visit(slot)` returns
/// false to stop; returns true when it stopped.
template <class S>
template <class Visit>
bool FclCollisionManager<S>::candidates_of(const Probe& p, double reach, Visit&& visit) const {
  Shape shape;
  if (!box_around(p.box, reach + reach * kReachSlack, shape)) {
    for (std::uint32_t slot = 0; slot < records_.size(); ++slot)
      if (records_[slot].object != nullptr && !visit(slot)) return true;
    return false;
  }
  const QueryCost cost = structure_->query(
      shape, [&](Handle h) { return static_cast<bool>(visit(slot_of_handle_[h.index])); });
  if (cost.stopped) return true;
  for (const std::uint32_t slot : apart_)
    if (!visit(slot)) return true;
  return false;
}

template <class S>
bool FclCollisionManager<S>::collide_probes(const std::vector<Probe>& probes, bool probes_first,
                                            void* cdata,
                                            ::fcl::CollisionCallBack<S> callback) const {
  for (const Probe& p : probes) {
    const bool stopped = candidates_of(p, 0.0, [&](std::uint32_t slot) {
      const Record& r = records_[slot];
      if (r.object == p.object || !fcl_overlap(r.box, p.box)) return true;
      return !(probes_first ? callback(p.object, r.object, cdata)
                            : callback(r.object, p.object, cdata));
    });
    if (stopped) return true;
  }
  return false;
}

template <class S>
void FclCollisionManager<S>::collide(Object* obj, void* cdata,
                                     ::fcl::CollisionCallBack<S> callback) const {
  if (count_ == 0) return;
  collide_probes({Probe{obj, obj->getAABB(), 0, kNone}}, true, cdata, callback);
}

template <class S>
void FclCollisionManager<S>::collide(void* cdata, ::fcl::CollisionCallBack<S> callback) const {
  if (count_ == 0) return;
  // The pairs among objects that never moved come from fixed_pairs_, FCL's
  // test done when the list was renewed: the callback alone, with the
  // objects' AABBs it reads fetched ahead. The rest come from the
  // structure's pair pass (find_pairs: no call per pair), then FCL's test
  // of the stored AABBs on each candidate. In fcl_bench at 10^5 objects
  // 300 000 of the 466 000 pairs are among fixed objects; the collide took
  // 18.1 ms (median of 4 runs) against 18.55 ms when every pair went through
  // the structure's pass, record lookups and test.
  const bool cached = fixed_complete_ && !fixed_dropped_;
  if (cached) {
    // Both lines an AABB may span (48 bytes, in an object aligned to 16),
    // 32 pairs ahead. The collide at 10^5 objects (fcl_bench, two builds
    // alternated, medians of 4 runs each): the first line 8 ahead 17.2 ms,
    // both lines 16.3; both 8 ahead 15.8, 16 ahead 14.6; 16 ahead 14.2, 32
    // ahead 13.6; 32 ahead 14.1, 64 ahead 13.9.
    constexpr std::size_t kAhead = 32;
    const std::size_t n = fixed_pairs_.size();
    const FixedPair* fp = fixed_pairs_.data();
    for (std::size_t i = 0; i < n; ++i) {
      if (i + kAhead < n) {
        for (const char* p : {aabb_of(fp[i + kAhead].first), aabb_of(fp[i + kAhead].second)}) {
          detail::prefetch(p);
          detail::prefetch(p + sizeof(::fcl::AABB<S>) - 1);
        }
      }
      if (callback(fp[i].first, fp[i].second, cdata)) return;
    }
  }
  std::vector<HandlePair> pairs;
  structure_->find_pairs(pairs);
  if (cached)
    pairs.erase(
        std::remove_if(pairs.begin(), pairs.end(),
                       [this](const HandlePair& hp) { return is_fixed(hp.a) && is_fixed(hp.b); }),
        pairs.end());
  // The objects' copies (hot_) and then the FCL objects of the pairs ahead
  // are fetched while this one is tested: both are scattered (an object is
  // FCL's own allocation), and the pair loop and the callback's reads of the
  // objects waited on them one after another. The copies, one line each by
  // handle index, replaced two lines of the record reached through
  // slot_of_handle_; the AABBs are fetched at aabb_of() rather than through
  // getAABB(), a call into libfcl per object: with both, collide took 17.6
  // ms against 18.8 (medians of 4 runs, fcl_bench at 10^5 objects). The
  // copies 32 pairs ahead and the AABBs 16 ahead: 13.2 ms against 14.2 at 16
  // and 8 ahead; 64 and 32 ahead 13.7 against 13.7 (two builds alternated,
  // medians of 4 runs each).
  constexpr std::size_t kRecordsAhead = 32, kObjectsAhead = 16;
  const Hot* const hot = hot_.data();
  // Both cache lines a 64-byte piece starting at p may touch.
  const auto fetch = [](const void* p) {
    detail::prefetch(p);
    detail::prefetch(static_cast<const char*>(p) + 63);
  };
  const std::size_t count = pairs.size();
  for (std::size_t i = 0; i < count; ++i) {
    if (i + kRecordsAhead < count) {
      const HandlePair& ahead = pairs[i + kRecordsAhead];
      detail::prefetch(&hot[ahead.a.index]);
      detail::prefetch(&hot[ahead.b.index]);
    }
    if (i + kObjectsAhead < count) {
      const HandlePair& ahead = pairs[i + kObjectsAhead];
      fetch(aabb_of(hot[ahead.a.index].object));
      fetch(aabb_of(hot[ahead.b.index].object));
    }
    const HandlePair& hp = pairs[i];
    const Hot* a = &hot[hp.a.index];
    const Hot* b = &hot[hp.b.index];
    if (!fcl_overlap(a->box, b->box)) continue;
    if (b->order < a->order) std::swap(a, b);
    if (callback(a->object, b->object, cdata)) return;
  }
  for (const std::uint32_t slot : apart_) {
    const Record& a = records_[slot];
    for (const Record& b : records_) {
      if (b.object == nullptr || b.object == a.object) continue;
      if (b.apart != kNone && b.order < a.order) continue;  // that pair came from b
      if (!fcl_overlap(a.box, b.box)) continue;
      const bool stop = a.order < b.order ? callback(a.object, b.object, cdata)
                                          : callback(b.object, a.object, cdata);
      if (stop) return;
    }
  }
}

template <class S>
void FclCollisionManager<S>::collide(Manager* other, void* cdata,
                                     ::fcl::CollisionCallBack<S> callback) const {
  if (other == this) {
    collide(cdata, callback);
    return;
  }
  if (count_ == 0 || other->size() == 0) return;
  if (const auto* ours = dynamic_cast<const FclCollisionManager*>(other)) {
    // The smaller side probes the larger one's structure.
    if (ours->size() > size()) {
      ours->collide_probes(own_probes(), true, cdata, callback);
    } else {
      collide_probes(ours->own_probes(), false, cdata, callback);
    }
    return;
  }
  std::vector<Object*> objs;
  other->getObjects(objs);
  std::vector<Probe> probes;
  probes.reserve(objs.size());
  for (Object* o : objs) probes.push_back({o, o->getAABB(), 0, kNone});
  collide_probes(probes, false, cdata, callback);
}

// The expanding search. Phase 0 takes the pairs whose AABBs touch (FCL
// distance 0); phase k the pairs at an AABB distance in (reach_{k-1},
// reach_k], each phase's in increasing distance, handed to the callback
// while their distance is below `dist` (FCL's rule). The first reach is the
// span of the objects over the cube root of their number (the spacing of
// as many objects spread evenly); it doubles while the callback has not
// lowered `dist` to a finite value, and is then set to `dist`, which ends
// the search after that phase: every pair not yet met is farther than
// `dist`. Pairs with an object kept apart are measured once, up front, and
// merged into the phases by their distance. When the reach passes twice the
// span every pair has been met.
template <class S>
void FclCollisionManager<S>::distance_probes(const std::vector<Probe>& probes, bool self,
                                             bool probes_first, void* cdata,
                                             ::fcl::DistanceCallBack<S> callback) const {
  S min_dist = std::numeric_limits<S>::max();
  const auto make = [&](const Probe& p, const Record& r, S d) {
    return probes_first ? Candidate{d, p.order, r.order, p.object, r.object}
                        : Candidate{d, r.order, p.order, r.object, p.object};
  };
  const auto wanted = [&](const Probe& p, const Record& r) {
    return r.object != p.object && (!self || p.order < r.order);
  };

  // The span of everything boxed, and the pairs with an object apart.
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -lo[a];
  }
  std::size_t boxed = 0;
  const auto grow = [&](const ::fcl::AABB<S>& b) {
    Shape s;
    if (!box_around(b, 0.0, s)) return false;
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<double>(b.min_[a]));
      hi[a] = std::max(hi[a], static_cast<double>(b.max_[a]));
    }
    ++boxed;
    return true;
  };
  std::vector<Candidate> apart_pairs;
  std::vector<char> probe_boxed(probes.size());
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const Probe& p = probes[i];
    probe_boxed[i] = grow(p.box);
    if (!probe_boxed[i]) {
      for (const Record& r : records_)
        if (r.object != nullptr && wanted(p, r))
          apart_pairs.push_back(make(p, r, r.box.distance(p.box)));
    } else {
      for (const std::uint32_t slot : apart_) {
        const Record& r = records_[slot];
        if (wanted(p, r)) apart_pairs.push_back(make(p, r, r.box.distance(p.box)));
      }
    }
  }
  for (const Record& r : records_)
    if (r.object != nullptr && r.apart == kNone) grow(r.box);
  std::sort(apart_pairs.begin(), apart_pairs.end());
  double span = 0;
  for (int a = 0; a < 3; ++a) span = std::max(span, boxed > 0 ? hi[a] - lo[a] : 0.0);
  double first_reach = span / std::cbrt(static_cast<double>(std::max<std::size_t>(boxed, 1)));
  if (!(first_reach > 0x1p-500)) first_reach = span;

  std::size_t next_apart = 0;
  std::vector<Candidate> phase;
  double prev = -1, reach = 0;
  for (;;) {
    phase.clear();
    const auto in_phase = [&](S d) {
      const double dd = static_cast<double>(d);
      return dd > prev && dd <= reach;
    };
    for (std::size_t i = 0; i < probes.size(); ++i) {
      if (!probe_boxed[i]) continue;
      const Probe& p = probes[i];
      Shape shape;
      box_around(p.box, reach + reach * kReachSlack, shape);
      structure_->query(shape, [&](Handle h) {
        const Record& r = records_[slot_of_handle_[h.index]];
        if (!wanted(p, r)) return true;
        const S d = r.box.distance(p.box);
        if (in_phase(d)) phase.push_back(make(p, r, d));
        return true;
      });
    }
    while (next_apart < apart_pairs.size() &&
           static_cast<double>(apart_pairs[next_apart].d) <= reach)
      phase.push_back(apart_pairs[next_apart++]);
    std::sort(phase.begin(), phase.end());
    for (const Candidate& c : phase)
      if (c.d < min_dist && callback(c.first, c.second, cdata, min_dist)) return;
    if (static_cast<double>(min_dist) <= reach) return;
    if (reach >= 2 * span) break;
    prev = reach;
    const double doubled = reach == 0 ? first_reach : 2 * reach;
    reach = min_dist < std::numeric_limits<S>::max() ? std::max(static_cast<double>(min_dist), prev)
                                                     : doubled;
    if (reach == prev) reach = doubled;
  }
  // Every boxed pair has been met; what is left is apart and farther.
  for (; next_apart < apart_pairs.size(); ++next_apart) {
    const Candidate& c = apart_pairs[next_apart];
    if (c.d < min_dist && callback(c.first, c.second, cdata, min_dist)) return;
  }
}

template <class S>
void FclCollisionManager<S>::distance(Object* obj, void* cdata,
                                      ::fcl::DistanceCallBack<S> callback) const {
  if (count_ == 0) return;
  distance_probes({Probe{obj, obj->getAABB(), 0, kNone}}, false, true, cdata, callback);
}

template <class S>
void FclCollisionManager<S>::distance(void* cdata, ::fcl::DistanceCallBack<S> callback) const {
  if (count_ == 0) return;
  distance_probes(own_probes(), true, true, cdata, callback);
}

template <class S>
void FclCollisionManager<S>::distance(Manager* other, void* cdata,
                                      ::fcl::DistanceCallBack<S> callback) const {
  if (other == this) {
    distance(cdata, callback);
    return;
  }
  if (count_ == 0 || other->size() == 0) return;
  if (const auto* ours = dynamic_cast<const FclCollisionManager*>(other);
      ours != nullptr && ours->size() > size()) {
    ours->distance_probes(own_probes(), false, true, cdata, callback);
    return;
  }
  std::vector<Object*> objs;
  other->getObjects(objs);
  std::vector<Probe> probes;
  probes.reserve(objs.size());
  for (Object* o : objs) probes.push_back({o, o->getAABB(), 0, kNone});
  if (const auto* ours = dynamic_cast<const FclCollisionManager*>(other))
    for (Probe& p : probes) p.box = ours->records_[ours->slot_of_.at(p.object)].box;
  distance_probes(probes, false, false, cdata, callback);
}

template <class S>
void FclCollisionManager<S>::validate() const {
  const auto fail = [](const std::string& what) {
    throw std::logic_error("broadphase::FclCollisionManager: " + what);
  };
  std::size_t live = 0, boxed = 0;
  for (std::uint32_t slot = 0; slot < records_.size(); ++slot) {
    const Record& r = records_[slot];
    if (r.object == nullptr) continue;
    ++live;
    const auto it = slot_of_.find(r.object);
    if (it == slot_of_.end() || it->second != slot)
      fail("slot " + std::to_string(slot) + " is not its object's slot");
    Shape shape;
    const bool can_box = box_around(r.box, 0.0, shape);
    if (r.handle.is_null()) {
      if (can_box) fail("slot " + std::to_string(slot) + " is kept apart but could be boxed");
      if (r.apart >= apart_.size() || apart_[r.apart] != slot)
        fail("slot " + std::to_string(slot) + " is missing from the objects kept apart");
      continue;
    }
    ++boxed;
    if (!can_box) fail("slot " + std::to_string(slot) + " is boxed but should be kept apart");
    if (!structure_->contains(r.handle) || structure_->user_data(r.handle) != slot ||
        slot_of_handle_.at(r.handle.index) != slot)
      fail("slot " + std::to_string(slot) + " and its structure handle disagree");
    if (!(structure_->shape(r.handle) == shape))
      fail("slot " + std::to_string(slot) + " has a stale box in the structure");
    const Hot& h = hot_[r.handle.index];
    if (h.object != r.object || h.order != r.order || !same_box(h.box, r.box))
      fail("slot " + std::to_string(slot) + " and its collide copy disagree");
    if (is_fixed(r.handle) == r.moving)
      fail("slot " + std::to_string(slot) + " is marked " + (r.moving ? "fixed" : "moving"));
  }
  if (fixed_complete_ && !fixed_dropped_) {
    // The cached pairs: every pair of fixed objects whose AABBs overlap,
    // once, earlier-registered first.
    std::vector<HandlePair> pairs;
    structure_->find_pairs(pairs);
    std::size_t expected = 0;
    for (const HandlePair& hp : pairs)
      if (is_fixed(hp.a) && is_fixed(hp.b) &&
          fcl_overlap(records_[slot_of_handle_[hp.a.index]].box,
                      records_[slot_of_handle_[hp.b.index]].box))
        ++expected;
    if (expected != fixed_pairs_.size())
      fail("the cache holds " + std::to_string(fixed_pairs_.size()) + " pairs of fixed objects, " +
           std::to_string(expected) + " expected");
    for (std::size_t i = 0; i < fixed_pairs_.size(); ++i) {
      const auto a = slot_of_.find(fixed_pairs_[i].first);
      const auto b = slot_of_.find(fixed_pairs_[i].second);
      if (a == slot_of_.end() || b == slot_of_.end()) fail("a cached pair names an unknown object");
      const Record& ra = records_[a->second];
      const Record& rb = records_[b->second];
      if (ra.moving || rb.moving || ra.handle.is_null() || rb.handle.is_null() ||
          !(ra.order < rb.order) || !fcl_overlap(ra.box, rb.box) ||
          fixed_pair_index_[i] != std::pair{ra.handle.index, rb.handle.index})
        fail("cached pair " + std::to_string(i) + " is not a pair of fixed objects in order");
    }
  }
  if (live != count_ || live != slot_of_.size())
    fail("object count " + std::to_string(count_) + ", records " + std::to_string(live));
  if (boxed != structure_->size() || boxed + apart_.size() != live)
    fail("structure holds " + std::to_string(structure_->size()) + " objects, expected " +
         std::to_string(boxed));
  structure_->validate();
}

template class FclCollisionManager<double>;
template class FclCollisionManager<float>;

}  // namespace broadphase
