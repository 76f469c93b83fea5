/// \file fcl.hpp
/// `broadphase::fcl`: an FCL broad-phase manager backed by any structure of
/// `broadphase list`, for programs that collide through FCL 0.7's
/// `fcl::BroadPhaseCollisionManager` (MoveIt, most of ROS). The one-line
/// change:
///
///     auto manager = std::make_shared<fcl::DynamicAABBTreeCollisionManagerd>();
///     auto manager = std::make_shared<broadphase::FclCollisionManagerd>();
///
/// What it reports. Every FCL manager tests the AABBs of its objects with
/// FCL's own inclusive `AABB::overlap` (touching boxes pair) and hands each
/// overlapping pair to the user's callback once; this one does the same,
/// with the same predicate on the same AABBs (FCL's own function is called
/// on every candidate, so the result is FCL's bit for bit, in float as in
/// double). The structure only culls: each object enters it as a box a
/// little larger than its FCL AABB (kBoundsSlack), so the structure's pairs
/// are a superset of FCL's. Like FCL's tree, a collide tests the AABBs as
/// they were at the object's registration or last `update`, and
/// `collide(obj)` and `distance(obj)` the query object's current AABB.
/// Objects whose AABB is not finite, is inverted, or reaches beyond 2^1000
/// (FCL's planes and half-spaces span ±max) are kept apart and tested
/// against every object, with the same predicate.
///
/// Callbacks follow FCL's contract: a callback returning true stops the
/// search at once; `cdata` is passed through unchanged. Argument order: a
/// self pair comes earlier-registered object first (NaiveCollisionManager's
/// order); `collide(obj)` and `distance(obj)` pass the query first and skip
/// the query object itself when it is registered (SaP's and spatial
/// hashing's behaviour; FCL's tree passes it second and also reports the
/// object with itself); against another manager, this manager's object
/// first (all of FCL's managers).
///
/// Distance is exact, by an expanding search: pairs whose AABBs touch
/// first, then pairs within a reach that doubles until the callback has
/// lowered `dist` below it, then every pair with an AABB distance below
/// `dist`, each phase's pairs in increasing AABB distance. A pair is handed
/// to the callback only when FCL's `AABB::distance` is below the current
/// `dist`, as every FCL manager does; with FCL's DefaultDistanceFunction
/// the result equals NaiveCollisionManager's. A callback that never lowers
/// `dist` gets every pair, as from FCL's managers.
///
/// Thread-safety: the const calls (collide, distance, getObjects, size,
/// empty) may run concurrently with each other when the structure's const
/// calls may (every structure of the library); registration, `update`,
/// `setup` and `clear` need exclusive access. The callbacks run on the
/// calling thread.
#pragma once

#include <fcl/broadphase/broadphase_collision_manager.h>

#include <broadphase/registry.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace broadphase {

/// The structure an FclCollisionManager uses when none is named: the one
/// `broadphase advise` picks for a dynamic world (docs/performance.md).
inline constexpr std::string_view kFclDefaultStructure = "grid-verlet";

/// A `fcl::BroadPhaseCollisionManager<S>` over a structure of the library
/// (S = double or float; FCL 0.7 instantiates its own managers in double
/// only, this one is compiled for both). Registration and update: O(1)
/// amortised per object plus the structure's cost (a bulk update per
/// `update()` call), plus, at the `setup()`, `registerObjects` or `update`
/// that follows, a pass over the kept pairs among objects that never moved
/// when some left that set, or over the structure's pairs when some joined
/// it; `collide()`: those kept pairs, then the structure's pair pass and
/// one FCL AABB test per other candidate. Objects are not owned: each
/// registered object must outlive its registration.
template <class S>
class FclCollisionManager final : public ::fcl::BroadPhaseCollisionManager<S> {
 public:
  using Object = ::fcl::CollisionObject<S>;
  using Manager = ::fcl::BroadPhaseCollisionManager<S>;

  /// A manager over the structure `spec` (`broadphase list`, with options:
  /// `"sap"`, `"grid-verlet:threads=2"`), whose world hint follows the
  /// objects: at registerObjects and setup, when more than one object in
  /// sixteen lies outside the structure's world, or the world is more
  /// than 64 times the volume the objects need, the structure is made
  /// anew over the objects' bounds (grown by an eighth of their largest
  /// extent) and the objects placed again. A world that does not fit
  /// costs no pair, only time: 10^5 spheres over [0, 2500]^3 under the
  /// default world [0, 1000]^3 took 586 ms to register and set up, against
  /// 90 with their world (docs/fcl.md). Throws InvalidConfig
  /// (UnknownStructure for an unknown name).
  explicit FclCollisionManager(std::string_view spec = kFclDefaultStructure);
  /// A manager over the structure `spec` with the caller's Config, kept
  /// as given (its world is not refitted).
  FclCollisionManager(std::string_view spec, const Config& config);
  /// The Config the structure was last made with: the caller's, or, where
  /// the world follows the objects, the fitted world.
  const Config& config() const { return config_; }
  /// A manager over an empty structure the caller made. Throws
  /// std::invalid_argument when it is null or not empty.
  explicit FclCollisionManager(std::unique_ptr<AnyBroadPhase> structure);
  ~FclCollisionManager() override;
  FclCollisionManager(const FclCollisionManager&) = delete;
  FclCollisionManager& operator=(const FclCollisionManager&) = delete;

  /// Registers the objects with their current AABBs (computeAABB() must
  /// have been called, as for FCL's managers). Throws std::invalid_argument
  /// for a null object or one already registered (nothing of the batch is
  /// registered then).
  void registerObjects(const std::vector<Object*>& objs) override;
  /// Registers one object. Throws std::invalid_argument (see above).
  void registerObject(Object* obj) override;
  /// Unregisters an object; one not registered is ignored (as
  /// NaiveCollisionManager does).
  void unregisterObject(Object* obj) override;
  /// Commits the registrations (the structure's settle()) and brings the
  /// kept pairs among objects that never moved up to date; results never
  /// depend on it.
  void setup() override;
  /// Reads every object's AABB and moves those that changed: O(n) plus one
  /// bulk update of the structure.
  void update() override;
  /// Reads one object's AABB (an object not registered is ignored).
  void update(Object* updated_obj) override;
  /// Reads the AABBs of these objects, then one bulk update.
  void update(const std::vector<Object*>& updated_objs) override;
  /// Unregisters every object.
  void clear() override;
  /// The registered objects, in registration order.
  void getObjects(std::vector<Object*>& objs) const override;

  /// Every registered object whose AABB overlaps `obj`'s: callback(obj, it).
  void collide(Object* obj, void* cdata, ::fcl::CollisionCallBack<S> callback) const override;
  /// Nearest objects to `obj` by expanding search: callback(obj, it, dist).
  void distance(Object* obj, void* cdata, ::fcl::DistanceCallBack<S> callback) const override;
  /// Every pair of registered objects whose AABBs overlap, once.
  void collide(void* cdata, ::fcl::CollisionCallBack<S> callback) const override;
  /// The nearest pair of registered objects, by expanding search.
  void distance(void* cdata, ::fcl::DistanceCallBack<S> callback) const override;
  /// Every (ours, theirs) pair whose AABBs overlap; `other` may be any FCL
  /// manager (another FclCollisionManager is queried through its structure,
  /// any other through getObjects). `other == this` is a self collide.
  void collide(Manager* other, void* cdata, ::fcl::CollisionCallBack<S> callback) const override;
  /// The nearest (ours, theirs) pair, by expanding search.
  void distance(Manager* other, void* cdata, ::fcl::DistanceCallBack<S> callback) const override;

  bool empty() const override;
  std::size_t size() const override;

  /// The structure underneath (for its statistics and `validate`).
  const AnyBroadPhase& structure() const { return *structure_; }
  /// Checks the manager's records against the structure and the
  /// structure's own invariants; throws std::logic_error naming the first
  /// that fails.
  void validate() const;

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  struct Record {
    Object* object = nullptr;     ///< null: a free slot
    ::fcl::AABB<S> box;           ///< the AABB at registration or the last update
    std::uint64_t order = 0;      ///< registration order
    Handle handle;                ///< in the structure; null while kept apart
    std::uint32_t apart = kNone;  ///< index in apart_, or kNone
    bool moving = false;          ///< has moved since registration
  };
  struct Probe;
  struct Candidate;
  /// A pair of fixed objects whose AABBs overlap, in the callback's order.
  struct FixedPair {
    Object* first;
    Object* second;
  };

  std::uint32_t add(Object* obj);
  void place(std::uint32_t slot, bool moving);
  void unplace(std::uint32_t slot);
  bool refresh(std::uint32_t slot, std::vector<Move>& moves);
  void commit(std::vector<Move>& moves);
  /// Brings fixed_pairs_ up to date: drops the pairs of objects that left
  /// the fixed set, or, after a fixed object joined it, takes them anew
  /// from the structure.
  void renew_fixed_pairs();
  bool is_fixed(Handle h) const { return (fixed_bits_[h.index >> 6] >> (h.index & 63)) & 1u; }
  void mark_fixed(Handle h, bool fixed);
  template <class Visit>
  bool candidates_of(const Probe& p, double reach, Visit&& visit) const;
  bool collide_probes(const std::vector<Probe>& probes, bool probes_first, void* cdata,
                      ::fcl::CollisionCallBack<S> callback) const;
  void distance_probes(const std::vector<Probe>& probes, bool self, bool probes_first, void* cdata,
                       ::fcl::DistanceCallBack<S> callback) const;
  std::vector<Probe> own_probes() const;
  /// With fit_world_: makes the structure anew over the objects' bounds
  /// when its world does not fit them (see the constructor).
  void fit_world();
  /// Drops what is kept by structure handle (copies, fixed bits and pairs).
  void forget_handles();

  std::unique_ptr<AnyBroadPhase> structure_;
  std::string spec_;        ///< the structure's spec, when made from one
  Config config_;           ///< its Config
  bool fit_world_ = false;  ///< the world hint follows the objects
  std::vector<Record> records_;
  std::vector<std::uint32_t> free_;
  std::unordered_map<const Object*, std::uint32_t> slot_of_;
  std::vector<std::uint32_t> slot_of_handle_;  ///< structure handle index -> slot
  /// What collide reads of an object the structure names, by its handle
  /// index, in one cache line: a copy of its record's box, object and order.
  struct alignas(64) Hot {
    ::fcl::AABB<S> box;
    Object* object;
    std::uint64_t order;
  };
  std::vector<Hot> hot_;
  /// Where an object's AABB lies from its start (FCL's CollisionObject
  /// member), for fetching it ahead without a call into libfcl per object:
  /// read at every registration. A fetch of a wrong address costs nothing
  /// and is never read.
  std::ptrdiff_t aabb_offset_ = 0;
  const char* aabb_of(const Object* o) const {
    return reinterpret_cast<const char*>(o) + aabb_offset_;
  }
  std::vector<std::uint32_t> apart_;  ///< slots of the objects kept apart
  /// Per position of the last update(objects) list, the slot it named.
  std::vector<std::uint32_t> update_slots_;
  std::size_t count_ = 0;
  std::uint64_t next_order_ = 0;
  bool replaced_ = false;  ///< an update re-inserted an object: settle()
  // The pairs among objects that never moved (fixed in the structure) whose
  // AABBs overlap, tested once: a collide hands them to the callback
  // straight from this list and skips them among the structure's pairs.
  std::vector<FixedPair> fixed_pairs_;
  /// Per fixed pair, its objects' structure handle indices: what a removal
  /// or a first move drops the pair by.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> fixed_pair_index_;
  std::vector<std::uint64_t> fixed_bits_;  ///< structure handle index -> fixed (a bit)
  bool fixed_complete_ = true;             ///< fixed_pairs_ holds every pair of fixed objects
  bool fixed_dropped_ = false;  ///< a fixed object left since: fixed_pairs_ holds stale pairs
};

extern template class FclCollisionManager<double>;
extern template class FclCollisionManager<float>;

using FclCollisionManagerd = FclCollisionManager<double>;
using FclCollisionManagerf = FclCollisionManager<float>;

}  // namespace broadphase
