/// \file arrays.hpp
/// The lean path: overlapping pairs over the caller's own arrays.
///
/// The handle API (`structure.hpp`) copies every object into the structure,
/// which then owns its shape and user data. Codes that keep their objects in
/// arrays of their own (particle and DEM codes, numpy, an engine's body pool,
/// an MPI rank's local block) do not want that copy: this header finds pairs
/// by reading the caller's arrays in place, and keeps only its own index
/// between calls. Results are the caller's indices.
///
/// Exact by the same contract as every structure: a pair (i, j) is reported
/// exactly when `overlaps()` of geometry.hpp holds for the two objects as
/// read in double (a float is widened exactly), touching counts, each pair
/// once, with i < j (bipartite calls: i indexes the first set, j the second).
///
/// Thread safety: the free functions are reentrant and may run concurrently
/// on any arrays. A `PairTracker` is used by one thread at a time (its calls
/// mutate its index); distinct trackers are independent. No call writes to
/// the caller's arrays; the arrays must not change during a call.
#pragma once

#include <broadphase/config_error.hpp>
#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

/// Everything here is in `broadphase::arrays`; the names are also declared
/// in `broadphase` itself, where code written before the lean path had a
/// namespace of its own finds them.
namespace broadphase::arrays {

/// The number type of a column of the caller's data.
enum class Real : std::uint8_t { f64, f32 };

/// One number per object, read in place from the caller's memory:
/// object i's value is at `data + i * stride` (bytes), of type `type`.
/// A stride of 0 gives every object the same value (a scalar radius).
/// Array-of-structs and struct-of-arrays layouts are both columns with
/// different strides.
struct Column {
  const void* data = nullptr;
  std::ptrdiff_t stride = 0;
  Real type = Real::f64;

  /// Object i's value, widened exactly to double.
  double at(std::size_t i) const {
    const auto* p =
        static_cast<const unsigned char*>(data) + static_cast<std::ptrdiff_t>(i) * stride;
    if (type == Real::f64) {
      double v;
      std::memcpy(&v, p, sizeof v);
      return v;
    }
    float v;
    std::memcpy(&v, p, sizeof v);
    return static_cast<double>(v);
  }
  bool empty() const { return data == nullptr; }

  /// A dense column of `T` with `stride_elems` elements between objects.
  template <class T>
  static Column of(const T* p, std::ptrdiff_t stride_elems = 1) {
    static_assert(std::is_same_v<T, double> || std::is_same_v<T, float>);
    return {p, stride_elems * static_cast<std::ptrdiff_t>(sizeof(T)),
            std::is_same_v<T, double> ? Real::f64 : Real::f32};
  }
};

/// A borrowed set of objects: centres plus, per object, a sphere radius or
/// box half-extents, all read from the caller's memory. Nothing is copied;
/// the memory must outlive every call that reads it.
///
/// Kinds: with `kind` empty, every object is a sphere when `radius` is set,
/// else a box. With `kind` set, byte `kind[i * kind_stride]` is 0 for a
/// sphere (its `radius` is read) and 1 for a box (its `half_*` are read).
struct Objects {
  std::size_t count = 0;
  Column x, y, z;                 ///< centre coordinates
  Column radius;                  ///< sphere radius (stride 0: one for all)
  Column half_x, half_y, half_z;  ///< box half-extents
  const std::uint8_t* kind = nullptr;
  std::ptrdiff_t kind_stride = 1;
  /// Collision filters, optional: object i's group bits `groups[i]` and
  /// mask bits `masks[i]` (Filter, geometry.hpp: i and j pair only when
  /// `groups[i] & masks[j]` and `groups[j] & masks[i]` are both non-zero).
  /// Both empty (the default): no filters. Otherwise both hold `count`
  /// values (InvalidObjects). Read on every call, at the hand-over of the
  /// pairs: a tracker's caller may change them between calls without
  /// listing the objects as changed.
  std::span<const std::uint32_t> groups, masks;

  /// Spheres, centres as n×3 rows (`xyz[3i + a]`), radii one per object
  /// (or `radius_stride` 0 for one radius shared by all).
  template <class T>
  static Objects spheres(const T* xyz, const T* radii, std::size_t n,
                         std::ptrdiff_t radius_stride = 1) {
    Objects o;
    o.count = n;
    o.x = Column::of(xyz, 3);
    o.y = Column::of(xyz + 1, 3);
    o.z = Column::of(xyz + 2, 3);
    o.radius = Column::of(radii, radius_stride);
    return o;
  }
  /// Boxes, centres and half-extents as n×3 rows.
  template <class T>
  static Objects boxes(const T* center_xyz, const T* half_xyz, std::size_t n) {
    Objects o;
    o.count = n;
    o.x = Column::of(center_xyz, 3);
    o.y = Column::of(center_xyz + 1, 3);
    o.z = Column::of(center_xyz + 2, 3);
    o.half_x = Column::of(half_xyz, 3);
    o.half_y = Column::of(half_xyz + 1, 3);
    o.half_z = Column::of(half_xyz + 2, 3);
    return o;
  }

  bool is_sphere(std::size_t i) const {
    if (kind != nullptr) return kind[static_cast<std::ptrdiff_t>(i) * kind_stride] == 0;
    return !radius.empty();
  }
  /// Object i as a Shape (no validity check: see `check_objects`).
  Shape shape(std::size_t i) const {
    const Vec3 c{x.at(i), y.at(i), z.at(i)};
    if (is_sphere(i)) return Shape::sphere(c, radius.at(i));
    return Shape::box(c, {half_x.at(i), half_y.at(i), half_z.at(i)});
  }
};

/// Thrown for unusable input: a NaN or infinite coordinate, a negative or
/// non-finite radius or half-extent, a missing column, an unknown kind byte,
/// more objects than 32-bit indices can name. `index` is the first bad
/// object (or SIZE_MAX when the error is not about one object).
class InvalidObjects : public std::invalid_argument {
 public:
  InvalidObjects(const std::string& what, std::size_t index)
      : std::invalid_argument(what), index_(index) {}
  std::size_t index() const { return index_; }

 private:
  std::size_t index_;
};

/// Checks every value the calls will read; throws InvalidObjects naming
/// the first bad object and what is wrong with it. Every call below runs it
/// on its input before it reads anything else (measured at 0.3 ms CPU for
/// 102 400 spheres in double columns, about 3 ns per object: docs/arrays.md);
/// a PairTracker call in movers mode, which reads only the objects listed
/// as changed (and others unchanged since it checked them), checks those.
void check_objects(const Objects& objects, const char* what = "objects");

/// Two indices of the caller's objects: i < j within one set; for the
/// bipartite calls, i in the first set and j in the second.
struct IndexPair {
  std::uint32_t i, j;
  friend constexpr bool operator==(const IndexPair&, const IndexPair&) = default;
};

/// Where pairs go. Pairs are handed over in chunks, in one deterministic
/// order that does not depend on the thread count; a chunk is valid only
/// during the call. Return false to stop early.
using PairSink = std::function<bool(std::span<const IndexPair>)>;

/// Options of the one-shot calls and the tracker.
struct ArrayOptions {
  /// The most threads a call takes (`threads`).
  static constexpr unsigned kMaxThreads = 1024;
  /// Threads to use; 1 runs on the calling thread, 0 uses every core. The
  /// pairs and their order are the same for every thread count.
  unsigned threads = 1;
  /// Verlet skin of the tracker, relative to the typical object size (the
  /// median largest half-extent at the last rebuild): an object's
  /// candidates are kept while it stays within the skin of where it was
  /// last placed; one that leaves is renewed alone. 0 picks the default,
  /// 0.25 (docs/arrays.md: larger skins renew less often but keep more
  /// candidates; 0.25 gives 71 bytes per object at scaled-even after a
  /// build), widened once to 1 when more than half of the objects a call
  /// changes leave it in that call (the index is then built again). A skin
  /// given here is kept as it is.
  double skin = 0;
  /// Sort the pairs (by i, then j) before handing them over.
  bool sorted = false;
  /// Tracker: the most bytes it keeps beyond its leanest form where they buy
  /// speed, in sets where the quiet objects overlap often (two pairs an
  /// object or more); 0 picks the default, 16 MiB. Half of it may keep the
  /// quiet pairs as they are handed over (8 bytes a pair, against 4 by
  /// their lower index), half the movers' lists of quiet candidates (a
  /// mover whose list finds no room probes the grids instead). Where the
  /// quiet pairs are few, both are kept whatever this says (a few bytes an
  /// object). Measured on one core (docs/arrays.md): study uneven 6 400
  /// takes 0.6 MB of it, and a call 0.97 -> 0.52 ms; scaled-uneven
  /// 1 024 000 has no room by default, 265 ms a call and 84 B/object;
  /// room for all took 182 ms and 163 B/object.
  std::size_t spare_bytes = 0;

  /// Throws InvalidConfig (config_error.hpp) naming the option: `skin` must
  /// be 0 (the default) or a positive finite number that is not subnormal
  /// (a NaN does not mean "default"), `threads` at most kMaxThreads. The
  /// tracker's constructor and every one-shot call check their options.
  void check() const;
};

/// What one call did, for the lab and the tests.
struct ArrayCallStats {
  std::uint64_t pairs = 0;
  std::uint64_t tests = 0;  ///< exact predicate evaluations
  bool rebuilt = false;     ///< the tracker rebuilt its index in this call
  /// Objects the tracker renewed alone in this call (they had left their
  /// fat box and got a new one, without a rebuild). In movers mode: movers
  /// that probed the quiet grids for a new list of quiet candidates (they
  /// had left the old one's reach, or had none).
  std::uint64_t renewed = 0;
  /// The tracker folded its renewed objects' candidates back into its rows
  /// (a new grid over the same fat boxes; no candidate search).
  bool compacted = false;
  /// Objects quiet after this call: unchanged for several calls that listed
  /// their changes, so their pairs with each other are handed over without
  /// a scan. A quiet object the caller changes again is renewed (woken);
  /// a call with `Changes::everything()` wakes them all.
  std::uint64_t quiet = 0;
  /// Quiet objects the caller changed in this call (renewed, whether or not
  /// they left their box; those that did count in `renewed` too).
  std::uint64_t woken = 0;
  /// The tracker found this call's pairs afresh, without an index: motion
  /// outran the skin (so many objects left their boxes that the index
  /// would be built again), and they are spheres in uncrowded cells, where
  /// a new search is several times cheaper than a build. It does the same
  /// for the next few calls, holding nothing meanwhile, then builds its
  /// index again. Also a tracker with no index yet (its first call, a new
  /// count) on such spheres, which keeps that call's cells and pairs: the
  /// next call that lists its changes then enters movers mode from them,
  /// without the index's build (one that does not builds the index).
  bool afresh = false;
  /// The tracker is in movers mode: a set of spheres most of which are
  /// quiet keeps them in grids of their own and finds the other objects'
  /// pairs on every call: among themselves afresh, and with the quiet ones
  /// from each mover's list of quiet candidates within a skin, probing the
  /// quiet grids for a new list when it leaves it; no index of the movers.
  /// `compacted` is then set on a call that partitioned anew.
  bool movers = false;
  bool stopped = false;  ///< the sink asked to stop
};

/// All overlapping pairs (i < j) of one set, streamed to `sink`.
///
/// The one-shot calls keep nothing: a call holds scratch memory of about
/// 120 to 180 bytes an object (float boxes, the grid, the shapes in the
/// grid's order), released before it returns. A set of spheres only,
/// spread over space rather than crowded into a few clusters, takes a few
/// grids of cells a diameter wide instead (one for spheres of one size),
/// about 60 bytes an object: at 1 000 000 spheres of one size 2.8
/// times faster, at 100 000 over one to three decades of radii 2.7 to 5
/// times.
ArrayCallStats find_pairs(const Objects& objects, const PairSink& sink,
                          const ArrayOptions& options = {});
/// All overlapping pairs of one set, appended to `out`.
ArrayCallStats find_pairs(const Objects& objects, std::vector<IndexPair>& out,
                          const ArrayOptions& options = {});
/// All overlapping pairs (i in `a`, j in `b`) between two sets.
ArrayCallStats find_pairs(const Objects& a, const Objects& b, const PairSink& sink,
                          const ArrayOptions& options = {});
ArrayCallStats find_pairs(const Objects& a, const Objects& b, std::vector<IndexPair>& out,
                          const ArrayOptions& options = {});
/// The indices of the objects that overlap `shape`, in increasing order.
/// Throws InvalidShape for an invalid shape.
std::vector<std::uint32_t> query(const Objects& objects, const Shape& shape);

class RayCaster;  // arrays/rays.hpp

/// Which objects changed since the tracker's last call.
struct Changes {
  /// True: any object may have moved, resized or changed kind (the tracker
  /// finds out which itself). False: only those listed in `indices` did.
  bool all = true;
  std::span<const std::uint32_t> indices;

  static Changes everything() { return {}; }
  static Changes only(std::span<const std::uint32_t> changed) { return {false, changed}; }
};

/// Pairs of one set, frame after frame. The caller moves its objects in
/// place and calls `find_pairs` again; the tracker reuses its index through
/// a skin (as Verlet lists do), renews the objects that left their skin
/// alone, and is exact however far objects moved.
///
/// Listing the changes pays: after two calls in a row with
/// `Changes::only`, the objects not listed become quiet, and the pairs
/// among quiet objects are handed over as they stand instead of being
/// tested (ArrayCallStats::quiet). A `Changes::everything()` call then
/// wakes them all (a rebuild when they are many), so a caller that can
/// list its changes should do so on every call.
///
/// Growing and shrinking: a call may see more objects than the last one
/// (appended at the end) or fewer (those past the new count are gone);
/// a caller that removes object k by moving the last one into its place
/// lists k as changed. With `Changes::only`, an index whose object was
/// removed and another appended in its place since the last call (the
/// count alone does not show it) is listed as changed too.
class PairTracker {
 public:
  explicit PairTracker(const ArrayOptions& options = {});
  ~PairTracker();
  PairTracker(PairTracker&&) noexcept;
  PairTracker& operator=(PairTracker&&) noexcept;

  /// All overlapping pairs (i < j) of `objects` as they are now.
  /// Throws InvalidObjects (the tracker is then as before the call).
  ArrayCallStats find_pairs(const Objects& objects, const PairSink& sink,
                            const Changes& changes = Changes::everything());
  ArrayCallStats find_pairs(const Objects& objects, std::vector<IndexPair>& out,
                            const Changes& changes = Changes::everything());

  /// Rays into the objects as the last `find_pairs` call saw them (pass
  /// the same arrays): a RayCaster (arrays/rays.hpp) built at the first ask
  /// after that call and used until the next, so that a frame's rays share
  /// one build (its memory, about 66 bytes an object once a ray was cast,
  /// is kept for the next build and counted in memory_bytes). Its casts may
  /// run concurrently; this call may not run with them. Throws
  /// InvalidObjects, or std::invalid_argument when the count is not the
  /// last call's.
  const RayCaster& ray_caster(const Objects& objects);

  /// Bytes the tracker keeps between calls (its index and candidate lists;
  /// the caller's arrays and output excluded).
  std::size_t memory_bytes() const;
  /// Forgets everything; the next call rebuilds.
  void clear();
  /// Checks the tracker's invariants against `objects` (the arrays of the
  /// last call); throws std::logic_error naming the first that fails.
  void validate(const Objects& objects) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Scratch memory. A call's own arrays of 2 MiB and more are, once the
/// call is done with them, kept for the next call (at most the limit in
/// all, each for at most 2 seconds, returned at a later call): their pages
/// are then in place, where fresh ones are cleared by the kernel on first
/// touch. Not counted in PairTracker::memory_bytes; reported here.
/// Thread-safe.
///
/// Bytes kept now.
std::size_t scratch_bytes();
/// The most bytes kept (512 MiB unless set); 0 keeps nothing. Setting it
/// returns at once what is kept beyond it.
void set_scratch_limit(std::size_t bytes);
std::size_t scratch_limit();

}  // namespace broadphase::arrays

namespace broadphase {
using arrays::ArrayCallStats;
using arrays::ArrayOptions;
using arrays::Changes;
using arrays::check_objects;
using arrays::Column;
using arrays::find_pairs;
using arrays::IndexPair;
using arrays::InvalidObjects;
using arrays::Objects;
using arrays::PairSink;
using arrays::PairTracker;
using arrays::query;
using arrays::Real;
using arrays::scratch_bytes;
using arrays::scratch_limit;
using arrays::set_scratch_limit;
}  // namespace broadphase
