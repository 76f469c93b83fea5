/// \file grid_static.hpp
/// `grid-static`: a uniform grid whose cell contents sit in one contiguous
/// array per population (cell start offsets + entries, built by counting
/// sort over hashed cells), the layout of a static grid, kept up to date
/// under motion by rebuilding or patching.
///
/// Layout: cells hash into B buckets (B a power of two, about the number of
/// entries); a bucket's entries are contiguous, each entry the exact cell
/// key and the object's slot with its offset mask (so bucket collisions
/// never mix cells, and the "lowest shared cell" rule needs no lookup).
/// Each bucket keeps some free slots after its entries so that a moved
/// object can be patched in place.
///
/// Two populations, following the Motion hint: objects inserted as
/// Motion::fixed live in their own table and their overlapping pairs with
/// each other are found once, on insertion, and kept in a pair list; each
/// frame then only looks for pairs involving a dynamic (or overflowing)
/// object. A fixed object that is updated becomes dynamic (its cached pairs
/// are dropped, O(cached pairs)). `fixed=plain` treats every object alike.
///
/// Policies for moves (`policy=`): `rebuild` re-packs the dynamic table by
/// counting sort once per update call (once per batch with the bulk
/// update); `patch` moves only the entries of objects whose cells changed,
/// falling back to a rebuild when a bucket has no free slot; `auto` (the
/// default) patches when few objects changed cells and rebuilds otherwise.
#pragma once

#include <broadphase/config_error.hpp>
#include <broadphase/detail/grid_common.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <span>
#include <utility>
#include <vector>

namespace broadphase {

/// How moved objects reach a GridStatic's dynamic table (option `policy`).
enum class GridStaticPolicy : std::uint8_t { rebuild, patch, automatic };

/// The options of GridStatic (`grid-static:cell=E,policy=P,fixed=cache|plain`).
struct GridStaticOptions {
  /// Cell edge in world units, in [1e-300, 1e300]; 0 (default): chosen from
  /// the world and the population.
  double cell = 0;
  /// How moved objects reach the dynamic table. Default automatic.
  GridStaticPolicy policy = GridStaticPolicy::automatic;
  /// Whether the pairs among fixed objects are cached (`fixed=cache`,
  /// default) or found each pass (`fixed=plain`).
  bool cache_fixed = true;
  /// Throws InvalidConfig for a value out of range (detail/structure_base.hpp).
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static GridStaticOptions from(const OptionText& text);
};

/// A uniform grid with contiguous cell contents.
/// insert: O(1) amortised (a fixed object also finds its fixed neighbours
/// once). remove: O(1) for dynamic objects, O(cached pairs) for fixed ones.
/// update: O(1) with `patch` when the cells did not change, else O(cells of
/// the object) or a rebuild O(entries + buckets); bulk update: at most one
/// rebuild per batch. query: O(cells covered + candidates). for_each_pair:
/// O(buckets + cached pairs + candidate pairs involving dynamic objects).
/// Memory: O(n). Options: `cell=`, `policy=rebuild|patch|auto`,
/// `fixed=cache|plain`. Handles stay valid until their object is removed.
/// Const members may run concurrently; mutations need exclusive access.
class GridStatic : public detail::StoreBase<GridStatic> {
 public:
  /// How moved objects reach the dynamic table.
  using Policy = GridStaticPolicy;

  using Options = GridStaticOptions;
  /// Reads the deprecated Config::options map into GridStaticOptions.
  /// Throws InvalidConfig.
  explicit GridStatic(const Config& c = {})
      : GridStatic(without_options(c), GridStaticOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (GridStaticOptions::check).
  GridStatic(const Config& c, const GridStaticOptions& o);

  /// Adds an object; `Motion::fixed` puts it in the fixed population
  /// (unless `fixed=plain`). Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion m = Motion::dynamic);
  /// Removes an object. Throws InvalidHandle.
  void remove(Handle h);
  /// Moves an object (a fixed one becomes dynamic). Throws InvalidHandle,
  /// InvalidShape.
  void update(Handle h, const Shape& s);
  /// Moves many objects with at most one rebuild. Every handle and shape is
  /// checked before anything changes. Throws InvalidHandle, InvalidShape.
  void update(std::span<const Move> moves);
  /// Changes an object's filter (HasFilters) and, for a fixed object,
  /// re-caches its fixed pairs: the cache holds only pairs that pass.
  /// Throws InvalidHandle. O(cells of the object + its cached pairs).
  void set_filter(Handle h, Filter f);
  /// Installs or removes the pair filter and re-caches every fixed pair.
  /// O(fixed objects' candidates).
  void set_pair_filter(PairFilter pf);

  /// Casts a ray (HasRayCast): the overflowing objects, then a march
  /// through the cells the ray passes (detail/ray_walk.hpp) over both
  /// tables, each object tested once. O(cells passed + candidates), and
  /// never more than about a scan of every object. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    auto box_of = [&](std::uint32_t b) -> const AabbF& { return box_[b]; };
    return detail::ray_grid_cast(
        store_, r, visitor, overflow_, box_of, [&](auto& cast, detail::RaySlots& tested) {
          const double budget = 2.0 * static_cast<double>(store_.size() - overflow_.size()) + 64;
          detail::ray_level_cast(
              cast, tested, detail::ray_level(map_), budget, &occupied_,
              [&](double x, int a) { return map_.coord(x, a); },
              [&](const detail::CellKey& c, auto&& f) {
                const std::size_t k = bucket_of(c);
                for (const Table* t : {&fixed_, &dyn_}) {
                  const Entry* e = t->entries.data() + t->start[k];
                  for (std::uint32_t j = 0; j < t->count[k]; ++j)
                    if (e[j].key == c && !f(e[j].tag >> 3)) return false;
                }
                return true;
              },
              [&](auto&& f) {
                for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
                  if (kind_[b] != kDead && where_[b] == detail::kNone && !f(b)) return false;
                return true;
              },
              box_of);
        });
  }

  /// Visits every object overlapping `q`.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    const AabbF qb = bounds_f(q);
    const bool go = visit_region(map_.range(qb), 3, [&](std::uint32_t b) {
      return detail::test_query(store_, box_.data(), q, qb, b, cost, visitor);
    });
    if (!go) return cost;
    for (std::uint32_t b : overflow_)
      if (!detail::test_query(store_, box_.data(), q, qb, b, cost, visitor)) return cost;
    return cost;
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): the cached fixed pairs (which hold only pairs that pass the
  /// filters), then per bucket the dynamic-dynamic and dynamic-fixed
  /// candidates, then the overflowing objects.
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    QueryCost cost;
    for (const auto& [a, b] : fixed_pairs_) {
      if (!visit(visitor, store_.handle(a), store_.handle(b))) {
        cost.stopped = true;
        return cost;
      }
    }
    const AabbF* box = box_.data();
    const Entry* de = dyn_.entries.data();
    const Entry* fe = fixed_.entries.data();
    const AabbF* fbox = fixed_.boxes.data();
    const std::size_t buckets = dyn_.count.size();
    for (std::size_t k = 0; k < buckets; ++k) {
      const std::uint32_t dn = dyn_.count[k];
      if (dn == 0) continue;
      const Entry* d = de + dyn_.start[k];
      for (std::uint32_t i = 0; i + 1 < dn; ++i)
        for (std::uint32_t j = i + 1; j < dn; ++j)
          if (d[i].key == d[j].key && (d[i].tag & d[j].tag & 7u) == 0 &&
              !detail::test_pair(store_, box, d[i].tag >> 3, d[j].tag >> 3, cost, visitor))
            return cost;
      // Fixed entries carry their bounds, so this loop reads one contiguous
      // segment per dynamic entry.
      const std::uint32_t fn = fixed_.count[k];
      if (fn == 0) continue;
      const Entry* f = fe + fixed_.start[k];
      const AabbF* fb = fbox + fixed_.start[k];
      for (std::uint32_t i = 0; i < dn; ++i) {
        const std::uint32_t a = d[i].tag >> 3;
        const AabbF ab = box[a];
        // Fixed segments are sorted by low x: stop at the first that starts
        // after this box ends.
        for (std::uint32_t j = 0; j < fn && fb[j].lo[0] <= ab.hi[0]; ++j) {
          if (!(d[i].key == f[j].key) || (d[i].tag & f[j].tag & 7u) != 0 || !ab.overlaps(fb[j]))
            continue;
          const std::uint32_t b = f[j].tag >> 3;
          if (!detail::admits(visitor, a, b)) continue;
          ++cost.tests;
          if (overlaps(store_.shape(a), store_.shape(b)) &&
              !visit(visitor, store_.handle(a), store_.handle(b))) {
            cost.stopped = true;
            return cost;
          }
        }
      }
    }
    for (std::size_t p = 0; p < overflow_.size(); ++p) {
      const std::uint32_t o = overflow_[p];
      // A fixed overflowing object meets fixed objects through the cache.
      const unsigned tables = kind_[o] == kFixed ? 2u : 3u;
      const bool go = visit_region(range_[o], tables, [&](std::uint32_t b) {
        return detail::test_pair(store_, box, o, b, cost, visitor);
      });
      if (!go) return cost;
      for (std::size_t q = p + 1; q < overflow_.size(); ++q) {
        const std::uint32_t b = overflow_[q];
        if (kind_[o] == kFixed && kind_[b] == kFixed) continue;
        if (!detail::test_pair(store_, box, o, b, cost, visitor)) return cost;
      }
    }
    return cost;
  }

  /// Bytes held: store, per-object arrays, both tables, the pair cache.
  std::size_t memory_bytes() const;
  /// The cell edge in use.
  double cell_size() const { return map_.cell(); }
  /// Times a table was re-packed from scratch (for the policy measurements).
  std::uint64_t rebuilds() const { return rebuilds_; }
  /// Overlapping fixed pairs currently cached.
  std::size_t cached_pairs() const { return fixed_pairs_.size(); }
  /// Objects covering more than kMaxCells cells.
  std::size_t overflow_count() const { return overflow_.size(); }

  /// Checks bounds, ranges, both tables entry by entry, the overflow list
  /// and that the pair cache holds exactly the overlapping fixed pairs.
  void validate() const;
  /// Reports every occupied cell (level 0) with the objects whose bounds touch
  /// it, fixed and dynamic alike. Overflow objects are in no cell.
  /// O(entries log cells).
  void visit_cells(CellVisitor visitor) const;

  /// Objects covering more cells than this go to the overflow list.
  static constexpr double kMaxCells = 64;

 private:
  struct Entry {
    detail::CellKey key;
    std::uint32_t tag;  // slot << 3 | offset mask of the key in the slot's range
  };
  enum Kind : std::uint8_t { kDead = 0, kFixed = 1, kDynamic = 2 };
  // One bucket table; `kind` says which population it holds. The fixed
  // table also keeps every entry's box beside it, each bucket sorted by low
  // x, and is packed tighter (it changes only on insert and remove).
  struct Table {
    explicit Table(Kind k) : kind(k) {}
    Kind kind;                         // kFixed or kDynamic, set once
    std::vector<Entry> entries;        // per bucket: count live entries, then free slots
    std::vector<AabbF> boxes;          // beside entries, fixed table only, sorted by low x
    std::vector<std::uint32_t> start;  // per bucket, plus the end
    std::vector<std::uint32_t> count;  // per bucket
    bool dirty = false;                // entries are stale until the end of the current mutation
    bool sorted() const { return kind == kFixed; }             // keeps boxes, sorted by low x
    unsigned bit() const { return kind == kFixed ? 1u : 2u; }  // in visit_region's mask
  };

  std::size_t bucket_of(const detail::CellKey& k) const {
    return static_cast<std::size_t>(detail::hash_cell(k) >> shift_);
  }
  Table& table_of(std::uint32_t i) { return kind_[i] == kFixed ? fixed_ : dyn_; }

  // Calls f(b) once for each object b of the selected tables (bit 1: fixed,
  // bit 2: dynamic) whose range meets `r`, in the lowest corner of the two
  // ranges' intersection; scans the objects when `r` is very large.
  template <class F>
  bool visit_region(const detail::CellRange& r, unsigned tables, F&& f) const {
    const std::size_t in_tables = store_.size() - overflow_.size();
    if (r.cells() > 2.0 * static_cast<double>(in_tables) + 8) {
      for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
        if (kind_[b] != kDead && where_[b] == detail::kNone && ((tables >> (kind_[b] - 1)) & 1u) &&
            !f(b))
          return false;
      return true;
    }
    detail::CellKey c;
    for (c.c[2] = r.lo[2]; c.c[2] <= r.hi[2]; ++c.c[2])
      for (c.c[1] = r.lo[1]; c.c[1] <= r.hi[1]; ++c.c[1])
        for (c.c[0] = r.lo[0]; c.c[0] <= r.hi[0]; ++c.c[0]) {
          const unsigned rm = detail::offset_mask(r, c);
          const std::size_t k = bucket_of(c);
          for (const Table* t : {&fixed_, &dyn_}) {
            if ((tables & t->bit()) == 0) continue;
            const Entry* e = t->entries.data() + t->start[k];
            for (std::uint32_t j = 0; j < t->count[k]; ++j)
              if (e[j].key == c && (e[j].tag & rm) == 0 && !f(e[j].tag >> 3)) return false;
          }
        }
    return true;
  }

  void move_one(std::uint32_t i, const AabbF& b, bool patch);
  void attach(std::uint32_t i, bool patch);
  void detach(std::uint32_t i, bool patch);
  bool add_entries(Table& t, std::uint32_t i);
  void remove_entries(Table& t, std::uint32_t i);
  void rebuild(Table& t);
  void finish_mutation();
  // Caches i's overlapping fixed pairs that pass the filters, with the
  // fixed objects below slot `below` only (all of them by default).
  void cache_pairs_of(std::uint32_t i, std::uint32_t below = ~std::uint32_t{0});
  void drop_pairs_of(std::uint32_t i);
  void regrid(double cell);
  void grow_slots(std::uint32_t i);

  std::vector<AabbF> box_;
  std::vector<detail::CellRange> range_;
  std::vector<Kind> kind_;
  std::vector<std::uint32_t> where_;   // position in overflow_, or kNone
  std::vector<std::uint32_t> degree_;  // cached pairs per fixed object
  std::vector<std::uint32_t> overflow_;
  detail::OccupiedBox occupied_;  // holds every box entered in a table (rays)
  std::vector<std::pair<std::uint32_t, std::uint32_t>> fixed_pairs_;
  Table fixed_{kFixed}, dyn_{kDynamic};
  detail::CellMap map_;
  Vec3 origin_;
  int shift_ = 58;
  Policy policy_ = Policy::automatic;
  bool cache_fixed_ = true;
  std::uint64_t rebuilds_ = 0;
  std::size_t entries_total_ = 0;  // entries the tables should hold
  detail::RegridTrigger trigger_;
};

}  // namespace broadphase
