/// \file mpi.hpp
/// Pair finding over MPI ranks: every overlapping pair of the whole world,
/// each reported exactly once, on one rank, with the caller's global ids;
/// and rays cast into that world, with the answers of one process.
///
/// Use from a user's own MPI program (plain MPI C API, any communicator):
/// each rank passes the objects it holds (global ids below 2^32, shapes of
/// geometry.hpp or a borrowed `Objects` view of arrays.hpp) and gets back
/// the pairs it is responsible for. Every call is collective: all ranks of
/// the communicator make the same calls in the same order.
///
/// How (docs/mpi.md has the measured figures):
/// - Space is split into one subdomain per rank, either a Cartesian grid
///   over the world box or a weighted recursive coordinate bisection of the
///   objects' centres. Subdomains are half-open boxes; the outermost faces
///   extend to infinity, so every point of space (objects outside the world
///   included, and infinite bounds) belongs to exactly one rank.
/// - Ghosts are sized per object: an object is sent to every rank whose
///   subdomain, grown by the margin, meets its conservative bounds
///   (`bounds()` of geometry.hpp). An object that reaches more than
///   `max_ghost_ranks` ranks goes to a shared list that every rank holds.
/// - A pair belongs to the rank whose subdomain contains the point
///   max(lo_a, lo_b) (per axis, of the two objects' bounds). That point lies
///   in both objects' bounds whenever they overlap, so both objects reach
///   that rank, and exactly one rank keeps the pair: no message, no
///   duplicate removal.
/// - Collision filters (optional groups and masks, the rule of
///   `filters_pass`) travel with every copy of an object, ghosts and the
///   shared list included, and each rank's local search applies them: the
///   rank that keeps a pair tests both objects' own bits.
/// - Rays (closest_hits, all_hits, any_hits) are global: every rank passes
///   the whole batch and casts each ray, through a structure it keeps over
///   the objects it passed (its own, never ghosts: no hit is found twice),
///   with the ray's mask against their groups. Each rank's hits are the
///   contract's hits of its objects, with the t of the contract's
///   evaluation (ray.hpp), so the union over the ranks is the one-process
///   answer bit for bit. The closest hit of a ray is reduced over the ranks
///   by (t, then global id), a total order: the same whatever the ranks,
///   the decomposition or the order of the reduction. All hits are gathered
///   in rows sorted by (t, id).
///
/// Exactness does not depend on which rank holds which object: ownership
/// (the rank of an object's centre, see `destinations`) only balances work.
#pragma once

#include <mpi.h>

#include <array>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/config_error.hpp>
#include <broadphase/geometry.hpp>
#include <broadphase/ray.hpp>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace broadphase::mpi {

/// Thrown on every rank of the communicator at once, with the same message,
/// when any rank failed during a collective call (bad input, a structure
/// that threw). Never one rank alone, so a caller that catches it can go on
/// to MPI_Finalize without a hang. Bad options (Options, the skin, the grid
/// text of parse_dims) are InvalidConfig (config_error.hpp), as for every
/// structure of the library.
class MpiError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The error's former name, kept so that existing code builds.
using DistributedError [[deprecated("DistributedError is now broadphase::mpi::MpiError")]] =
    MpiError;

/// Two global ids whose objects overlap, a < b.
struct IdPair {
  std::uint32_t a, b;
  friend constexpr bool operator==(const IdPair&, const IdPair&) = default;
};

/// A ray's hit on the object with global id `id`, at the contract's t.
struct IdHit {
  double t = std::numeric_limits<double>::infinity();
  std::uint32_t id = 0;
  /// False only where closest_hits reports a ray that hits nothing (then
  /// id 0, t = +infinity).
  bool hit = false;
  friend constexpr bool operator==(const IdHit&, const IdHit&) = default;
};

/// Every hit of each ray in compressed rows, as RayHitRows (rays.hpp) with
/// global ids: the hits of ray i are `hits[offsets[i]]` to
/// `hits[offsets[i + 1] - 1]`, sorted by t, then by id (the closest first).
struct IdHitRows {
  std::vector<std::size_t> offsets;
  std::vector<IdHit> hits;
};

/// The `root` of Domain::all_hits that gives the rows to every rank.
inline constexpr int kEveryRank = -1;

/// How space is split into subdomains.
enum class Decomposition : std::uint8_t {
  grid,       ///< a Cartesian grid of equal boxes over the world box
  bisection,  ///< weighted recursive coordinate bisection of the centres
};

/// What the bisection balances.
enum class BalanceBy : std::uint8_t {
  objects,   ///< the number of objects (deterministic: the default)
  measured,  ///< each rank's last measured local time, spread over its objects
};

/// The `Options::algo` that finds each rank's local pairs with the lean
/// path (arrays.hpp's one-shot `find_pairs`), reading the received objects
/// in place instead of building a structure.
inline constexpr const char* kLeanPath = "arrays";

/// Options of a Domain. Every field has a default.
struct Options {
  /// What finds each rank's local pairs: `kLeanPath` ("arrays", the
  /// default), or a structure by registry name (registry.hpp; options
  /// after a colon), rebuilt on every call. The lean path reads the
  /// received objects in place; local pairs of one frame at 256 000
  /// scaled-even objects on one rank took 0.63x grid-hashed's time
  /// (medians of three alternated runs, 0.87-0.92 s against 1.35-1.43 s,
  /// 2-core VM at a load of 6), the fastest of the structures before it
  /// (at 64 000: grid-hashed 0.79 s, grid-verlet 0.82, hgrid 1.12,
  /// sort-sweep 1.80).
  std::string algo = kLeanPath;
  Decomposition decomposition = Decomposition::grid;
  /// Grid: ranks per axis. Zero entries are chosen by MPI_Dims_create; the
  /// product must equal the number of ranks.
  std::array<int, 3> dims{0, 0, 0};
  /// Ghost margin in world units: subdomains are grown by it when ghosts
  /// are chosen, and no subdomain is made thinner than it. Zero is exact.
  double margin = 0;
  /// Bisection: `rebalance` rebuilds the cuts when the most loaded rank
  /// holds more than the mean times this.
  double rebalance_threshold = 1.1;
  /// Bisection: what `balance` and `rebalance` weigh when the caller gives
  /// no weights. `measured` gives each object its rank's last local-pairs
  /// time over its object count (zero before the first find_pairs: then
  /// one each), so cuts follow the measured cost and change with timing
  /// noise; the pairs found never depend on the cuts.
  BalanceBy balance_by = BalanceBy::objects;
  /// An object whose bounds reach more ranks than this goes to the shared
  /// list every rank holds, instead of one message per rank.
  int max_ghost_ranks = 4;
  /// False: find_pairs exchanges ghosts but finds no pairs (it reports
  /// none). Measures the decomposition alone (ghosts, traffic) at sizes
  /// whose pair finding would not fit the time.
  bool local_pairs = true;
  /// The structure (registry name, options after a colon) each rank builds
  /// over its own objects to cast rays, afresh on every ray call. The k-d
  /// tree cast the most rays a second of the registry's structures over
  /// 10^5 spheres on one thread (46 000 closest hits a second against
  /// grid-dense's 25 000-31 000 and aabb-tree's 19 000, docs/rays.md).
  std::string ray_algo = "kdtree";
};

/// The subdomains: a binary tree of axis-aligned cuts whose leaves are the
/// ranks. A point p goes left at a cut c on axis a when p[a] < c (half-open
/// boxes). The same tree answers both the owner of a point and the ranks a
/// box reaches, so the two never disagree.
class Partition {
 public:
  /// A grid of dims[0] x dims[1] x dims[2] equal boxes over `world`; rank
  /// (ix * dims[1] + iy) * dims[2] + iz holds cell (ix, iy, iz).
  static Partition grid(const Aabb& world, std::array<int, 3> dims);

  /// The rank whose subdomain holds `p` (any point, infinite coordinates too).
  int owner(const Vec3& p) const;
  /// Appends the ranks whose subdomain, grown by `margin`, meets `box`
  /// (closed box against half-open subdomains).
  void ranks_meeting(const Aabb& box, double margin, std::vector<int>& out) const;
  /// Rank r's subdomain; outermost faces are at ±infinity.
  const Aabb& region(int rank) const { return regions_[static_cast<std::size_t>(rank)]; }
  int size() const { return static_cast<int>(regions_.size()); }
  /// True when p lies in rank r's half-open subdomain.
  bool holds(int rank, const Vec3& p) const;
  /// True when `box`, grown by `margin`, lies inside rank r's subdomain so
  /// that ranks_meeting would list r alone (the same comparisons, against
  /// the cuts that bound r's subdomain; false for a NaN box). Then every
  /// pair of that object with one it overlaps is r's: per axis
  /// lo_a <= max(lo_a, lo_b) <= hi_a, inside the subdomain.
  bool alone(int rank, const Aabb& box, double margin) const;

  /// A node of the tree: a cut (leaf = -1 - rank in `left`).
  struct Node {
    int axis = 0;
    double cut = 0;
    int left = 0, right = 0;  ///< child node index, or -1 - rank for a leaf
  };
  /// Builds a partition from its nodes (root first) and number of ranks.
  Partition(std::vector<Node> nodes, int ranks);
  Partition() = default;

 private:
  std::vector<Node> nodes_;
  std::vector<Aabb> regions_;
};

/// What the last collective call did on this rank (for the CLI's --json
/// and the lab). Bytes and messages count what this rank sent to others.
struct Stats {
  std::uint64_t owned = 0;          ///< objects this rank passed
  std::uint64_t ghosts = 0;         ///< copies received from other ranks
  std::uint64_t shared = 0;         ///< objects in the shared list (all ranks)
  std::uint64_t local_pairs = 0;    ///< pairs this rank reported
  std::uint64_t bytes_sent = 0;     ///< to other ranks
  std::uint64_t messages_sent = 0;  ///< to other ranks (non-empty sends)
  bool rebuilt = true;              ///< PairTracker: the ghost lists were chosen afresh
  double exchange_seconds = 0;      ///< choosing and sending ghosts
  double local_seconds = 0;         ///< the local structure's build and pairs
};

/// What travels for one object in the ghost exchange: its shape, global
/// id and collision filter (72 bytes). The filter travels with every copy,
/// so that the rank which reports a pair (the pair rule above) tests both
/// objects' own bits, whichever ranks own them.
struct GhostRecord {
  Shape shape;
  std::uint32_t id = 0;
  Filter filter;
};

/// A borrowed view (arrays.hpp) of `count` shapes laid out every
/// `stride_bytes` bytes from `first`, such as the `shape` member of an
/// array of structs: no copy.
Objects shapes_view(const Shape* first, std::size_t count, std::ptrdiff_t stride_bytes);

/// The decomposition and the collective calls over one communicator.
///
/// Thread safety: a Domain is used by one thread at a time (its calls are
/// collective over its communicator and it keeps buffers between calls);
/// Domains over different communicators are independent. Movable, not
/// copyable.
class Domain {
 public:
  /// Collective. `world` is the box most objects live in (finite,
  /// non-empty); objects outside it are still handled exactly. Throws
  /// InvalidConfig for a bad world box, bad dims or options (on every rank
  /// given them: the checks read nothing but the arguments and the
  /// communicator's size), among them a grid that does not fit the ranks
  /// or makes subdomains thinner than the margin, and a `ray_algo` that
  /// the registry does not make.
  Domain(MPI_Comm comm, const Aabb& world, Options options = {});
  ~Domain();
  Domain(Domain&&) noexcept;
  Domain& operator=(Domain&&) noexcept;

  int rank() const { return rank_; }
  int size() const { return size_; }
  MPI_Comm comm() const { return comm_; }
  const Options& options() const { return options_; }
  const Partition& partition() const { return partition_; }
  /// How many times the cuts were rebuilt (balance, rebalance): a
  /// PairTracker rebuilds when this changes.
  std::uint64_t cuts() const { return cuts_; }
  const Aabb& world() const { return world_; }

  /// The rank that should own each object: the one whose subdomain holds
  /// its centre. Local, no message.
  std::vector<int> destinations(std::span<const Shape> shapes) const;

  /// Collective. Rebuilds the bisection from the centres of every rank's
  /// `shapes`, each cut splitting the total weight in proportion to the
  /// ranks on either side. `weights[i]` is object i's weight (finite,
  /// >= 0); empty: as `Options::balance_by` says (one each by default, so
  /// results do not depend on timing noise). With integer weights the cuts
  /// are deterministic: the same objects give the same cuts whatever rank
  /// holds them. No effect with a grid decomposition.
  void balance(std::span<const Shape> shapes, std::span<const double> weights = {});
  /// Collective. Calls `balance` when the most loaded rank (by weight, as
  /// for `balance`) holds more than the mean times `rebalance_threshold`;
  /// returns true when it did.
  bool rebalance(std::span<const Shape> shapes, std::span<const double> weights = {});
  /// The same over a borrowed view of the caller's objects, weighed as
  /// `Options::balance_by` says; copies nothing unless a cut is due.
  bool rebalance(const Objects& objects);

  /// Collective. Sends `items[i]` to rank `dest[i]` (an all-to-all, so an
  /// item may go to any rank, not only a neighbour) and returns what this
  /// rank receives, by source rank, in the senders' order.
  template <class T>
  std::vector<T> exchange(std::span<const T> items, std::span<const int> dest) {
    static_assert(std::is_trivially_copyable_v<T>);
    std::vector<T> out;
    exchange_bytes(items.data(), sizeof(T), items.size(), dest.data(), &resize_to<T>, &out);
    return out;
  }

  /// Collective. Sends every item whose centre (`centre_of(item)`, a Vec3)
  /// this rank's subdomain does not hold to the rank whose subdomain does
  /// (an all-to-all, so an item that jumped past a neighbour still
  /// arrives). Items that stay are not copied out: the place of one that
  /// leaves is taken by the last item (the order changes, deterministically;
  /// keeping it would move every item after the first leaver, 35 ms a
  /// frame at 1 024 000 objects of 80 bytes). Arrivals are appended in the
  /// order of their source ranks; a vector without room for them grows (a
  /// copy of every item), so a caller that migrates each frame reserves
  /// some room once (broadphase-mpi reserves a sixteenth more).
  template <class T, class CentreOf>
  void migrate(std::vector<T>& items, CentreOf centre_of) {
    static_assert(std::is_trivially_copyable_v<T>);
    std::vector<T> leaving;
    std::vector<int> dest;
    for (std::size_t i = 0; i < items.size();) {
      const Vec3 c = centre_of(items[i]);
      if (partition_.holds(rank_, c)) {
        ++i;
        continue;
      }
      leaving.push_back(items[i]);
      dest.push_back(partition_.owner(c));
      items[i] = items.back();  // looked at next, in its new place
      items.pop_back();
    }
    exchange_bytes(leaving.data(), sizeof(T), leaving.size(), dest.data(), &append_to<T>, &items);
  }

  /// Collective. Every overlapping pair among the objects of all ranks,
  /// the ones this rank is responsible for appended to `out` (a < b).
  /// Each pair of the world is reported on exactly one rank. Throws
  /// MpiError on every rank when any rank's input is invalid (the
  /// message names the rank and the id) or any rank failed.
  void find_pairs(std::span<const std::uint32_t> ids, std::span<const Shape> shapes,
                  std::vector<IdPair>& out);
  /// The same with collision filters: object i's group bits `groups[i]`
  /// and mask bits `masks[i]` (Filter, geometry.hpp), as the lean path's
  /// `Objects::groups` and `masks`: a pair is reported only when
  /// `filters_pass` holds for its two objects. Both empty: every object has
  /// the default Filter. Otherwise both hold one value per shape (else
  /// MpiError on every rank, naming the rank). The bits may change from one
  /// call to the next; each call sends them with the ghosts.
  void find_pairs(std::span<const std::uint32_t> ids, std::span<const Shape> shapes,
                  std::span<const std::uint32_t> groups, std::span<const std::uint32_t> masks,
                  std::vector<IdPair>& out);
  /// The same over a borrowed view of the caller's arrays: object i of
  /// `objects` has global id `ids[i]`, and the filter of
  /// `objects.groups[i]`, `objects.masks[i]` when those columns are given
  /// (both or neither, one value per object: else MpiError on every rank).
  void find_pairs(std::span<const std::uint32_t> ids, const Objects& objects,
                  std::vector<IdPair>& out);

  /// Collective. The closest hit of each ray over the objects of every
  /// rank: `closest[i]` is the hit of `rays[i]` with the smallest t, then
  /// the smallest global id, among the objects whose group shares a bit
  /// with the ray's mask (`hit` false where there is none), on every rank.
  /// Every rank passes the same `rays` (all of them) and its own objects,
  /// as to find_pairs: object i has global id `ids[i]` and, when the
  /// columns are given, group `objects.groups[i]` (the masks column is
  /// checked as for find_pairs but does not affect rays). `closest` holds
  /// one entry per ray. Throws MpiError on every rank, before casting any
  /// ray, when any ray is invalid (`ray_problem`: the message names the
  /// first), when the ranks pass different batches, or for bad objects (the
  /// message names the rank). Each rank casts every ray through
  /// `Options::ray_algo` over its objects; one reduction of 16 bytes a ray
  /// follows. The structure is kept between ray calls, by id: a call
  /// inserts the objects that arrived on this rank, removes those that left
  /// and moves those whose shape changed (the structure's bulk update). An
  /// id given twice on one rank is refused (MpiError naming the rank).
  void closest_hits(std::span<const std::uint32_t> ids, const Objects& objects,
                    std::span<const Ray> rays, std::span<IdHit> closest);
  /// Collective. Every hit of each ray over the objects of every rank, in
  /// rows sorted by (t, id), identical to one process's: on rank `root`
  /// alone, or on every rank with kEveryRank (the same `root` on every
  /// rank). Other ranks' `out` is left empty. Arguments and errors as for
  /// closest_hits; MpiError on every rank also when more than 2^31 hits
  /// would be gathered. Each hit travels once, 16 bytes, to the root (or
  /// to every rank).
  void all_hits(std::span<const std::uint32_t> ids, const Objects& objects,
                std::span<const Ray> rays, IdHitRows& out, int root = kEveryRank);
  /// Collective. `hit[i]` is 1 on every rank when `rays[i]` hits some
  /// object of some rank, else 0. Each rank's cast stops at its first hit.
  /// Arguments and errors as for closest_hits.
  void any_hits(std::span<const std::uint32_t> ids, const Objects& objects,
                std::span<const Ray> rays, std::span<std::uint8_t> hit);

  /// What the last find_pairs did on this rank (a ray call sets `owned`,
  /// `local_seconds`: building and casting, and `exchange_seconds`: the
  /// checks and the reduction or gather).
  const Stats& stats() const { return stats_; }

  /// Collective. Throws MpiError on every rank when any rank passes
  /// a non-empty `error`; the message is the lowest failing rank's, which
  /// names that rank. Returns normally when every `error` is empty.
  void agree(const std::string& error) const;

 private:
  // The weights `balance` uses: `weights` checked (on every rank), or as
  // Options::balance_by says.
  std::vector<double> weights_for(std::span<const Shape> shapes,
                                  std::span<const double> weights) const;
  // The weight of every object when the caller gives none (collective
  // when balancing by measured cost).
  double default_weight() const;
  // Collective: true when the most loaded rank's weight `mine` exceeds the
  // mean by the threshold and by more than the heaviest object.
  bool due(double mine, double heaviest) const;
  // Rebuilds the bisection's cuts, object i weighing w[i].
  void cut(std::span<const Shape> shapes, const std::vector<double>& w);
  // Sends count items of `size` bytes; the result goes to the buffer that
  // resize(out, bytes) returns (the caller's vector, resized).
  void exchange_bytes(const void* data, std::size_t size, std::size_t count, const int* dest,
                      std::byte* (*resize)(void*, std::size_t), void* out);
  template <class T>
  static std::byte* resize_to(void* out, std::size_t bytes) {
    auto& v = *static_cast<std::vector<T>*>(out);
    v.resize(bytes / sizeof(T));
    return reinterpret_cast<std::byte*>(v.data());
  }
  template <class T>
  static std::byte* append_to(void* out, std::size_t bytes) {
    auto& v = *static_cast<std::vector<T>*>(out);
    const std::size_t old = v.size();
    v.resize(old + bytes / sizeof(T));
    return reinterpret_cast<std::byte*>(v.data() + old);
  }
  // find_pairs over any reader of this rank's shapes.
  template <class ShapeAt>
  void find_pairs_of(std::span<const std::uint32_t> ids, std::size_t count, ShapeAt shape_at,
                     std::span<const std::uint32_t> groups, std::span<const std::uint32_t> masks,
                     std::vector<IdPair>& out);
  // Collective: the checks every ray call makes before casting (see
  // closest_hits), agreed on every rank; `root` is all_hits' (kEveryRank
  // otherwise). Then brings this rank's ray caster up to `objects`.
  struct RayCaster;
  const RayCaster& prepare_rays(const char* call, std::span<const std::uint32_t> ids,
                                const Objects& objects, std::span<const Ray> rays, int root);
  // Local: rays_ brought up to `objects` (built on the first call).
  void fit_ray_caster(std::span<const std::uint32_t> ids, const Objects& objects);
  // Makes room for `count` records in local_ from `used` on without
  // shrinking it (so a frame like the last one writes no fresh pages).
  GhostRecord* grow_local(std::size_t used, std::size_t count);

  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  Aabb world_;
  Options options_;
  Partition partition_;
  Stats stats_;
  // Buffers kept between find_pairs calls: this rank's objects and ghosts
  // (the first local_used_ of local_, with their ids apart in local_ids_),
  // and what is sent.
  std::vector<GhostRecord> local_, sent_, shared_mine_;
  std::vector<std::uint32_t> local_ids_;
  // The filters of local_'s records as the lean path's columns, filled
  // only when some record's filter is not the default.
  std::vector<std::uint32_t> local_groups_, local_masks_;
  std::vector<int> dest_;
  std::vector<std::byte> send_buffer_;
  std::size_t local_used_ = 0;
  std::uint64_t cuts_ = 0;
  // This rank's objects in Options::ray_algo, kept between ray calls.
  std::unique_ptr<RayCaster> rays_;
};

/// Pairs frame after frame with a skin, as Verlet lists and LAMMPS's
/// neighbour lists do: the ghost lists (which rank gets which object, the
/// shared list, which objects lie inside this subdomain) are kept while
/// every object's bounds stay within `skin` of its bounds at the last
/// rebuild. The local pairs are found afresh by the lean path each call. Ghosts go to every rank
/// that bounds grown by the skin reach, so they cover the objects wherever they move inside it; on
/// other frames only the ghosts whose shape changed travel, along the same lists, each with its id
/// (the shared list travels whole). Every call is exact however far objects moved: one beyond its
/// skin on any rank makes every rank rebuild.
///
/// Between rebuilds the caller keeps its objects in place: the same ids in
/// the same order on each rank (an object may then stand outside its
/// owner's subdomain by up to the skin; ownership never matters for
/// exactness). `rebuild_due` tells the caller when to migrate and
/// rebalance first. A call with other ids, or after new cuts, rebuilds.
///
/// Thread safety: as Domain (one thread at a time); it uses the Domain it
/// was made with, which must outlive it.
class PairTracker {
 public:
  /// `skin` in world units, finite and >= 0 (0: a rebuild whenever an
  /// object moves). Throws InvalidConfig otherwise (local, no collective
  /// call: every rank passes the same value).
  PairTracker(Domain& domain, double skin);
  ~PairTracker();
  PairTracker(const PairTracker&) = delete;
  PairTracker& operator=(const PairTracker&) = delete;

  /// Collective. True on every rank when the next find_pairs would rebuild:
  /// the first call, another count of objects on some rank, an object
  /// beyond its skin on some rank, or new cuts.
  bool rebuild_due(const Objects& objects);
  /// Collective. As Domain::find_pairs: every overlapping pair of the
  /// world once, on one rank; MpiError on every rank for bad input. The
  /// filters of `objects.groups` and `masks` (optional, as there) may
  /// change between calls without a rebuild: a ghost whose filter changed
  /// travels along the kept lists as one whose shape changed does.
  void find_pairs(std::span<const std::uint32_t> ids, const Objects& objects,
                  std::vector<IdPair>& out);
  /// What the last find_pairs did on this rank.
  const Stats& stats() const { return stats_; }
  /// Rebuilds so far (the first call's included).
  std::uint64_t rebuilds() const { return rebuilds_; }

 private:
  struct State;
  // True when this rank's objects alone require a rebuild (no message).
  bool beyond_skin(const Objects& objects) const;
  void rebuild(std::span<const std::uint32_t> ids, const Objects& objects);
  // Copies this rank's shapes in and says whether a rebuild is due here.
  bool take(const Objects& objects);
  // Sends the shapes and filters that changed along the kept ghost lists,
  // and the shared list whole.
  void refresh();
  // The lean path's filter columns over the rank's objects and ghosts, when
  // any has a filter (`own`: the caller gave this rank's).
  void fill_filters(bool own);
  Domain& domain_;
  double skin_;
  Stats stats_;
  std::uint64_t rebuilds_ = 0;
  std::unique_ptr<State> state_;
};

/// Collective over `comm`: throws MpiError on every rank when any
/// rank passes a non-empty `error` (the lowest failing rank's message).
void agree(MPI_Comm comm, const std::string& error);

/// Parses "2x2x1" into grid dims (each >= 1). Throws InvalidConfig.
std::array<int, 3> parse_dims(const std::string& text);

}  // namespace broadphase::mpi

namespace broadphase {
/// The MPI part's former namespace, kept so that existing code builds.
namespace distributed = mpi;
}  // namespace broadphase
