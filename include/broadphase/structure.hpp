/// \file structure.hpp
/// The one interface every structure implements, as a compile-time concept
/// for the hot paths and as a type-erased class for the CLI and the lab.
///
/// Reading and writing are separate: `query`, `for_each_pair`, `size`,
/// `memory_bytes` and `validate` are const and may run concurrently with each
/// other; `insert`, `remove`, `update` mutate and need exclusive access.
/// Mutations are complete when they return: no structure defers work to the
/// next query.
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <broadphase/ray.hpp>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace broadphase {

/// How an object is expected to move. A hint only: every structure stays
/// exact when a `fixed` object is updated, it may just cost more.
enum class Motion : std::uint8_t {
  dynamic,  ///< updated often (the study's moving 20%)
  fixed,    ///< rarely or never updated (the study's static 80%)
};

/// What a query or an all-pairs pass cost. `tests` counts exact narrow-phase
/// predicate evaluations (the study's "narrow-phase tests"); `stopped` is
/// true when the visitor asked to stop early.
struct QueryCost {
  std::uint64_t tests = 0;
  bool stopped = false;
};

/// Two objects that overlap. The order inside a pair is unspecified.
struct HandlePair {
  Handle a, b;
};

/// One object's new shape, for bulk updates.
///
/// A bulk update (`update(std::span<const Move>)`) is all-or-nothing: every
/// move is checked (live handle, valid shape) before any is applied, so a
/// batch that throws InvalidHandle or InvalidShape leaves the structure
/// exactly as it was. A handle named more than once in one batch ends with
/// its last move's shape, as if the moves were applied in order; every
/// structure gives that meaning.
struct Move {
  Handle handle;
  Shape shape;
};

/// Checks a whole batch of moves against structure `s` before any of it is
/// applied: throws InvalidHandle for the first move whose handle `s` does
/// not hold and InvalidShape for the first invalid shape, in batch order.
/// O(batch); every bulk update calls it first (a failed move half-way
/// through a batch would otherwise leave the moves before it applied, or,
/// in a structure that rebuilds once per batch, leave it inconsistent).
template <class S>
void check_moves(const S& s, std::span<const Move> moves) {
  for (const Move& m : moves) {
    if (!s.contains(m.handle)) throw InvalidHandle(m.handle);
    require_valid(m.shape);
  }
}

/// A structure's options as text, `key` -> `value`: what a registry spec
/// (`octree:split=16`) or the deprecated Config::options gives; each
/// structure's `Options::from` reads it into its typed options struct.
using OptionText = std::map<std::string, std::string>;

/// Options common to all structures. Every field has a sensible default.
struct Config {
  /// The region most objects live in. A hint for structures that subdivide
  /// a box (octrees, dense grids): objects outside it are still handled
  /// exactly, at some cost. Must be non-empty with finite corners and a
  /// finite width on each axis (check_config in config_error.hpp).
  Aabb world{{0, 0, 0}, {1000, 1000, 1000}};
  /// How many objects the caller expects; sizes tables up front. 0: grow.
  std::size_t expected_objects = 0;
  /// Deprecated: give a structure's options typed instead, as its options
  /// struct (`Octree(config, OctreeOptions{.split = 16})`), or by name
  /// through the registry (`make_structure("octree:split=16")`, which parses
  /// the spec straight into the options struct). Still accepted from old
  /// callers, as `key=value` text, by the registry and by every constructor
  /// that takes a Config alone: read once into the typed options, rejecting
  /// keys the structure does not know (InvalidConfig).
  OptionText options;
};

/// Calls a visitor and tells whether to continue: a visitor may return bool
/// (false stops the traversal) or nothing (never stops).
template <class V, class... Args>
inline bool visit(V& v, Args&&... args) {
  if constexpr (std::is_void_v<std::invoke_result_t<V&, Args...>>) {
    v(std::forward<Args>(args)...);
    return true;
  } else {
    return static_cast<bool>(v(std::forward<Args>(args)...));
  }
}

/// What every structure provides. Query visitors take `(Handle)`, pair
/// visitors `(Handle, Handle)`; both may return bool to stop early. A shape
/// given to insert, update or query must be valid (`is_valid`), or the call
/// throws InvalidShape and changes nothing; a stale handle throws
/// InvalidHandle.
///
/// Optional members, used when present (Erased and the callers below check
/// with `requires`): a bulk `update(std::span<const Move>)`, `find_pairs`,
/// `visit_cells`, and `settle()` (HasSettle).
template <class S>
concept Structure = requires(S& s, const S& cs, const Shape& shape, Handle h, std::uint64_t user,
                             bool (*qv)(Handle), bool (*pv)(Handle, Handle)) {
  { s.insert(shape, user, Motion::dynamic) } -> std::same_as<Handle>;
  s.remove(h);
  s.update(h, shape);
  { cs.query(shape, qv) } -> std::same_as<QueryCost>;
  { cs.for_each_pair(pv) } -> std::same_as<QueryCost>;
  { cs.size() } -> std::convertible_to<std::size_t>;
  { cs.memory_bytes() } -> std::convertible_to<std::size_t>;
  { cs.contains(h) } -> std::same_as<bool>;
  { cs.shape(h) } -> std::convertible_to<Shape>;
  { cs.user_data(h) } -> std::same_as<std::uint64_t>;
  cs.validate();
};

/// A structure with a commit step: `settle()` ends a batch of single
/// inserts and updates (after a scene is loaded, or after a frame's moves)
/// and puts the structure in the state a frame is fastest in. Optional: a
/// structure whose mutations leave nothing to commit need not have it (the
/// library's structures inherit a no-op from detail::StructureBase), and
/// callers use settle_structure(), which does nothing for them. Results
/// never depend on it: every query is exact before and after.
template <class S>
concept HasSettle = requires(S& s) {
  s.settle();
};

/// The user's pair filter, applied after the group/mask bits (Filter): false
/// means "these two never pair" (a joint, a ragdoll's own parts). It must be
/// symmetric, pure and safe to call from several threads at once (a
/// structure on several threads calls it from each).
using PairFilter = std::function<bool(Handle, Handle)>;

/// A structure with collision filters: `set_filter(h, f)` changes an
/// object's group and mask (InvalidHandle for a stale handle), `filter(h)`
/// reads them, `set_pair_filter(pf)` installs (or, empty, removes) the pair
/// filter. Pairs that fail either are never reported nor cached: the rule is
/// applied inside the structure, before a pair is reported.
template <class S>
concept HasFilters = requires(S& s, const S& cs, Handle h, Filter f, PairFilter pf) {
  s.set_filter(h, f);
  { cs.filter(h) } -> std::same_as<Filter>;
  s.set_pair_filter(pf);
};

/// A structure that casts rays: `cast_ray(ray, visitor)` reports every
/// object the ray sees (Ray::mask) and hits by the contract's evaluation
/// (ray.hpp), each once with its t, to a visitor `(Handle, double t)` that
/// may clip or stop the cast (kRayGoOn, kStopRay). Throws InvalidRay.
template <class S>
concept HasRayCast = requires(const S& cs, const Ray& r, double (*v)(Handle, double)) {
  { cs.cast_ray(r, v) } -> std::same_as<QueryCost>;
};

/// The closest hit of `r` in `s` (smallest t, then smallest slot index), or
/// a null handle when there is none. Throws InvalidRay.
template <HasRayCast S>
RayHit closest_hit(const S& s, const Ray& r) {
  ClosestHit v;
  s.cast_ray(r, v);
  return v.best;
}

/// True when `r` hits anything in `s`; stops at the first hit found.
template <HasRayCast S>
bool any_hit(const S& s, const Ray& r) {
  bool hit = false;
  s.cast_ray(r, [&](Handle, double) {
    hit = true;
    return kStopRay;
  });
  return hit;
}

/// Calls `s.settle()` when S has it; otherwise does nothing.
template <class S>
void settle_structure(S& s) {
  if constexpr (HasSettle<S>) s.settle();
}

/// A non-owning reference to a callable, cheaper than std::function: one
/// indirect call, no allocation. The referenced callable must outlive it.
template <class Sig>
class FunctionRef;

template <class R, class... Args>
class FunctionRef<R(Args...)> {
 public:
  template <class F>
  requires(!std::is_same_v<std::remove_cvref_t<F>, FunctionRef> &&
           std::is_invocable_r_v<R, F&, Args...>)
      FunctionRef(F&& f)  // NOLINT(google-explicit-constructor): a reference wrapper
      : obj_(const_cast<void*>(static_cast<const void*>(std::addressof(f)))),
        call_([](void* o, Args... a) -> R {
          return static_cast<R>(
              (*static_cast<std::remove_reference_t<F>*>(o))(std::forward<Args>(a)...));
        }) {}
  R operator()(Args... a) const { return call_(obj_, std::forward<Args>(a)...); }

 private:
  void* obj_;
  R (*call_)(void*, Args...);
};

/// Receives one cell or node of a structure, for pictures and checks:
/// its box, its level (the depth in a tree, the level in a hierarchy of
/// grids, 0 in a single grid) and how many objects it holds itself (an
/// object a grid enters into several cells counts in each; inner nodes of a
/// tree that hold none are reported too, with 0). Objects a structure keeps
/// outside every cell (an overflow list) are in no cell.
using CellVisitor = FunctionRef<void(const Aabb& box, int level, std::size_t objects)>;

/// The type-erased face of a structure: one virtual call per operation or
/// query, never per node. Used by the CLI, the lab and the tests to handle
/// all structures alike. Same thread-safety as the structure it wraps.
class AnyBroadPhase {
 public:
  virtual ~AnyBroadPhase() = default;

  /// Adds an object; returns its handle. Throws InvalidShape.
  virtual Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic) = 0;
  /// Removes an object; its handle becomes stale. Throws InvalidHandle.
  virtual void remove(Handle h) = 0;
  /// Moves and/or resizes an object. Throws InvalidHandle, InvalidShape.
  virtual void update(Handle h, const Shape& s) = 0;
  /// Updates many objects at once (some structures rebuild once per batch).
  /// All-or-nothing: throws InvalidHandle or InvalidShape, changing nothing,
  /// when any move is bad; a handle named twice takes its last move (Move).
  virtual void update(std::span<const Move> moves) = 0;
  /// Commits a batch of single inserts and updates, after a scene is loaded
  /// or after a frame's moves (HasSettle); a no-op for structures without
  /// a commit step. Call it instead of an empty bulk update.
  virtual void settle() {}
  /// Adds an object with a collision filter. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m, Filter f) {
    const Handle h = insert(s, user, m);
    if (!(f == Filter{})) set_filter(h, f);
    return h;
  }
  /// Changes an object's collision filter (HasFilters). Throws InvalidHandle.
  virtual void set_filter(Handle h, Filter f) = 0;
  /// An object's collision filter. Throws InvalidHandle.
  virtual Filter filter(Handle h) const = 0;
  /// Installs the pair filter (PairFilter), or removes it when empty.
  virtual void set_pair_filter(PairFilter pf) = 0;
  /// True when objects `a` and `b` may pair: their filters pass, and so
  /// does the pair filter. Throws InvalidHandle.
  virtual bool pair_passes(Handle a, Handle b) const = 0;
  /// Visits every object whose shape overlaps `s` exactly.
  virtual QueryCost query(const Shape& s, FunctionRef<bool(Handle)> visitor) const = 0;
  /// Casts a ray (HasRayCast): every hit to `visitor`, which returns the
  /// ray's new tmax (kRayGoOn, a clip, or kStopRay). Throws InvalidRay.
  virtual QueryCost cast_ray(const Ray& r, FunctionRef<double(Handle, double)> visitor) const = 0;
  /// The closest hit (smallest t, then smallest slot index); a null handle
  /// when the ray hits nothing. Throws InvalidRay.
  RayHit closest_hit(const Ray& r) const {
    ClosestHit v;
    cast_ray(r, v);
    return v.best;
  }
  /// The closest hit of each ray into `out`, which must be as long as
  /// `rays` (std::invalid_argument): closest_hit(rays[i]) bit for bit, on
  /// the calling thread (cast_rays shares a batch among threads). A
  /// structure may walk several rays at once (KdTree::closest_hits). Throws
  /// InvalidRay, naming the first invalid ray, before casting any.
  virtual void closest_hits(std::span<const Ray> rays, std::span<RayHit> out) const {
    detail::require_valid_batch(rays, out.size(), "closest_hits");
    for (std::size_t i = 0; i < rays.size(); ++i) out[i] = closest_hit(rays[i]);
  }
  /// True when the ray hits anything; stops at the first hit found.
  bool any_hit(const Ray& r) const {
    bool hit = false;
    cast_ray(r, [&](Handle, double) {
      hit = true;
      return kStopRay;
    });
    return hit;
  }
  /// Visits every overlapping pair once.
  virtual QueryCost for_each_pair(FunctionRef<bool(Handle, Handle)> visitor) const = 0;
  /// Appends every overlapping pair once to `out` (no per-pair virtual call).
  virtual QueryCost find_pairs(std::vector<HandlePair>& out) const = 0;

  virtual std::size_t size() const = 0;
  /// Bytes of memory the structure holds (capacities, not sizes).
  virtual std::size_t memory_bytes() const = 0;
  virtual bool contains(Handle h) const = 0;
  virtual Shape shape(Handle h) const = 0;
  virtual std::uint64_t user_data(Handle h) const = 0;
  /// Checks the structure's invariants; throws std::logic_error naming the
  /// first one that fails.
  virtual void validate() const = 0;
  /// Reports the structure's cells or nodes as built (`visit_cells` of the
  /// structure, when it has one); false, visiting nothing, when it has none.
  virtual bool visit_cells(CellVisitor visitor) const {
    (void)visitor;
    return false;
  }
};

/// Wraps a concrete structure behind AnyBroadPhase.
template <Structure S>
class Erased final : public AnyBroadPhase {
 public:
  template <class... A>
  explicit Erased(A&&... a) : s_(std::forward<A>(a)...) {}

  Handle insert(const Shape& s, std::uint64_t user, Motion m) override {
    return s_.insert(s, user, m);
  }
  void remove(Handle h) override { s_.remove(h); }
  void update(Handle h, const Shape& s) override { s_.update(h, s); }
  void update(std::span<const Move> moves) override {
    if constexpr (requires { s_.update(moves); }) {
      s_.update(moves);  // checks the batch itself
    } else {
      check_moves(s_, moves);  // all-or-nothing: nothing below can fail on input
      for (const Move& m : moves) s_.update(m.handle, m.shape);
    }
  }
  void settle() override { settle_structure(s_); }
  using AnyBroadPhase::insert;
  void set_filter(Handle h, Filter f) override { s_.set_filter(h, f); }
  Filter filter(Handle h) const override { return s_.filter(h); }
  void set_pair_filter(PairFilter pf) override { s_.set_pair_filter(std::move(pf)); }
  bool pair_passes(Handle a, Handle b) const override {
    if constexpr (requires { s_.pair_passes(a, b); }) {
      return s_.pair_passes(a, b);
    } else {
      return filters_pass(s_.filter(a), s_.filter(b));
    }
  }
  QueryCost query(const Shape& s, FunctionRef<bool(Handle)> v) const override {
    return s_.query(s, v);
  }
  QueryCost cast_ray(const Ray& r, FunctionRef<double(Handle, double)> v) const override {
    return s_.cast_ray(r, v);
  }
  void closest_hits(std::span<const Ray> rays, std::span<RayHit> out) const override {
    if constexpr (requires { s_.closest_hits(rays, out); })
      s_.closest_hits(rays, out);
    else
      AnyBroadPhase::closest_hits(rays, out);
  }
  QueryCost for_each_pair(FunctionRef<bool(Handle, Handle)> v) const override {
    return s_.for_each_pair(v);
  }
  QueryCost find_pairs(std::vector<HandlePair>& out) const override {
    if constexpr (requires { s_.find_pairs(out); }) {
      return s_.find_pairs(out);
    } else {
      return s_.for_each_pair([&out](Handle a, Handle b) { out.push_back({a, b}); });
    }
  }
  std::size_t size() const override { return s_.size(); }
  std::size_t memory_bytes() const override { return s_.memory_bytes(); }
  bool contains(Handle h) const override { return s_.contains(h); }
  Shape shape(Handle h) const override { return s_.shape(h); }
  std::uint64_t user_data(Handle h) const override { return s_.user_data(h); }
  void validate() const override { s_.validate(); }
  bool visit_cells(CellVisitor v) const override {
    if constexpr (requires { s_.visit_cells(v); }) {
      s_.visit_cells(v);
      return true;
    } else {
      return false;
    }
  }

  S& get() { return s_; }
  const S& get() const { return s_; }

 private:
  S s_;
};

}  // namespace broadphase
