/// \file grid_verlet.hpp
/// `grid-verlet` (formerly `fast-grid`, still accepted): the default
/// structure, tuned for frames in which a fifth of the objects move. A
/// hierarchy of cell grids rebuilt in bulk by counting sort, with fixed and
/// moving objects kept apart, the pairs among fixed objects cached, and for
/// each mover a Verlet list: the objects near a box grown by a margin, valid
/// until the mover leaves that box. A frame of the study retests only what
/// moved, from those lists.
///
/// Parts: the grids are detail::LevelGrid (detail/level_grid.hpp), which
/// build themselves from their items, the movers' fat boxes and candidate
/// lists a detail::VerletLists (detail/verlet_lists.hpp),
/// the threads and the split of every pass a detail::WorkShares
/// (detail/work_shares.hpp) over a detail::WorkerPool (detail/worker_pool.hpp).
///
/// Layout. Objects live in slot-indexed arrays (shape, user data,
/// generation, where the object is). Each of the two grids (fixed objects,
/// moving objects) is a flat array of 32-byte entries (float bounds rounded
/// outwards, slot and generation) in cell order, with one cell index per
/// level and a copy of each entry's shape in the same order. An object goes
/// into exactly one cell of one level: the level whose reach (halved per
/// level from the largest extent) covers its widest extent, the cell of its
/// lower corner. Cells along x are contiguous, so a query box visits on each
/// level one contiguous run of entries per (y, z) row of cells, without any
/// search; every object is met at most once and every pair is reported once
/// by construction.
///
/// Mutations. A bulk `update(span)` rebuilds the moving grid (one counting
/// sort) and, when the fixed set changed, the fixed grid and its pair cache.
/// A single insert or update puts the object on a short unsorted "loose"
/// list that every query and frame scans; a removal takes the object out at
/// once (loose objects leave their list, grid entries get NaN bounds, which
/// no test passes, and their slot is held back until the next rebuild so
/// that no stale grid entry can name a new object). When the loose and
/// held-back objects exceed max(64, size/8), the mutation that crossed the
/// line rebuilds the grids (not the pair cache, which the next bulk update
/// builds; until then pair finding scans the fixed grid): amortised
/// O(log n) per insert, and no work is ever left for the next query.
///
/// Frames. Each moving object keeps a list of the fixed objects near a
/// "fat" box around it (its bounds grown by about 12 frames of its last
/// displacement), with copies of their spheres, and a list of the moving
/// objects whose fat boxes meet its own. While its bounds stay inside the
/// fat box a frame tests these two lists and nothing else; the bulk update
/// renews the lists of the objects that left theirs. An object too fast
/// for a useful margin keeps no moving list and probes the moving grid
/// every frame instead.
///
/// Dense mode. When most movers would renew their lists every frame or two
/// (everything moves fast) and fixed objects are no more than the movers,
/// the lists cost more than they save: the movers then keep none, and are
/// kept as well in a grid-dense grid (grid_dense.hpp) updated in place,
/// which finds their pairs and answers queries and rays for them; each
/// mover probes the fixed grid for its fixed pairs, and the moving grid is
/// rebuilt only when objects join or leave it. The choice is made every
/// eighth bulk update from the movers' last displacements (option
/// `movers=auto|lists|dense`, `dense_movers()` tells which is in use), so
/// it never depends on the thread count. On threads the moves are staged
/// by chunks and the objects that change cells relinked after them, in
/// the moves' order; the pair pass splits the probes of the fixed grid
/// and the dense grid's cells into chunks joined in order.
///
/// Threads. `find_pairs` and the bulk update split the moving objects over
/// `threads` threads (option `threads=N`, default 1, 0 = hardware
/// concurrency) of a pool kept by the structure, in chunks taken by
/// whichever thread is free; each chunk writes its own buffers and the
/// buffers are joined in chunk order, so the results, the pair order and
/// the hash never depend on the thread count. Between the parts of a call
/// the workers poll for up to 0.5 ms before they sleep (waking a sleeping
/// thread costs more than that part of a frame), so after each call the
/// workers keep their cores busy for up to that long; a call never waits
/// for a worker that is still waking up (the caller takes its work).
#pragma once

#include <algorithm>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/level_grid.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/detail/verlet_lists.hpp>
#include <broadphase/detail/work_shares.hpp>
#include <broadphase/grid_dense.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <span>
#include <utility>
#include <vector>

namespace broadphase {

/// How GridVerlet finds its movers' pairs (option `movers=`).
enum class GridVerletMovers {
  /// Lists while they pay, the dense grid while most movers would renew
  /// theirs every frame or two, switching as the motion changes (default).
  automatic,
  /// Always the movers' lists.
  lists,
  /// Always the dense grid.
  dense,
};

/// The options of GridVerlet
/// (`grid-verlet:threads=N,cell=F,grain=N,movers=auto|lists|dense`).
struct GridVerletOptions {
  /// The most threads: a chunk's mark holds its chunk in 10 bits, which
  /// more than 128 threads would overflow.
  static constexpr unsigned kMaxThreads = detail::WorkShares::kMaxThreads;
  /// Threads the bulk update and find_pairs split their work over, with the
  /// same results and pair order for every count, in [0, 64]; 0: the
  /// hardware concurrency (at most 64). Default 1.
  unsigned threads = 1;
  /// A cell's side over its level's reach, in [0.5, 64] (larger: fewer cells
  /// to visit, more entries per cell). Default 1.
  double cell = 1;
  /// Moving objects per thread below which the work stays on fewer threads,
  /// in [1, 2^24]. Default 2048 (1: every thread takes part from two movers
  /// on, which tests use to run the threaded paths on small scenes).
  std::size_t grain = 2048;
  /// Lists, the dense grid, or the choice made from the movers' motion
  /// (GridVerletMovers). Default: automatic.
  GridVerletMovers movers = GridVerletMovers::automatic;
  /// Throws InvalidConfig for a value out of range (detail/structure_base.hpp).
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static GridVerletOptions from(const OptionText& text);
};

/// Hierarchical cell grid with a fixed/moving split and cached fixed pairs.
/// insert, remove, update: amortised O(log n) (O(1) unless a rebuild is
/// due); bulk update of m objects: O(m) plus a rebuild of the fixed grid,
/// O(f + pairs), only when the fixed set changed. Handles stay valid until
/// their object is removed. Const members may run concurrently; mutations
/// need exclusive access.
class GridVerlet : public detail::StructureBase<GridVerlet> {
 public:
  using Options = GridVerletOptions;
  /// Reads the deprecated Config::options map into GridVerletOptions.
  /// Throws InvalidConfig.
  explicit GridVerlet(const Config& c = {})
      : GridVerlet(without_options(c), GridVerletOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (GridVerletOptions::check).
  GridVerlet(const Config& c, const GridVerletOptions& o);
  ~GridVerlet();

  /// Adds an object (to the loose list). Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object; its handle becomes stale. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves one object (to the loose list). Throws InvalidHandle, InvalidShape.
  /// A fixed object that is updated is treated as moving from then on.
  void update(Handle h, const Shape& s);
  /// Moves many objects and rebuilds the moving grid once. Throws like
  /// update(h, s), before changing anything when a handle or shape is bad.
  void update(std::span<const Move> moves);
  /// Puts every object inserted or updated one at a time (the loose list)
  /// into the grids and, when the fixed objects changed, rebuilds the fixed
  /// grid and the cache of pairs among fixed objects: the step that ends
  /// every bulk update. Call it once after inserting a scene, before the
  /// first frame, so that the first find_pairs reads the cache instead of
  /// scanning the fixed grid (an empty bulk update does the same).
  /// O(n + fixed pairs) when the fixed set changed, else O(moving + loose).
  void settle();

  /// Visits every object whose shape overlaps `q` exactly.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const;
  /// Visits every overlapping pair that passes the filters once, in a
  /// deterministic order. `query(shape)` is not filtered (its shape has no
  /// filter).
  template <class V>
  QueryCost for_each_pair(V&& visitor) const;
  /// Appends every overlapping pair that passes the filters once to `out`,
  /// using the configured threads; the order equals for_each_pair's
  /// whatever the thread count.
  QueryCost find_pairs(std::vector<HandlePair>& out) const;

  /// The number of live objects. O(1).
  std::size_t size() const { return live_; }
  /// Bytes held: the capacity of every container, pair buffers included.
  std::size_t memory_bytes() const;
  /// True when `h` names a live object of this structure. O(1).
  bool contains(Handle h) const {
    return h.index < slots_.size() && slots_[h.index].gen == h.generation &&
           (h.generation & 1u) != 0;
  }
  /// The object's shape. Throws InvalidHandle. The reference lives until
  /// the next mutation.
  const Shape& shape(Handle h) const { return shape_of(index_of(h)); }
  /// The user data given at insertion. Throws InvalidHandle.
  std::uint64_t user_data(Handle h) const { return user_[index_of(h)]; }
  /// Changes an object's collision filter (HasFilters); a fixed object's
  /// change drops the cache of fixed pairs, which holds only pairs that pass
  /// (the next settle() or bulk update rebuilds it). Throws InvalidHandle.
  void set_filter(Handle h, Filter f);
  /// An object's collision filter. Throws InvalidHandle.
  Filter filter(Handle h) const {
    const std::uint32_t i = index_of(h);
    return i < filters_.size() ? filters_[i] : Filter{};
  }
  /// Installs the pair filter (structure.hpp's PairFilter); empty removes
  /// it. Drops the cache of fixed pairs, as set_filter does.
  void set_pair_filter(PairFilter pf);
  /// True when objects `a` and `b` may pair by the filters and the pair
  /// filter. Throws InvalidHandle.
  bool pair_passes(Handle a, Handle b) const { return may_pair(index_of(a), index_of(b)); }
  /// Casts a ray (HasRayCast); each hit once to `visitor`. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const;
  /// The number of threads find_pairs and the bulk update use.
  unsigned threads() const { return shares_.threads(); }
  /// True while the movers' pairs come from the dense grid rather than
  /// from their lists (option `movers=`; with `auto`, decided at every
  /// eighth bulk update from the movers' displacements). O(1).
  bool dense_movers() const { return dense_mode_; }
  /// Checks slots, lists, grid order and the pair cache; throws std::logic_error.
  void validate() const;
  /// Reports the occupied cells of the two grids as built: the fixed
  /// grid's levels as levels 0, 1, ... (finest first), then the moving
  /// grid's after them, each cell with the live objects whose lower corner
  /// it holds (a moving object's is the corner of its fat box, a little
  /// below its own); an object reaches up to its level's reach beyond its
  /// cell, and an object whose corner lies beyond the world hint sits in a
  /// border cell, outside its box. Objects on the loose list (inserted or
  /// moved one at a time since the last rebuild; settle() empties it) come
  /// last, each as its own box on one more level after the moving grid's,
  /// holding 1; in dense mode (dense_movers()) the movers, instead of the
  /// moving grid's levels, are reported the same way. Unbounded objects are
  /// in no cell. O(cells + entries), for pictures.
  void visit_cells(CellVisitor visitor) const;

 private:
  /// Where a slot's object is: which list or grid holds its live entry.
  enum class Home : std::uint8_t { free, held, fixed_grid, moving_grid, loose };
  using Entry = detail::GridEntry;
  using Level = detail::GridLevel;
  using LineShape = detail::LineShape;
  using Grid = detail::LevelGrid;
  using Mover = detail::VerletMover;
  using Candidate = detail::VerletCandidate;

  // So many candidates of a list at most are prefetched ahead of the pair
  // pass, when the lists are out of cache.
  static constexpr std::uint32_t kPrefetchCandidates = 128;
  static constexpr double kNoMinX = Grid::kNoMinX;
  static constexpr std::uint32_t kFromLoose = 0x80000000u;

  std::uint32_t index_of(Handle h) const {
    if (!contains(h)) throw InvalidHandle(h);
    return h.index;
  }
  Handle handle_of(std::uint32_t s) const { return {s, slots_[s].gen}; }
  /// The shape of a live object: each is held once, by its grid or list.
  const Shape& shape_of(std::uint32_t s) const {
    switch (slots_[s].home) {
      case Home::fixed_grid:
        return fixed_.shapes[slots_[s].pos];
      case Home::moving_grid:
        if (dense_mode_) return dense_->shape(dense_handle_[slots_[s].pos]);
        return moving_.shapes[slots_[s].pos];
      default:
        return loose_shapes_[slots_[s].pos];
    }
  }
  std::uint32_t allocate_slot();
  void free_slot(std::uint32_t s);
  void add_loose(std::uint32_t s, const Shape& shape);
  void drop_loose(std::uint32_t s);
  void leave_grid(std::uint32_t s);
  /// A mover (moving-grid entry k) to its new shape, in a bulk update.
  void move_mover(std::uint32_t k, const Shape& shape);
  /// Any object (slot i) to its new shape by the loose list: a grid object
  /// leaves its grid; the object is moving from now on.
  void move_via_loose(std::uint32_t i, const Shape& shape);
  void maybe_rebuild();
  void rebuild(bool fixed_too);
  /// After a bulk update: switches between the movers' lists and the dense
  /// grid when the movers' expected renewals cross kDenseFrom or kDenseUntil
  /// (the switch takes effect in the rebuild that follows).
  void choose_mover_mode();
  /// Dense mode: refills the dense grid with every live mover, after a rebuild.
  void refill_dense();
  /// Dense mode: copies each mover's shape, bounds and last displacement
  /// from the dense grid back to the moving grid and the lists' records
  /// (before a rebuild, or to look at the movers' speeds).
  void sync_from_dense();
  /// Our handle of a dense-grid object (its user data).
  Handle from_dense(Handle d) const { return unpack(dense_->user_data(d)); }
  static std::uint64_t pack(Handle h) { return std::uint64_t{h.index} << 32 | h.generation; }
  static Handle unpack(std::uint64_t u) {
    return {static_cast<std::uint32_t>(u >> 32), static_cast<std::uint32_t>(u)};
  }
  /// The shape an item of a rebuild came from: `src` is an index into
  /// `old_shapes` (the grid's shapes before the build), or kFromLoose | an
  /// index into loose_shapes_.
  const Shape& shape_from(std::uint32_t src, const std::vector<LineShape>& old_shapes) const;
  /// Points the slots of a grid's entries at them.
  void point_slots(const Grid& g, Home home);
  void build_fixed_cache();

  /// Exact test of two shapes, with the sphere–sphere case inline.
  static bool exact(const Shape& a, const Shape& b) {
    if (a.kind == ShapeKind::sphere && b.kind == ShapeKind::sphere)
      return spheres_overlap(a.center, a.half.x, b.center, b.half.x);
    return overlaps(a, b);
  }

  /// Pairs of moving-grid entries [begin, end) with their fixed candidates
  /// and their moving neighbours. emit(handle, handle) returns false to stop.
  template <class E>
  bool mover_pairs(std::size_t begin, std::size_t end, E& emit, std::uint64_t& tests) const;
  /// Pairs among entries [begin, end) of one grid and later ones (each
  /// pair once).
  template <class E>
  bool grid_pairs(const Grid& g, std::size_t begin, std::size_t end, E& emit,
                  std::uint64_t& tests) const;
  /// The fixed pairs: the cache when it is built, else a scan of the grid.
  template <class E>
  bool fixed_pairs(E& emit, std::uint64_t& tests) const;
  /// Pairs of loose objects with both grids and with later loose objects.
  template <class E>
  bool loose_pairs(E& emit, std::uint64_t& tests) const;
  template <class E>
  bool all_pairs(E& emit, std::uint64_t& tests) const;
  /// The movers' pairs without their lists, in dense mode or when a filter
  /// change left them incomplete until the next rebuild renews them
  /// (lists_stale_): each mover probes the fixed grid, and the movers'
  /// own pairs come from the dense grid, or else from the moving grid as
  /// the fixed grid's are found.
  template <class E>
  bool pairs_without_lists(E& emit, std::uint64_t& tests) const;
  /// Each mover of moving-grid entries [begin, end) against the fixed grid,
  /// where it is now (in dense mode, as the dense grid holds it).
  template <class E>
  bool fixed_probes(std::size_t begin, std::size_t end, E& emit, std::uint64_t& tests) const;
  /// The pairs among movers in dense mode, from the dense grid (part `part`
  /// of `parts` of its cells: the parts in turn give the whole, in order).
  template <class E>
  bool dense_pairs(E& emit, std::uint64_t& tests, std::size_t part = 0,
                   std::size_t parts = 1) const;
  /// Dense mode, many moves on threads: stages mover k's move in the dense
  /// grid (LinkedGrid::stage_update), `b` its new bounds; false when it
  /// still has to be relinked. Distinct movers may be staged at once.
  bool stage_dense(std::uint32_t k, const Shape& shape, AabbF& b, detail::OccupiedBox& grown);

  /// The threads (option threads=N) and the split of every pass (option
  /// grain=N: moving objects per share at least).
  detail::WorkShares shares_;
  // What the grids are built for: the world, the cell side over the reach
  // (option cell=F), cells per object at most.
  detail::LevelGridSpec fixed_spec_;
  detail::LevelGridSpec moving_spec_;

  std::vector<std::uint64_t> user_;  // for a free slot: the next free slot
  /// What a handle leads to, in one record (a lookup is one cache line).
  /// Kept instead of the shared SlotMap (handle.hpp), whose generations lie
  /// in an array of their own: a lookup then reads two lines (in the bulk
  /// update's check of every move, and for each near-list hit), the map
  /// keeps a free-list link per slot (4 bytes) where this record threads
  /// its free list through the user data, and it has no held-back state.
  /// Measured side by side, SlotMap version over this one (tools/ab/ab.sh,
  /// scaled-even 102 400, 100 frames, 4 interleaved runs, 2-core EPYC VM
  /// at load 5-10): frame time 0.97-1.11x (middle two 1.01x and 1.08x)
  /// with one thread, 0.98-1.09x (1.04x and 1.06x) with two.
  struct Slot {
    std::uint32_t gen = 0;  // odd while alive
    std::uint32_t pos = 0;  // a loose object's index in loose_, a grid object's entry
    Home home = Home::free;
    Motion motion = Motion::dynamic;
  };
  std::vector<Slot> slots_;
  std::uint32_t free_head_ = Handle::kNullIndex;
  std::size_t live_ = 0;

  // Collision filters by slot: empty until one other than the default is set.
  std::vector<Filter> filters_;
  PairFilter pair_filter_;
  Filter filter_of(std::uint32_t s) const { return s < filters_.size() ? filters_[s] : Filter{}; }
  bool unfiltered() const { return filters_.empty() && !pair_filter_; }
  // The movers' lists leave out candidates by the filters they were renewed
  // with: after a filter changes they are incomplete until every list is
  // renewed (at the next rebuild), and the frames do without them.
  bool lists_stale_ = false;
  /// The filter rule for slots `i`, `j`: the bits, then the pair filter.
  bool may_pair(std::uint32_t i, std::uint32_t j) const {
    return filters_pass(filter_of(i), filter_of(j)) &&
           (!pair_filter_ || pair_filter_(handle_of(i), handle_of(j)));
  }
  /// An emitter with the filter test attached (detail::admits): the pair
  /// walks test it on every candidate before the exact test.
  template <class E>
  struct Gated {
    using PairGate = void;
    E emit;
    const GridVerlet* self;
    bool operator()(Handle a, Handle b) { return emit(a, b); }
    bool may_pair(std::uint32_t i, std::uint32_t j) const { return self->may_pair(i, j); }
  };
  /// `emit` as the walks of a world with (kFiltered) or without filters take it.
  template <bool kFiltered, class E>
  auto gated(E emit) const {
    if constexpr (kFiltered) {
      return Gated<E>{std::move(emit), this};
    } else {
      return emit;
    }
  }
  template <bool kFiltered>
  QueryCost find_pairs_as(std::vector<HandlePair>& out) const;
  void drop_fixed_cache();

  std::vector<std::uint32_t> loose_;  // loose slots
  std::vector<AabbF> loose_bounds_;   // parallel to loose_
  std::vector<Shape> loose_shapes_;   // parallel to loose_
  std::vector<float> loose_speed_;    // parallel to loose_: last displacement, 0 if unknown
  std::vector<std::uint32_t> held_;   // removed grid objects whose slots wait for a rebuild
  bool fixed_dirty_ = false;          // the fixed set changed since the fixed grid was built
  bool cache_built_ = true;           // fixed_pairs_ holds the pairs of the fixed grid
  std::size_t fixed_count_ = 0;       // objects of the fixed grid still in it
  std::size_t moving_count_ = 0;      // objects of the moving grid still in it

  Grid fixed_;
  Grid moving_;
  // Overlapping pairs within the fixed grid, stored as the handles find_pairs
  // reports: while no fixed object has left the grid since the cache was
  // built, a frame appends the whole cache as one block copy.
  std::vector<HandlePair> fixed_pairs_;
  // Rebuild scratch, kept to avoid reallocation: the moving grid's input,
  // where each item came from, the previous shapes and mover states.
  std::vector<Entry> scratch_items_;
  std::vector<std::uint32_t> scratch_src_;
  std::vector<LineShape> scratch_shapes_;
  Grid::Scratch moving_scratch_;            // the moving grid's build scratch
  std::vector<std::uint32_t> move_target_;  // per move in a bulk update: its mover
  // A bulk update on threads: per slot, the mark (update and chunk)
  // of the last chunk of moves that named it, to find a handle named twice.
  std::vector<std::uint32_t> mark_;
  std::uint32_t mark_round_ = 0;

  // The movers' fat boxes and candidate lists, in the moving grid's order.
  detail::VerletLists lists_;

  // Dense mode: when most movers would renew their lists every frame or
  // two (everything moves fast), lists cost more than they save. The
  // movers then keep no lists (lists_.direct()), stay where the last
  // rebuild put them in the moving grid (whose boxes go stale and are not
  // read), and are kept as well in a grid-dense grid, updated in place each
  // frame, which finds their pairs and answers queries and rays for them.
  // The switch follows the movers' expected renewals (choose_mover_mode),
  // which depend on their motion alone, so pairs and their order never
  // depend on the thread count or the timing.
  GridVerletMovers movers_option_ = GridVerletMovers::automatic;
  bool dense_mode_ = false;
  bool mode_changed_ = false;  // a rebuild is due to enter or leave dense mode
  std::uint32_t bulk_updates_ = 0;
  std::unique_ptr<GridDense> dense_;  // dense mode: the movers (user data: our handle)
  std::vector<Handle> dense_handle_;  // dense mode: per moving entry, its dense handle
  std::vector<float> dense_speed_;    // dense mode: per dense slot, its last displacement
  // Per chunk of a bulk update in dense mode: the moves that relink, with
  // their new bounds.
  std::vector<std::vector<std::pair<std::uint32_t, AabbF>>> dense_later_;
  std::vector<detail::OccupiedBox> dense_grown_;  // per chunk: bounds moved within cells

  /// Per-share pair buffers of find_pairs, reused between frames.
  mutable std::mutex buffers_mutex_;
  mutable std::vector<std::vector<HandlePair>> buffers_;
};

// ---------------------------------------------------------------------------

template <class V>
QueryCost GridVerlet::cast_ray(const Ray& r, V&& visitor) const {
  require_valid(r);
  detail::RayCast<std::remove_reference_t<V>> cast(nullptr, r, visitor);
  auto test = [&](Handle h, const Shape& s, const AabbF& box) {
    double t;
    return !cast.cull.enter(box, cast.tmax, t) || cast.test_object(h, s, filter_of(h.index).group);
  };
  if (dense_mode_) {
    // The movers, from the dense grid (the moving grid's boxes are stale).
    Ray within = r;
    within.tmax = cast.tmax;
    const QueryCost c = dense_->cast_ray(within, [&](Handle d, double t) {
      cast.tmax = visit_hit(visitor, from_dense(d), t, cast.tmax);
      return cast.tmax;
    });
    cast.cost.tests += c.tests;
    if (cast.tmax < 0) {
      cast.cost.stopped = true;
      return cast.cost;
    }
  }
  for (std::size_t i = 0; i < loose_.size(); ++i)
    if (!test(handle_of(loose_[i]), loose_shapes_[i], loose_bounds_[i])) return cast.cost;
  // Each level of both grids: a march through its cells (an entry sits in
  // the cell of its box's lower corner and reaches at most the level's
  // reach above it), each entry tested once.
  detail::RaySlots tested;
  for (const Grid* g : {&fixed_, &moving_}) {
    if (g == &moving_ && dense_mode_) break;
    for (const Level& lv : g->levels) {
      const std::uint32_t begin = g->cell_start[lv.first_cell];
      const std::uint32_t end = g->cell_start[lv.first_cell + lv.cells()];
      if (begin == end) continue;
      detail::RayGridLevel l;
      l.cell = lv.inv_cell > 0 ? 1 / lv.inv_cell : std::numeric_limits<double>::infinity();
      for (int a = 0; a < 3; ++a) {
        l.origin[a] = lv.origin[a];
        l.index_lo[a] = 0;
        l.index_hi[a] = lv.n[a] - 1.0;
      }
      l.reach = lv.reach;
      auto entry = [&](std::uint32_t k) {
        const Entry& e = g->entries[k];
        return e.dead() || !tested.insert(e.slot) || test(e.handle(), g->shapes[k], e.box());
      };
      auto march = detail::RayGridMarch(
          l, [&](double x, int a) { return static_cast<std::int32_t>(lv.cell(x, a)); },
          [&](const detail::CellKey& c) {
            const std::uint32_t cell = lv.first_cell +
                                       (static_cast<std::uint32_t>(c.c[1]) * lv.n[2] +
                                        static_cast<std::uint32_t>(c.c[2])) *
                                           lv.n[0] +
                                       static_cast<std::uint32_t>(c.c[0]);
            for (std::uint32_t k = g->cell_start[cell]; k < g->cell_start[cell + 1]; ++k)
              if (!entry(k)) return false;
            return true;
          });
      // Only the part of the ray inside the level's entries' union is
      // marched: a ray above a city's buildings otherwise marched the
      // flat levels' clamped border rows (LevelGrid::bounded).
      const Aabb bound{{lv.bound.lo[0], lv.bound.lo[1], lv.bound.lo[2]},
                       {lv.bound.hi[0], lv.bound.hi[1], lv.bound.hi[2]}};
      using Outcome = typename decltype(march)::Outcome;
      switch (march.march_within(cast, 2.0 * (end - begin) + 64, g->bounded ? &bound : nullptr)) {
        case Outcome::finished:
          continue;
        case Outcome::stopped:
          return cast.cost;
        case Outcome::scan:
          break;
      }
      for (std::uint32_t k = begin; k < end; ++k)
        if (!entry(k)) return cast.cost;
    }
  }
  return cast.cost;
}

template <class V>
QueryCost GridVerlet::query(const Shape& q, V&& visitor) const {
  require_valid(q);
  QueryCost cost;
  const AabbF b = bounds_f(q);
  auto test = [&](Handle h, const Shape& shape) {
    ++cost.tests;
    if (overlaps(q, shape) && !visit(visitor, h)) {
      cost.stopped = true;
      return false;
    }
    return true;
  };
  for (const Grid* g : {&fixed_, &moving_}) {
    if (g == &moving_ && dense_mode_) {
      const QueryCost c = dense_->query(q, [&](Handle d) {
        if (visit(visitor, from_dense(d))) return true;
        cost.stopped = true;
        return false;
      });
      cost.tests += c.tests;
      if (cost.stopped) return cost;
      continue;
    }
    if (!g->scan(b, 0, kNoMinX,
                 [&](std::uint32_t k) { return test(g->entries[k].handle(), g->shapes[k]); }))
      return cost;
  }
  for (std::size_t i = 0; i < loose_.size(); ++i)
    if (loose_bounds_[i].overlaps(b) && !test(handle_of(loose_[i]), loose_shapes_[i])) return cost;
  return cost;
}

template <class E>
bool GridVerlet::grid_pairs(const Grid& g, std::size_t begin, std::size_t end, E& emit,
                            std::uint64_t& tests) const {
  // Each pair is reported by the entry that comes first in the order
  // (level, lower x, entry index): entries on higher levels are scanned in
  // full, entries on the same level only from the lower x onwards.
  std::size_t level = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const Entry& me = g.entries[i];
    while (level + 1 < g.levels.size() && i >= g.level_end(level)) ++level;
    if (me.dead()) continue;
    const Shape& sm = g.shapes[i];
    const std::size_t level_end = g.level_end(level);
    const float me_x = me.lo[0];
    const bool go = g.scan(me.box(), level, me_x, [&](std::uint32_t j) {
      const Entry& o = g.entries[j];
      if (j < level_end && (o.lo[0] < me_x || (o.lo[0] == me_x && j <= i))) return true;
      if (!detail::admits(emit, me.slot, o.slot)) return true;
      ++tests;
      return !exact(sm, g.shapes[j]) || emit(me.handle(), o.handle());
    });
    if (!go) return false;
  }
  return true;
}

template <class E>
bool GridVerlet::mover_pairs(std::size_t begin, std::size_t end, E& emit,
                             std::uint64_t& tests) const {
  // While no fixed object has left the grid since it was built, every
  // candidate is live and fixed lists are read alone.
  const bool all_live = fixed_count_ == fixed_.entries.size();
  const bool far = lists_.lists_out_of_cache();
  const std::vector<Mover>& movers = lists_.movers();
  const Candidate* const list_pool = lists_.list_data();
  const std::uint32_t* const near_pool = lists_.near_data();
  std::size_t level = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const Entry& me = moving_.entries[i];
    if (me.dead()) continue;
    const Shape& sm = moving_.shapes[i];
    const Mover& mv = movers[i];
    // Prefetch ahead: the lists of the movers a few entries on (lists
    // renewed since the last compaction lie elsewhere in the pool), then
    // the slots their near lists name, then those neighbours' records.
    if (i + 8 < end) {
      // Lists far out of cache are prefetched whole, line by line: a list
      // is read in one go, and its lines then arrive together rather than
      // one miss after another. Lists that fit in cache only get their
      // first lines (prefetching every line costs more than it saves).
      // Only lines of the list itself: an address past a list (or into an
      // empty pool, whose data() may be null) is not computed.
      const Mover& ahead = movers[i + 8];
      const std::uint32_t count =
          std::min<std::uint32_t>(ahead.list_count, far ? kPrefetchCandidates : 2);
      if (count > 0) {
        const char* l = reinterpret_cast<const char*>(list_pool + ahead.list_begin);
        for (const char* l_end = l + count * sizeof(Candidate); l < l_end; l += 64)
          detail::prefetch(l);
      }
      if (ahead.near_count > 0) detail::prefetch(near_pool + ahead.near_begin);
    }
    if (i + 4 < end) {
      const Mover& ahead = movers[i + 4];
      const std::uint32_t* n = near_pool + ahead.near_begin;
      for (std::uint32_t k = 0; k < ahead.near_count; ++k) detail::prefetch(&slots_[n[k]]);
    }
    if (i + 2 < end) {
      const Mover& ahead = movers[i + 2];
      const std::uint32_t* n = near_pool + ahead.near_begin;
      for (std::uint32_t k = 0; k < ahead.near_count; ++k) {
        const std::uint32_t p = slots_[n[k]].pos;
        if (p < movers.size()) {
          // The fields read (an 80-byte record often spans two lines;
          // prefetching the shape's second line too cost more than it
          // saved), and the shape.
          detail::prefetch(&movers[p].stamp);
          detail::prefetch(&moving_.shapes[p].center);
        }
      }
    }
    const Handle hm = me.handle();
    const Candidate* c = list_pool + mv.list_begin;
    const Candidate* c_end = c + mv.list_count;
    tests += mv.list_count;
    if (all_live) {
      const Vec3 p = sm.center;
      const double r = sm.half.x;
      const bool sphere = sm.kind == ShapeKind::sphere;
      // Hits are gathered without a branch on the outcome (about half the
      // candidates hit in crowded scenes, which a branch mispredicts), then
      // reported in order. A box mover tests sphere candidates from their
      // copies too, and box candidates are read from the grid entry their
      // radius names: through the slot, and from the grid's shapes for
      // every candidate of a box, shapes-decades 20 000 spent a third of
      // its frame on these lists (perf).
      constexpr std::ptrdiff_t kBatch = 64;
      Handle hits[kBatch];
      while (c != c_end) {
        const Candidate* stop = c + std::min(kBatch, c_end - c);
        std::size_t n = 0;
        for (; c != stop; ++c) {
          if (!detail::admits(emit, me.slot, c->handle.index)) continue;
          hits[n] = c->handle;
          if (c->is_box())
            n += overlaps(sm, fixed_.shapes[c->box_entry()]);
          else if (sphere)
            n += spheres_overlap(p, r, {c->c[0], c->c[1], c->c[2]}, c->r);
          else
            n += sphere_box_overlap({c->c[0], c->c[1], c->c[2]}, c->r, p, sm.half);
        }
        for (std::size_t k = 0; k < n; ++k)
          if (!emit(hm, hits[k])) return false;
      }
    } else {
      for (; c != c_end; ++c) {
        // A fixed object that left has another home (its slot is held back).
        if (slots_[c->handle.index].home != Home::fixed_grid) continue;
        if (!detail::admits(emit, me.slot, c->handle.index)) continue;
        if (exact(sm, fixed_.shapes[slots_[c->handle.index].pos]) && !emit(hm, c->handle))
          return false;
      }
    }
    if (mv.fast) {
      // Pairs with slow movers are this one's to report; of two fast ones,
      // the one first in the order (level, lower x, entry) reports, as in
      // grid_pairs. Levels below its own and the part of its level before
      // it are probed only when they hold slow movers.
      while (level + 1 < moving_.levels.size() && i >= moving_.level_end(level)) ++level;
      const std::size_t own_end = moving_.level_end(level);
      const float me_x = me.lo[0];
      auto test = [&](std::uint32_t k) {
        if (k == i) return true;
        const Entry& o = moving_.entries[k];
        if (movers[k].fast &&
            (k < own_end && (k < moving_.cell_start[moving_.levels[level].first_cell] ||
                             o.lo[0] < me_x || (o.lo[0] == me_x && k < i))))
          return true;
        if (!detail::admits(emit, me.slot, o.slot)) return true;
        ++tests;
        return !exact(sm, moving_.shapes[k]) || emit(hm, o.handle());
      };
      bool go = true;
      for (std::size_t l = 0; go && l < level; ++l)
        if (lists_.slow_on_level(l) > 0) go = moving_.scan_level(mv.cur, l, kNoMinX, test);
      if (go)
        go = moving_.scan_level(mv.cur, level, lists_.slow_on_level(level) > 0 ? kNoMinX : me_x,
                                test);
      for (std::size_t l = level + 1; go && l < moving_.levels.size(); ++l)
        go = moving_.scan_level(mv.cur, l, kNoMinX, test);
      if (!go) return false;
      continue;
    }
    const std::uint32_t* n = near_pool + mv.near_begin;
    const std::uint32_t* n_end = n + mv.near_count;
    for (; n != n_end; ++n) {
      const Slot& o = slots_[*n];
      // A neighbour that left the moving grid is met elsewhere (loose
      // list); one renewed later holds this pair in its own list. A slot
      // reused by another object always carries a later stamp.
      if (o.home != Home::moving_grid || movers[o.pos].fast) continue;
      const std::uint32_t os = movers[o.pos].stamp;
      if (os > mv.stamp || (os == mv.stamp && *n < me.slot)) continue;
      if (!detail::admits(emit, me.slot, *n)) continue;
      ++tests;
      if (exact(sm, moving_.shapes[o.pos]) && !emit(hm, Handle{*n, o.gen})) return false;
    }
  }
  return true;
}

template <class E>
bool GridVerlet::fixed_pairs(E& emit, std::uint64_t& tests) const {
  if (!cache_built_) return grid_pairs(fixed_, 0, fixed_.entries.size(), emit, tests);
  for (const HandlePair& p : fixed_pairs_)
    if (slots_[p.a.index].home == Home::fixed_grid && slots_[p.b.index].home == Home::fixed_grid &&
        !emit(p.a, p.b))
      return false;
  return true;
}

template <class E>
bool GridVerlet::loose_pairs(E& emit, std::uint64_t& tests) const {
  const std::size_t n = loose_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t s = loose_[i];
    const Shape& sh = loose_shapes_[i];
    for (const Grid* g : {&fixed_, &moving_}) {
      if (g == &moving_ && dense_mode_) {
        bool go = true;
        const QueryCost c = dense_->query(sh, [&](Handle d) {
          const Handle o = from_dense(d);
          go = !detail::admits(emit, s, o.index) || emit(handle_of(s), o);
          return go;
        });
        tests += c.tests;
        if (!go) return false;
        continue;
      }
      if (!g->scan(loose_bounds_[i], 0, kNoMinX, [&](std::uint32_t k) {
            if (!detail::admits(emit, s, g->entries[k].slot)) return true;
            ++tests;
            return !overlaps(sh, g->shapes[k]) || emit(handle_of(s), g->entries[k].handle());
          }))
        return false;
    }
  }
  // Loose against loose: a sweep along x (the loose list can hold an eighth
  // of the objects, so testing every two of them would be quadratic).
  if (n < 2) return true;
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(i);
  std::sort(order.begin(), order.end(), [this](std::uint32_t a, std::uint32_t b) {
    const float xa = loose_bounds_[a].lo[0], xb = loose_bounds_[b].lo[0];
    return xa < xb || (xa == xb && a < b);
  });
  for (std::size_t a = 0; a < n; ++a) {
    const std::uint32_t i = order[a];
    const AabbF& q = loose_bounds_[i];
    for (std::size_t b = a + 1; b < n && loose_bounds_[order[b]].lo[0] <= q.hi[0]; ++b) {
      const std::uint32_t j = order[b];
      if (!loose_bounds_[j].overlaps(q) || !detail::admits(emit, loose_[i], loose_[j])) continue;
      ++tests;
      if (overlaps(loose_shapes_[i], loose_shapes_[j]) &&
          !emit(handle_of(loose_[i]), handle_of(loose_[j])))
        return false;
    }
  }
  return true;
}

template <class E>
bool GridVerlet::pairs_without_lists(E& emit, std::uint64_t& tests) const {
  if (!fixed_probes(0, moving_.entries.size(), emit, tests)) return false;
  if (dense_mode_) return dense_pairs(emit, tests);
  return grid_pairs(moving_, 0, moving_.entries.size(), emit, tests);
}

template <class E>
bool GridVerlet::fixed_probes(std::size_t begin, std::size_t end, E& emit,
                              std::uint64_t& tests) const {
  const std::vector<Mover>& movers = lists_.movers();
  for (std::size_t i = begin; i < end; ++i) {
    const Entry& me = moving_.entries[i];
    if (me.dead()) continue;
    // In dense mode the mover is where the dense grid holds it.
    const Handle d = dense_mode_ ? dense_handle_[i] : Handle{};
    const Shape& sm = dense_mode_ ? dense_->shape(d) : moving_.shapes[i];
    const AabbF& box = dense_mode_ ? dense_->bounds_at(d.index) : movers[i].cur;
    const bool go = fixed_.scan(box, 0, kNoMinX, [&](std::uint32_t k) {
      const Entry& o = fixed_.entries[k];
      if (!detail::admits(emit, me.slot, o.slot)) return true;
      ++tests;
      return !exact(sm, fixed_.shapes[k]) || emit(me.handle(), o.handle());
    });
    if (!go) return false;
  }
  return true;
}

template <class E>
bool GridVerlet::dense_pairs(E& emit, std::uint64_t& tests, std::size_t part,
                             std::size_t parts) const {
  bool go = true;
  auto pass = [&](Handle a, Handle b) {
    const Handle ha = from_dense(a), hb = from_dense(b);
    go = !detail::admits(emit, ha.index, hb.index) || emit(ha, hb);
    return go;
  };
  tests += dense_->walk_pairs_part(pass, part, parts).tests;
  return go;
}

template <class E>
bool GridVerlet::all_pairs(E& emit, std::uint64_t& tests) const {
  const std::size_t m = moving_.entries.size();
  if (lists_stale_ || dense_mode_)
    return fixed_pairs(emit, tests) && pairs_without_lists(emit, tests) && loose_pairs(emit, tests);
  return fixed_pairs(emit, tests) && mover_pairs(0, m, emit, tests) && loose_pairs(emit, tests);
}

template <class V>
QueryCost GridVerlet::for_each_pair(V&& visitor) const {
  QueryCost cost;
  auto emit = [&](Handle a, Handle b) { return visit(visitor, a, b); };
  if (unfiltered()) {
    cost.stopped = !all_pairs(emit, cost.tests);
  } else {
    auto gate = gated<true>(emit);
    cost.stopped = !all_pairs(gate, cost.tests);
  }
  return cost;
}

}  // namespace broadphase
