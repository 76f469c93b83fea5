/// \file detail/linked_grid.hpp
/// `detail::LinkedGrid`, the engine of `grid-dense`, `grid-hashed` and
/// `grid-hybrid`: cells, each the head of a doubly linked list whose links
/// live in per-object arrays (eight links per object, one per cell it may
/// touch). The three differ only in how a cell finds its list head and
/// whether a list is kept sorted; grid_dense.hpp describes the placement.
#pragma once

#include <bit>
#include <broadphase/config_error.hpp>
#include <broadphase/detail/cell_tally.hpp>
#include <broadphase/detail/grid_common.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/detail/structure_base.hpp>
#include <broadphase/structure.hpp>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace broadphase {
namespace detail {

/// The linked-list grid behind grid-dense (kHashed = false: cells are
/// array entries), grid-hashed (kHashed = true: cells hash into a bucket
/// table, each link's exact cell is recomputed from its object's range so
/// bucket collisions never mix cells) and grid-hybrid (kSorted = true: each
/// bucket's list is kept sorted by the low x of the bounds and swept, and
/// cells are `cell_scale` times the automatic size).
template <bool kHashed, bool kSorted = false>
class LinkedGrid : public StoreBase<LinkedGrid<kHashed, kSorted>> {
 public:
  /// A grid of cells of edge `cell` (0: automatic), and when hashed of
  /// `buckets` heads (0: automatic); both already checked by the options
  /// struct of the structure named `name`. Throws InvalidConfig for a bad `c`.
  LinkedGrid(const Config& c, const char* name, double cell, std::size_t buckets,
             double cell_scale = 1)
      : name_(name), world_(check_config(c, name).world), cell_scale_(cell_scale) {
    if constexpr (kHashed) {
      forced_buckets_ = buckets > 0;
      const std::size_t want =
          forced_buckets_ ? buckets : std::max<std::size_t>(c.expected_objects, 64);
      heads_.assign(std::bit_ceil(want), kNone);
    }
    if (cell > 0) {
      trigger_.forced = true;
      set_cell(cell, std::max<std::size_t>(c.expected_objects, 1));
    } else {
      set_cell(cell_scale_ * initial_cell_size(c), std::max<std::size_t>(c.expected_objects, 1));
    }
  }

  /// Adds an object: O(1) amortised (a re-grid, O(n), happens each time the
  /// population doubles when the cell size is automatic). Throws InvalidShape.
  Handle insert(const Shape& s, std::uint64_t user, Motion = Motion::dynamic) {
    if (store_.slot_count() >= (1u << 29)) throw std::length_error(std::string(name_) + ": full");
    const Handle h = store_.insert(s, user);
    const std::uint32_t i = h.index;
    if (i >= box_.size()) {
      box_.resize(i + 1);
      range_.resize(i + 1);
      kmask_.resize(i + 1, 0);
      where_.resize(i + 1, kNone);
      next_.resize(8 * std::size_t{i + 1}, kNone);
      prev_.resize(8 * std::size_t{i + 1}, kNone);
    }
    box_[i] = bounds_f(s);
    place(i);
    after_count_change();
    return h;
  }

  /// Removes an object: O(1) (plus a rare re-grid). Throws InvalidHandle.
  void remove(Handle h) {
    const std::uint32_t i = store_.index_of(h);
    lift(i);
    store_.erase(h);
    after_count_change();
  }

  /// Moves an object: O(1); only the bounds change when it stays in the same
  /// cells. Throws InvalidHandle, InvalidShape.
  void update(Handle h, const Shape& s) {
    const std::uint32_t i = store_.set_shape(h, s);
    const AabbF b = bounds_f(s);
    const CellRange r = map_.range(b);
    if (kmask_[i] != 0 && r == range_[i]) {
      box_[i] = b;
      occupied_.add(b);
      if constexpr (kSorted) resort(i);
      return;
    }
    lift(i);
    box_[i] = b;
    place(i);
  }

  /// update(h, s) in two halves, for many moves on several threads (not
  /// for the sorted grid). stage_update stores the shape and its bounds
  /// `b`; when the object stays in the same cells it also takes the
  /// bounds (adding them to `grown`, which the caller hands to cover()
  /// before any other call) and returns true: the move is made. Otherwise
  /// it returns false, and relink(h, b) makes the move, on one thread.
  /// Distinct objects may be staged at once, each thread with its own
  /// `grown` (no list or shared state is written). The handle must be live
  /// (unchecked). Relinks in the order of the moves leave the lists as
  /// update() would.
  bool stage_update(Handle h, const Shape& s, AabbF& b, OccupiedBox& grown) requires(!kSorted) {
    const std::uint32_t i = h.index;
    b = bounds_f(s);
    store_.set_shape(h, s);
    if (kmask_[i] == 0 || !(map_.range(b) == range_[i])) return false;
    box_[i] = b;
    grown.add(b);
    return true;
  }
  /// Takes in the bounds stage_update gathered in `grown`.
  void cover(const OccupiedBox& grown) {
    if (!grown.empty()) occupied_.add(grown.box);
  }
  /// Makes a staged move that changes cells.
  void relink(Handle h, const AabbF& b) requires(!kSorted) {
    lift(h.index);
    box_[h.index] = b;
    place(h.index);
  }

  /// Visits every object overlapping `q`. O(cells of q + candidates).
  template <class V>
  QueryCost query(const Shape& q, V&& visitor) const {
    require_valid(q);
    QueryCost cost;
    const AabbF qb = bounds_f(q);
    const bool go = visit_region(map_.range(qb), [&](std::uint32_t b) {
      return test_query(store_, box_.data(), q, qb, b, cost, visitor);
    });
    if (!go) return cost;
    for (std::uint32_t b : overflow_)
      if (!test_query(store_, box_.data(), q, qb, b, cost, visitor)) return cost;
    return cost;
  }

  /// Casts a ray (HasRayCast): the overflowing objects, then a march
  /// through the cells the ray passes (detail/ray_walk.hpp), each object
  /// tested once. O(cells passed + candidates), and never more than about
  /// a scan of every object. Throws InvalidRay.
  template <class V>
  QueryCost cast_ray(const Ray& r, V&& visitor) const {
    auto box_of = [&](std::uint32_t b) -> const AabbF& { return box_[b]; };
    return ray_grid_cast(store_, r, visitor, overflow_, box_of, [&](auto& cast, RaySlots& tested) {
      const double budget = 2.0 * static_cast<double>(store_.size() - overflow_.size()) + 64;
      ray_level_cast(
          cast, tested, ray_level(map_), budget, &occupied_,
          [&](double x, int a) { return map_.coord(x, a); },
          [&](const CellKey& c, auto&& f) {
            for (std::uint32_t m = heads_[bucket_of(c)]; m != kNone; m = next_[m]) {
              const std::uint32_t b = m >> 3;
              if constexpr (kHashed) {
                if (!(key_of(range_[b], m & 7u) == c)) continue;  // another cell, same bucket
              }
              if (!f(b)) return false;
            }
            return true;
          },
          [&](auto&& f) {
            for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
              if (kmask_[b] != 0 && !f(b)) return false;
            return true;
          },
          box_of);
    });
  }

  /// The pair walk behind for_each_pair (StoreBase, which attaches the
  /// filters). Each cell's (or bucket's) list is
  /// copied once into a small contiguous buffer, so the quadratic part of
  /// the pass reads contiguous memory instead of chasing links; a pair is
  /// kept only in its lowest shared cell. Lists longer than the buffer are
  /// walked in place.
  template <class V>
  QueryCost walk_pairs(V& visitor) const {
    return walk_pairs_part(visitor, 0, 1);
  }
  /// Part `part` of `parts` of walk_pairs: the pairs of a contiguous range
  /// of the cells (the overflowing objects' with the last), in the same
  /// order. The parts, one after another, report what walk_pairs does;
  /// they may run at once.
  template <class V>
  QueryCost walk_pairs_part(V& visitor, std::size_t part, std::size_t parts) const {
    const std::size_t begin = heads_.size() * part / parts;
    const std::size_t end = heads_.size() * (part + 1) / parts;
    if constexpr (kSorted) {
      return sweep_pairs(visitor, begin, end, part + 1 == parts);
    } else {
      return gather_pairs(visitor, begin, end, part + 1 == parts);
    }
  }

  /// Bytes held: object store, per-object bounds, ranges and links, cell heads.
  std::size_t memory_bytes() const {
    return store_.memory_bytes() + box_.capacity() * sizeof(AabbF) +
           range_.capacity() * sizeof(CellRange) + kmask_.capacity() +
           (where_.capacity() + next_.capacity() + prev_.capacity() + heads_.capacity() +
            overflow_.capacity()) *
               sizeof(std::uint32_t);
  }
  /// The float bounds of the live object in slot `i` (its handle's index).
  const AabbF& bounds_at(std::uint32_t i) const { return box_[i]; }
  /// The cell edge in use.
  double cell_size() const { return map_.cell(); }
  /// Objects that span more than two cells on some axis.
  std::size_t overflow_count() const { return overflow_.size(); }
  /// Number of cells (grid-dense) or buckets (grid-hashed).
  std::size_t cell_count() const { return heads_.size(); }

  /// Checks bounds, ranges, link masks, list links and the overflow list.
  void validate() const {
    const auto fail = this->validate_store(name_);
    std::size_t links = 0;
    for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
      if (!store_.slots().alive(i)) {
        if (kmask_[i] != 0 || where_[i] != kNone) fail("a free slot is still in the grid");
        continue;
      }
      const AabbF b = bounds_f(store_.shape(i));
      if (std::memcmp(&b, &box_[i], sizeof b) != 0) fail("stale bounds");
      if (!(map_.range(b) == range_[i])) fail("stale cell range");
      if (!occupied_.holds(b)) fail("an object outside the occupied box");
      const unsigned want = link_mask(range_[i]);
      if (want != kmask_[i]) fail("link mask disagrees with range");
      if ((want == 0) != (where_[i] != kNone)) fail("overflow membership disagrees with range");
      if (where_[i] != kNone && (where_[i] >= overflow_.size() || overflow_[where_[i]] != i))
        fail("overflow position");
      for (unsigned k = 0; k < 8; ++k) {
        if ((want >> k & 1u) == 0) continue;
        ++links;
        const std::uint32_t l = 8 * i + k;
        const std::size_t bucket = bucket_of(key_of(range_[i], k));
        if (prev_[l] == kNone ? heads_[bucket] != l : next_[prev_[l]] != l)
          fail("broken backward link");
        if (next_[l] != kNone &&
            (prev_[next_[l]] != l ||
             bucket_of(key_of(range_[next_[l] >> 3], next_[l] & 7u)) != bucket))
          fail("broken forward link");
        if (kSorted && next_[l] != kNone && low_x(next_[l]) < low_x(l)) fail("list out of x order");
      }
    }
    if (links != link_count_) fail("link count");
  }

  /// Reports every occupied cell (level 0) with the objects its list holds,
  /// read from the lists. Overflow objects are in no cell. O(links log cells).
  void visit_cells(CellVisitor visitor) const {
    CellTally tally;
    for (const std::uint32_t head : heads_)
      for (std::uint32_t m = head; m != kNone; m = next_[m])
        tally.add(0, key_of(range_[m >> 3], m & 7u));
    tally.report([&](int, const CellKey& k) { return map_.box(k); }, visitor);
  }

 private:
  using Base = StoreBase<LinkedGrid>;
  using Base::store_;

  // One link copied out of a list for the all-pairs pass.
  struct Gathered {
    AabbF box;
    std::uint32_t obj;
    std::uint32_t k;
    CellKey key;
  };
  static constexpr std::size_t kGather = 256;
  // An object spanning a third cell on an axis leaves for the overflow list,
  // whose objects meet each other by brute force: size cells to hold 95% of
  // the objects within two cells per axis (the lab's cell-size sweep).
  static constexpr CellSizeRule kRule{0.95, 0.5};

  // The all-pairs pass of the unsorted grids: gather each list, then test
  // every pair of the buffer.
  template <class V>
  QueryCost gather_pairs(V& visitor, std::size_t first, std::size_t last, bool overflow) const {
    QueryCost cost;
    const AabbF* box = box_.data();
    Gathered buf[kGather];
    for (std::size_t c = first; c < last; ++c) {
      const std::uint32_t head = heads_[c];
      if (head == kNone || next_[head] == kNone) continue;
      std::size_t n = 0;
      std::uint32_t m = head;
      for (; m != kNone && n < kGather; m = next_[m], ++n) {
        const std::uint32_t b = m >> 3;
        buf[n] = {box[b], b, m & 7u, {}};
        if constexpr (kHashed) buf[n].key = key_of(range_[b], m & 7u);
      }
      if (m != kNone) {
        if (!walk_list(head, cost, visitor)) return cost;
        continue;
      }
      for (std::size_t i = 0; i + 1 < n; ++i) {
        const Gathered& gi = buf[i];
        for (std::size_t j = i + 1; j < n; ++j) {
          const Gathered& gj = buf[j];
          if ((gi.k & gj.k) != 0 || !gi.box.overlaps(gj.box)) continue;
          if constexpr (kHashed) {
            if (!(gi.key == gj.key)) continue;
          }
          if (!admits(visitor, gi.obj, gj.obj)) continue;
          ++cost.tests;
          if (!overlaps(store_.shape(gi.obj), store_.shape(gj.obj))) continue;
          if (!visit(visitor, store_.handle(gi.obj), store_.handle(gj.obj))) {
            cost.stopped = true;
            return cost;
          }
        }
      }
    }
    if (overflow) overflow_pairs(cost, visitor);
    return cost;
  }

  // The all-pairs pass of the sorted grid: sweep each list along x, each
  // link meeting only the links that start before it ends.
  template <class V>
  QueryCost sweep_pairs(V& visitor, std::size_t first, std::size_t last, bool overflow) const {
    QueryCost cost;
    const AabbF* box = box_.data();
    for (std::size_t c = first; c < last; ++c) {
      const std::uint32_t head = heads_[c];
      for (std::uint32_t l = head; l != kNone; l = next_[l]) {
        const std::uint32_t a = l >> 3;
        const unsigned k = l & 7u;
        const float end = box[a].hi[0];
        const CellKey key = key_of(range_[a], k);
        for (std::uint32_t m = next_[l]; m != kNone && box[m >> 3].lo[0] <= end; m = next_[m]) {
          const unsigned kb = m & 7u;
          if ((k & kb) != 0) continue;
          const std::uint32_t b = m >> 3;
          if (!(key_of(range_[b], kb) == key)) continue;
          if (!test_pair(store_, box, a, b, cost, visitor)) return cost;
        }
      }
    }
    if (overflow) overflow_pairs(cost, visitor);
    return cost;
  }

  // Overflowing objects against the grid and against each other.
  template <class V>
  void overflow_pairs(QueryCost& cost, V& visitor) const {
    if (cost.stopped) return;
    const AabbF* box = box_.data();
    for (std::size_t p = 0; p < overflow_.size(); ++p) {
      const std::uint32_t o = overflow_[p];
      const bool go = visit_region(
          range_[o], [&](std::uint32_t b) { return test_pair(store_, box, o, b, cost, visitor); });
      if (!go) return;
      for (std::size_t q = p + 1; q < overflow_.size(); ++q)
        if (!test_pair(store_, box, o, overflow_[q], cost, visitor)) return;
    }
  }

  // All pairs of one list, walked in place (lists longer than the buffer).
  template <class V>
  bool walk_list(std::uint32_t head, QueryCost& cost, V& visitor) const {
    for (std::uint32_t l = head; l != kNone; l = next_[l]) {
      const std::uint32_t a = l >> 3;
      const unsigned k = l & 7u;
      for (std::uint32_t m = next_[l]; m != kNone; m = next_[m]) {
        const unsigned kb = m & 7u;
        if ((k & kb) != 0) continue;
        const std::uint32_t b = m >> 3;
        if constexpr (kHashed) {
          if (!(key_of(range_[b], kb) == key_of(range_[a], k))) continue;
        }
        if (!test_pair(store_, box_.data(), a, b, cost, visitor)) return false;
      }
    }
    return true;
  }

  std::size_t bucket_of(const CellKey& k) const {
    if constexpr (kHashed) {
      return static_cast<std::size_t>(hash_cell(k)) & (heads_.size() - 1);
    } else {
      return static_cast<std::size_t>(k.c[0]) +
             static_cast<std::size_t>(n_[0]) *
                 (static_cast<std::size_t>(k.c[1]) +
                  static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(k.c[2]));
    }
  }

  // Calls f(b) once for every grid object b whose range meets `r` (once:
  // only in the lowest corner of the two ranges' intersection). Scans the
  // objects instead when `r` covers more cells than there are objects.
  template <class F>
  bool visit_region(const CellRange& r, F&& f) const {
    const std::size_t grid_objects = store_.size() - overflow_.size();
    if (r.cells() > 2.0 * static_cast<double>(grid_objects) + 8) {
      for (std::uint32_t b = 0; b < store_.slot_count(); ++b)
        if (kmask_[b] != 0 && !f(b)) return false;
      return true;
    }
    CellKey c;
    for (c.c[2] = r.lo[2]; c.c[2] <= r.hi[2]; ++c.c[2])
      for (c.c[1] = r.lo[1]; c.c[1] <= r.hi[1]; ++c.c[1])
        for (c.c[0] = r.lo[0]; c.c[0] <= r.hi[0]; ++c.c[0]) {
          const unsigned rm = offset_mask(r, c);
          for (std::uint32_t m = heads_[bucket_of(c)]; m != kNone; m = next_[m]) {
            const unsigned kb = m & 7u;
            if ((rm & kb) != 0) continue;
            const std::uint32_t b = m >> 3;
            if constexpr (kHashed) {
              if (!(key_of(range_[b], kb) == c)) continue;
            }
            if (!f(b)) return false;
          }
        }
    return true;
  }

  void place(std::uint32_t i) {
    occupied_.add(box_[i]);
    range_[i] = map_.range(box_[i]);
    const unsigned mask = link_mask(range_[i]);
    kmask_[i] = static_cast<std::uint8_t>(mask);
    if (mask == 0) {
      where_[i] = static_cast<std::uint32_t>(overflow_.size());
      overflow_.push_back(i);
      return;
    }
    for (unsigned k = 0; k < 8; ++k) {
      if ((mask >> k & 1u) == 0) continue;
      const std::uint32_t l = 8 * i + k;
      const std::size_t bucket = bucket_of(key_of(range_[i], k));
      std::uint32_t& head = heads_[bucket];
      ++link_count_;
      if constexpr (kSorted) {
        if (head != kNone && low_x(head) < low_x(l)) {
          std::uint32_t m = head;
          while (next_[m] != kNone && low_x(next_[m]) < low_x(l)) m = next_[m];
          link_after(l, m);
          continue;
        }
      }
      next_[l] = head;
      prev_[l] = kNone;
      if (head != kNone) prev_[head] = l;
      head = l;
    }
  }

  float low_x(std::uint32_t link) const { return box_[link >> 3].lo[0]; }

  void link_after(std::uint32_t l, std::uint32_t m) {
    next_[l] = next_[m];
    prev_[l] = m;
    if (next_[m] != kNone) prev_[next_[m]] = l;
    next_[m] = l;
  }

  // Restores the x order of object i's links after its bounds moved inside
  // the same cells: each link moves by as many places as objects it passed,
  // O(1) for coherent motion. Two links of i may share a bucket (two cells,
  // one hash); i's own links are skipped over as if absent, since i's
  // other links are still at their old places while one is being moved.
  void resort(std::uint32_t i) {
    const unsigned mask = kmask_[i];
    auto back = [&](std::uint32_t m) {
      while (m != kNone && (m >> 3) == i) m = prev_[m];
      return m;
    };
    auto ahead = [&](std::uint32_t m) {
      while (m != kNone && (m >> 3) == i) m = next_[m];
      return m;
    };
    const float x = box_[i].lo[0];
    for (unsigned k = 0; k < 8; ++k) {
      if ((mask >> k & 1u) == 0) continue;
      const std::uint32_t l = 8 * i + k;
      const std::uint32_t before = back(prev_[l]);
      const std::uint32_t after = ahead(next_[l]);
      const bool go_back = before != kNone && low_x(before) > x;
      if (!go_back && (after == kNone || low_x(after) >= x)) continue;
      std::uint32_t& head = heads_[bucket_of(key_of(range_[i], k))];
      if (prev_[l] == kNone) {
        head = next_[l];
      } else {
        next_[prev_[l]] = next_[l];
      }
      if (next_[l] != kNone) prev_[next_[l]] = prev_[l];
      if (go_back) {
        std::uint32_t m = before;
        while (prev_[m] != kNone && ((prev_[m] >> 3) == i || low_x(prev_[m]) > x)) m = prev_[m];
        if (prev_[m] == kNone) {
          next_[l] = m;
          prev_[l] = kNone;
          prev_[m] = l;
          head = l;
        } else {
          link_after(l, prev_[m]);
        }
      } else {
        std::uint32_t m = after;
        while (next_[m] != kNone && ((next_[m] >> 3) == i || low_x(next_[m]) < x)) m = next_[m];
        link_after(l, m);
      }
    }
  }

  void lift(std::uint32_t i) {
    if (where_[i] != kNone) {
      leave_list(overflow_, where_, i);
      return;
    }
    const unsigned mask = kmask_[i];
    for (unsigned k = 0; k < 8; ++k) {
      if ((mask >> k & 1u) == 0) continue;
      const std::uint32_t l = 8 * i + k;
      if (prev_[l] == kNone) {
        heads_[bucket_of(key_of(range_[i], k))] = next_[l];
      } else {
        next_[prev_[l]] = next_[l];
      }
      if (next_[l] != kNone) prev_[next_[l]] = prev_[l];
      --link_count_;
    }
    kmask_[i] = 0;
  }

  // Chooses the cell map for cell edge `cell` and `n` objects.
  void set_cell(double cell, std::size_t n) {
    if constexpr (kHashed) {
      map_ = CellMap(world_.lo, cell);
    } else {
      const double cap = std::clamp(16.0 * static_cast<double>(n), 4096.0, 4194304.0);
      std::int32_t count[3];
      // A cell of zero or NaN (an automatic size of degenerate objects)
      // would never grow below; each pass grows the cell by at least 1%,
      // and at once by the cube root of the excess when counts are capped.
      if (!(cell > 0)) cell = std::numeric_limits<double>::min();
      for (;;) {
        double total = 1;
        for (int a = 0; a < 3; ++a) {
          count[a] = cells_across(world_.lo[a], world_.hi[a], cell, 4194304.0);
          total *= count[a];
        }
        if (total <= cap) break;
        cell *= std::max(1.01, std::cbrt(total / cap));
      }
      for (int a = 0; a < 3; ++a) n_[a] = count[a];
      map_ = CellMap(world_.lo, cell, count);
      heads_.assign(static_cast<std::size_t>(count[0]) * static_cast<std::size_t>(count[1]) *
                        static_cast<std::size_t>(count[2]),
                    kNone);
    }
  }

  // Re-enters every object after the cell map or the bucket table changed.
  void relink_all() {
    occupied_.clear();
    std::fill(heads_.begin(), heads_.end(), kNone);
    overflow_.clear();
    link_count_ = 0;
    for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
      kmask_[i] = 0;
      where_[i] = kNone;
      if (store_.slots().alive(i)) place(i);
    }
  }

  void after_count_change() {
    if (trigger_.due(store_.size())) {
      trigger_.chosen_at = store_.size();
      set_cell(cell_scale_ * auto_cell_size(store_, box_, kRule), store_.size());
      relink_all();
    } else if constexpr (kHashed) {
      if (!forced_buckets_ && link_count_ > 2 * heads_.size()) {
        heads_.assign(2 * heads_.size(), kNone);
        relink_all();
      }
    }
  }

  const char* name_;
  Aabb world_;
  double cell_scale_;
  std::vector<AabbF> box_;            // per slot: float bounds
  std::vector<CellRange> range_;      // per slot: cells covered
  std::vector<std::uint8_t> kmask_;   // per slot: which of the 8 links are used (0: none)
  std::vector<std::uint32_t> where_;  // per slot: position in overflow_, or kNone
  std::vector<std::uint32_t> next_;   // per link (8 per slot): next link in its cell
  std::vector<std::uint32_t> prev_;   // per link: previous link, kNone at the head
  std::vector<std::uint32_t> heads_;  // per cell (dense) or bucket (hashed): first link
  std::vector<std::uint32_t> overflow_;
  OccupiedBox occupied_;  // holds every box placed since the last relink (rays)
  CellMap map_;
  std::int32_t n_[3] = {1, 1, 1};
  bool forced_buckets_ = false;
  std::size_t link_count_ = 0;
  RegridTrigger trigger_;
};

}  // namespace detail

}  // namespace broadphase
