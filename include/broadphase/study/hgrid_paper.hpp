/// \file study/hgrid_paper.hpp
/// `hgrid-paper`: the study's hierarchical hashed grid, made exact.
///
/// Level k (1 ... levels) cuts the world cube into 2^k cells per axis; all
/// levels share one hash table keyed by (level, cell x, y, z). An object
/// goes to the finest level whose cell side is at least four times its
/// largest extent, into the cell of its centre, and is chained into that
/// cell's bucket through per-object `next` and `prev` indices. It remembers
/// the bucket, so removal unlinks it from that one bucket in O(1), however
/// crowded the cell (the study's chains were singly linked, and a walk along
/// a coarse cell's chain costs hundreds of steps at 6400 objects). Cells of
/// the whole integer range exist (the hash is unbounded): objects outside the
/// world sit in cells with negative or large coordinates.
///
/// Exactness: several cells can share a bucket, so each entry keeps its
/// exact cell key and entries of other cells are skipped unseen. A query
/// probes, at each level, the cells whose objects could reach its bounds:
/// the cells of every centre within the bounds widened by the largest reach
/// an object of that level can have, computed with the same monotone
/// formula as the objects' cells, so rounding never drops a candidate.
/// Objects too large for the coarsest level go to an oversize list that is
/// tested against everything; so do objects whose cell coordinates would
/// pass ±2^40. The bounds' slack grows with the distance from the origin, so
/// far objects rise to coarse levels by themselves (centres near 1e300 are
/// oversize by size); the coordinate limit catches a world box placed far
/// from the origin with objects near it.
///
/// Rays march each non-empty level's cells (detail/ray_walk.hpp), coarse to
/// fine, the oversize list first; a box grown on every placement bounds the
/// march.
#pragma once

#include <algorithm>
#include <array>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/clamp_index.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cmath>
#include <cstdint>
#include <vector>

namespace broadphase {

/// The options of HGridPaper (`hgrid-paper:levels=N`).
struct HGridPaperOptions {
  /// Levels below the root, in [1, 30]. Default 10: the finest cells are
  /// 1/1024 of the world.
  int levels = 10;
  /// Throws InvalidConfig for a value out of range.
  void check() const;
  /// Reads options given as text (detail/structure_base.hpp). Throws InvalidConfig.
  static HGridPaperOptions from(const OptionText& text);
};

/// The study's hierarchical hashed grid.
/// insert, update: O(1) expected (amortised: the table doubles when it holds
/// more objects than buckets). remove: O(1).
/// query: the cells within reach at every non-empty level, or one pass over
/// the objects for levels where the query covers more cells than that.
/// for_each_pair: each object probes at most 2 x 2 x 2 cells at its own
/// level and at each coarser non-empty level.
/// Handles stay valid until their object is removed. Not thread-safe for
/// writers; const members may run concurrently.
class HGridPaper : public detail::StoreBase<HGridPaper> {
 public:
  /// The most levels the option `levels=` accepts.
  static constexpr int kMaxLevels = 30;
  /// Default: levels 1 to 10, the finest with cells of 1/1024 of the world.
  static constexpr int kDefaultLevels = 10;

  /// Builds the empty grid over the cube with corner `c.world.lo` and side
  /// the world box's largest extent. The table is sized for
  /// `c.expected_objects`.
  using Options = HGridPaperOptions;
  /// Reads the deprecated Config::options map into HGridPaperOptions.
  /// Throws InvalidConfig.
  explicit HGridPaper(const Config& c = {})
      : HGridPaper(without_options(c), HGridPaperOptions::from(c.options)) {}
  /// Throws InvalidConfig for a bad `c` (check_config) or `o` (HGridPaperOptions::check).
  HGridPaper(const Config& c, const HGridPaperOptions& o);

  /// Adds an object to its level and cell. Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic);
  /// Removes an object from its remembered bucket in O(1). Throws InvalidHandle.
  void remove(Handle h);
  /// Replaces an object's shape; O(1) when its level and cell stay the same.
  /// Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s);

  /// Visits every object whose shape overlaps `q` exactly.
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const;

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters): every overlapping pair exactly once.
  template <class V>
  QueryCost walk_pairs(V& visitor) const;

  /// Casts a ray (HasRayCast): the oversize objects, then a march through
  /// each non-empty level's cells, coarsest first, over the part of the ray
  /// inside the box of every object placed (each object tested once). Per
  /// level O(cells passed + candidates), never more than about a scan of
  /// the objects; a level whose cells the march's 32-bit keys cannot hold
  /// (objects near 2^30 cells from the world) is scanned. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const;

  /// The store, the per-object entries and remembered buckets, the bucket
  /// heads and the oversize list, by capacity.
  std::size_t memory_bytes() const;

  /// Checks that every live object is in exactly one list (its bucket's
  /// chain or the oversize list), at the level and cell its shape
  /// prescribes, that chains have no cycles and that the counts agree.
  /// Throws std::logic_error.
  void validate() const;
  /// Reports every occupied cell: its box, its level (1: the finest), the
  /// objects whose centre it holds (an object reaches at most half a cell
  /// beyond). Oversize objects are in no cell. O(objects log cells).
  void visit_cells(CellVisitor visitor) const;

  /// The number of levels (level 1 is the coarsest).
  int levels() const { return levels_; }
  /// The cell side of level `k` in 1 ... levels().
  double cell_side(int k) const { return side_[static_cast<std::size_t>(k)]; }
  /// The level an object of shape `s` goes to, or 0 for the oversize list.
  int level_of(const Shape& s) const { return place(s).level; }
  /// The level of a live object (0: oversize). Throws InvalidHandle.
  int level_of(Handle h) const { return entry_[store_.index_of(h)].level; }
  /// The objects in the oversize list.
  std::size_t oversize_count() const { return oversize_.size(); }
  /// The number of hash buckets.
  std::size_t bucket_count() const { return head_.size(); }

 private:
  static constexpr std::uint32_t kNull = 0xffffffffu;

  // Per object: its exact cell, the next object of its bucket, its level
  // (0: oversize). 32 bytes, so an entry never straddles two cache lines.
  struct Entry {
    std::int64_t cell[3];
    std::uint32_t next;
    std::uint8_t level;
  };
  static_assert(sizeof(Entry) == 32);

  struct Placement {
    int level;
    std::int64_t cell[3];
  };
  // The cells a probe visits at one level, with their count.
  struct CellBox {
    std::int64_t lo[3];
    std::int64_t hi[3];
    double volume;
  };

  double cell_coord(double v, int axis, int level) const {
    return std::floor((v - origin_[axis]) * inv_side_[static_cast<std::size_t>(level)]);
  }
  int level_for_extent(double extent) const;
  Placement place(const Shape& s) const;
  CellBox probe_box(const Aabb& b, int level) const;
  std::uint32_t bucket_of(int level, const std::int64_t* cell) const;
  // Allocates what linking `i` at `p` needs; link() then cannot fail.
  void make_room(std::uint32_t i, const Placement& p);
  void link(std::uint32_t i, const Placement& p);
  void unlink(std::uint32_t i);
  void push_front(std::uint32_t bucket, std::uint32_t i);
  void grow_table();

  // Calls f(j) for each object j in the cells of `box` at `level`; stops
  // when f returns false.
  template <class F>
  bool probe(int level, const CellBox& box, F& f) const;
  // The same-level half of the pair search for object `i`: the cells of
  // `box` after i's own cell in (z, y, x) order, and in its own cell the
  // objects chained after i. Two overlapping objects of one level each lie
  // in the other's probe box, so their pair is taken once, from the earlier
  // cell, or from the earlier entry of a shared cell.
  template <class F>
  bool probe_forward(std::uint32_t i, const CellBox& box, F& f) const;

  std::vector<Entry> entry_;         // by slot index
  std::vector<std::uint32_t> slot_;  // by slot index: its bucket, or its place in oversize_
  std::vector<std::uint32_t> prev_;  // by slot index: the previous object of its bucket, or kNull
  std::vector<std::uint32_t> head_;  // bucket -> first object, or kNull
  std::vector<std::uint32_t> oversize_;                // objects tested against everything
  detail::OccupiedBox occupied_;                       // holds every object in a bucket (rays)
  std::array<std::uint32_t, kMaxLevels + 1> count_{};  // objects per level (0: oversize)
  std::size_t in_table_ = 0;                           // objects chained in buckets
  std::uint64_t mask_ = 0;                             // head_.size() - 1
  int levels_ = kDefaultLevels;
  Vec3 origin_;
  std::array<double, kMaxLevels + 1> side_{};      // cell side per level
  std::array<double, kMaxLevels + 1> inv_side_{};  // cells per world unit per level
  std::array<double, kMaxLevels + 1> reach_{};  // how far an object's bounds reach from its centre
};

template <class F>
bool HGridPaper::probe(int level, const CellBox& box, F& f) const {
  std::int64_t cell[3];
  for (cell[2] = box.lo[2]; cell[2] <= box.hi[2]; ++cell[2])
    for (cell[1] = box.lo[1]; cell[1] <= box.hi[1]; ++cell[1])
      for (cell[0] = box.lo[0]; cell[0] <= box.hi[0]; ++cell[0])
        for (std::uint32_t j = head_[bucket_of(level, cell)]; j != kNull; j = entry_[j].next) {
          const Entry& e = entry_[j];
          if (e.level != level || e.cell[0] != cell[0] || e.cell[1] != cell[1] ||
              e.cell[2] != cell[2])
            continue;  // another cell hashed to the same bucket
          if (!f(j)) return false;
        }
  return true;
}

template <class F>
bool HGridPaper::probe_forward(std::uint32_t i, const CellBox& box, F& f) const {
  const Entry& own = entry_[i];
  std::int64_t cell[3];
  for (cell[2] = std::max(box.lo[2], own.cell[2]); cell[2] <= box.hi[2]; ++cell[2])
    for (cell[1] = box.lo[1]; cell[1] <= box.hi[1]; ++cell[1])
      for (cell[0] = box.lo[0]; cell[0] <= box.hi[0]; ++cell[0]) {
        int order = 0;  // of this cell against the own cell, z most significant
        for (int a = 2; a >= 0 && order == 0; --a)
          order = cell[a] < own.cell[a] ? -1 : (cell[a] > own.cell[a] ? 1 : 0);
        if (order < 0) continue;
        for (std::uint32_t j = order == 0 ? own.next : head_[bucket_of(own.level, cell)];
             j != kNull; j = entry_[j].next) {
          const Entry& e = entry_[j];
          if (e.level != own.level || e.cell[0] != cell[0] || e.cell[1] != cell[1] ||
              e.cell[2] != cell[2])
            continue;
          if (!f(j)) return false;
        }
      }
  return true;
}

template <class V>
QueryCost HGridPaper::query(const Shape& q, V&& visitor) const {
  require_valid(q);
  QueryCost cost;
  auto test = [&](std::uint32_t j) {
    ++cost.tests;
    return !overlaps(q, store_.shape(j)) || visit(visitor, store_.handle(j));
  };
  for (std::uint32_t j : oversize_)
    if (!test(j)) {
      cost.stopped = true;
      return cost;
    }
  const Aabb qb = bounds(q);
  // Probing a cell costs a hash and a random access, scanning an object one
  // sequential step: a level whose probe box holds more cells than a
  // quarter of the slots is scanned instead, all such levels in one pass.
  const double probe_limit = static_cast<double>(store_.slot_count()) / 4 + 16;
  std::uint32_t scan_levels = 0;
  for (int k = 1; k <= levels_; ++k) {
    if (count_[static_cast<std::size_t>(k)] == 0) continue;
    const CellBox box = probe_box(qb, k);
    if (box.volume > probe_limit) {
      scan_levels |= 1u << k;
    } else if (!probe(k, box, test)) {
      cost.stopped = true;
      return cost;
    }
  }
  if (scan_levels != 0) {
    for (std::uint32_t j = 0; j < store_.slot_count(); ++j)
      if (store_.slots().alive(j) && ((scan_levels >> entry_[j].level) & 1u) != 0 && !test(j)) {
        cost.stopped = true;
        return cost;
      }
  }
  return cost;
}

template <class V>
QueryCost HGridPaper::cast_ray(const Ray& r, V&& visitor) const {
  auto box_of = [&](std::uint32_t j) { return bounds_f(store_.shape(j)); };
  return detail::ray_grid_cast(
      store_, r, visitor, oversize_, box_of, [&](auto& cast, detail::RaySlots& tested) {
        if (occupied_.empty()) return;
        // Probing a cell costs a hash and a chain, scanning an object one
        // sequential step: as query's limit.
        const double budget = static_cast<double>(store_.slot_count()) / 4 + 16;
        // Coarsest first: its large objects, hit early, clip the ray for the
        // finer levels (1 460 rays/s against 1 210 finest first, 10^5
        // spheres, random rays).
        for (int k = 1; k <= levels_; ++k) {
          const auto level = static_cast<std::size_t>(k);
          if (count_[level] == 0) continue;
          constexpr double kKeyLimit = 0x1p30;  // as CellMap's clamp
          auto coord = [&](double x, int a) {
            return detail::clamp_floor<std::int32_t>((x - origin_[a]) * inv_side_[level],
                                                     -kKeyLimit, kKeyLimit);
          };
          detail::RayGridLevel l;
          l.origin = origin_;
          l.cell = side_[level];
          bool fits = true;  // every object's cell strictly inside the clamp
          for (int a = 0; a < 3; ++a) {
            l.index_lo[a] = 0;
            l.index_hi[a] = std::ldexp(1.0, k) - 1;
            fits = fits && coord(occupied_.box.lo[a], a) > -kKeyLimit &&
                   coord(occupied_.box.hi[a], a) < kKeyLimit;
          }
          l.reach = reach_[level];
          const bool go = detail::ray_level_cast(
              cast, tested, l, fits ? budget : -1, &occupied_, coord,
              [&](const detail::CellKey& c, auto&& f) {
                const std::int64_t cell[3] = {c.c[0], c.c[1], c.c[2]};
                for (std::uint32_t j = head_[bucket_of(k, cell)]; j != kNull; j = entry_[j].next) {
                  const Entry& e = entry_[j];
                  if (e.level == k && e.cell[0] == cell[0] && e.cell[1] == cell[1] &&
                      e.cell[2] == cell[2] && !f(j))
                    return false;
                }
                return true;
              },
              [&](auto&& f) {
                for (std::uint32_t j = 0; j < store_.slot_count(); ++j)
                  if (store_.slots().alive(j) && entry_[j].level == k && !f(j)) return false;
                return true;
              },
              box_of);
          if (!go) return;
        }
      });
}

template <class V>
QueryCost HGridPaper::walk_pairs(V& visitor) const {
  QueryCost cost;
  const std::uint32_t slots = store_.slot_count();
  for (std::uint32_t i = 0; i < slots; ++i) {
    if (!store_.slots().alive(i)) continue;
    const int level = entry_[i].level;
    if (level == 0) continue;
    const Shape& si = store_.shape(i);
    const Aabb bi = bounds(si);
    // Partners at the same level are taken from one side only (see
    // probe_forward); partners at coarser levels never probe finer ones, so
    // they are found from this side only.
    auto test = [&](std::uint32_t j) {
      if (!detail::admits(visitor, i, j)) return true;
      ++cost.tests;
      return !overlaps(si, store_.shape(j)) || visit(visitor, store_.handle(i), store_.handle(j));
    };
    if (!probe_forward(i, probe_box(bi, level), test)) {
      cost.stopped = true;
      return cost;
    }
    for (int k = level - 1; k >= 1; --k) {
      if (count_[static_cast<std::size_t>(k)] == 0) continue;
      if (!probe(k, probe_box(bi, k), test)) {
        cost.stopped = true;
        return cost;
      }
    }
  }
  for (std::size_t p = 0; p < oversize_.size(); ++p) {
    const std::uint32_t i = oversize_[p];
    const Shape& si = store_.shape(i);
    auto test = [&](std::uint32_t j) {
      if (!detail::admits(visitor, i, j)) return true;
      ++cost.tests;
      return !overlaps(si, store_.shape(j)) || visit(visitor, store_.handle(i), store_.handle(j));
    };
    for (std::size_t r = p + 1; r < oversize_.size(); ++r)
      if (!test(oversize_[r])) {
        cost.stopped = true;
        return cost;
      }
    for (std::uint32_t j = 0; j < slots; ++j)
      if (store_.slots().alive(j) && entry_[j].level != 0 && !test(j)) {
        cost.stopped = true;
        return cost;
      }
  }
  return cost;
}

}  // namespace broadphase
