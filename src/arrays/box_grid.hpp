// A multi-level hashed grid over float boxes, built by a counting sort of
// 32-bit object indices: the index behind the lean path (arrays.hpp).
//
// Each object sits once, in the cell of its box's low corner, on the finest
// level whose cells are at least as wide as its widest side. A probe from
// object i visits its own level (half of it, below) and every coarser level
// (any partner), so each pair whose boxes overlap is visited exactly once,
// from the object on the finer level; on one level, from the object whose
// cell comes first in (z, y, x) order on a dense level, or from the lower
// index (in one cell, or on a hashed level). Objects whose box is infinite
// or wider than the coarsest level sit in a "big" list and are tested
// against every object.
//
// A level is dense when its occupied cells span few more cells than it has
// objects: a bucket per cell, rows of cells along x as runs of buckets. The
// others are hashed, a bucket per object, with a bitmap of occupied blocks
// of cells that lets a probe skip the level where nothing lies near.
#pragma once

#include <algorithm>
#include <broadphase/geometry.hpp>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <type_traits>
#include <vector>

#include "big_vector.hpp"

namespace broadphase::arrays::detail {

/// A float box and the object it belongs to, stored in bucket order so that
/// a probe reads the boxes it tests from consecutive memory.
struct GridEntry {
  AabbF box;
  std::uint32_t index;
};

class ArrayGrid {
 public:
  /// Builds over `boxes` (object i's box at i). Keeps what it needs.
  /// A level whose occupied cells span a box of at most `dense` times its
  /// object count (rounded up to a power of two) gets one bucket per cell
  /// of that box, laid out row by row (see `Level::ky`); others are hashed
  /// into one bucket per object. The finest level's cells are at least
  /// `min_cell` wide, and exactly that wide when the boxes' own choice
  /// would be no wider (so a grid rebuilt with its own base_cell keeps it).
  void build(std::span<const AabbF> boxes, std::uint32_t dense = 1, double min_cell = 0);
  /// The finest level's cell side (0 before a build or with no level).
  double base_cell() const { return levels_.empty() ? 0 : levels_.front().h; }

  /// Calls `visit(j)` once for every object j whose box overlaps the box of
  /// i = probe_object(k) (probe_box(k)): j on i's level when the pair is
  /// i's to find (see the top of this file), j on a coarser level, and,
  /// when i is big, every other object (big ones with j > i). Objects on
  /// finer levels are not visited: they find i themselves. A
  /// `visit(j, place)` is also told j's place in the probing order
  /// (j == probe_object(place)), or kNoPlace when i is big, so that a caller
  /// can keep its objects' data in that order.
  static constexpr std::uint32_t kNoPlace = 0xFFFFFFFFu;
  template <class Visit>
  void probe(std::size_t k, Visit&& visit) const;

  /// The probing order: the objects in bucket order (neighbours in space
  /// close together), then the big ones. Probing in this order reads the
  /// grid's memory in long runs.
  std::size_t probe_count() const { return placed() + big_.size(); }
  std::uint32_t probe_object(std::size_t k) const {
    return k < placed() ? entry_index(k) : big_[k - placed()];
  }
  /// Not after `slim`.
  const AabbF& probe_box(std::size_t k) const {
    return k < entries_.size() ? entries_[k].box : boxes_[big_[k - entries_.size()]];
  }

  /// Keeps only the entries' object indices (4 bytes an object instead of
  /// 28): `query` then reads the boxes from `by_place`, the box of
  /// probe_object(k) at k for every k < probe_count(), which the caller keeps
  /// valid (and may change: a query then tests the changed box, though it
  /// finds the object only in the cells of its box at the build). In the
  /// probing order, a query's boxes lie together in memory, as in the
  /// entries. `probe` and `probe_box` are then unavailable, and the grid is
  /// not built again (assign a new one instead).
  void slim(std::span<const AabbF> by_place) {
    slim_.resize(entries_.size());
    for (std::size_t k = 0; k < entries_.size(); ++k) slim_[k] = entries_[k].index;
    BigVector<GridEntry>().swap(entries_);  // `= {}` would keep the capacity
    boxes_ = by_place;
    slimmed_ = true;
  }
  /// Bytes of the index kept by `slim` (not in `memory_bytes`).
  std::size_t slim_bytes() const { return slim_.capacity() * sizeof(std::uint32_t); }

  /// Calls `visit(j)` once for every object j whose box, as given to the
  /// last build, overlaps `box` (every level and the big list); a
  /// `visit(j, place)` is also told j's place in the probing order.
  template <class Visit>
  void query(const AabbF& box, Visit&& visit) const;

  /// The objects whose box was infinite or too wide for any level.
  std::span<const std::uint32_t> big() const { return big_; }

  /// For ray casts (rays.cpp), which march each level's cells: a level's
  /// cell side, the map of a coordinate to its cell (monotone; an object's
  /// cell is that of its box's low corner), its occupied cells and count.
  struct LevelShape {
    double h = 0, inv = 0;
    std::int64_t lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    std::uint32_t count = 0;
  };
  std::size_t level_count() const { return levels_.size(); }
  LevelShape level_shape(std::size_t b) const {
    const Level& lv = levels_[b];
    LevelShape s;
    s.h = lv.h;
    s.inv = lv.inv;
    s.count = lv.count;
    for (int a = 0; a < 3; ++a) {
      s.lo[a] = lv.lo[a];
      s.hi[a] = lv.hi[a];
    }
    return s;
  }
  static std::int64_t cell_of(double x, double inv) { return cell(x, inv); }
  /// Calls `take(entry)` for each entry of level b whose cell is (cx, cy,
  /// cz); false as soon as `take` returns false. Not after `slim`.
  template <class Take>
  bool for_cell(std::size_t b, std::int64_t cx, std::int64_t cy, std::int64_t cz,
                Take&& take) const {
    const Level& lv = levels_[b];
    if (lv.count == 0 || cx < lv.lo[0] || cx > lv.hi[0] || cy < lv.lo[1] || cy > lv.hi[1] ||
        cz < lv.lo[2] || cz > lv.hi[2])
      return true;
    // A hashed level's summary first: its bucket would be a cache miss.
    if (!lv.dense && !may_hold(lv, cx, cx, cy, cy, cz, cz)) return true;
    const std::uint32_t* st = start_.data() + lv.first_bucket;
    const std::uint32_t h = hash(lv, cx, cy, cz) & lv.mask;
    for (std::uint32_t p = st[h]; p < st[h + 1]; ++p) {
      const GridEntry& e = entries_[p];
      // A dense level's occupied cells have a bucket each; a hashed
      // level's buckets are shared.
      if (!lv.dense && (cell(e.box.lo[0], lv.inv) != cx || cell(e.box.lo[1], lv.inv) != cy ||
                        cell(e.box.lo[2], lv.inv) != cz))
        continue;
      if (!take(e)) return false;
    }
    return true;
  }
  /// Calls `take(entry)` for every entry of level b, as `for_cell`.
  template <class Take>
  bool for_level(std::size_t b, Take&& take) const {
    const Level& lv = levels_[b];
    if (lv.count == 0) return true;
    const std::uint32_t* st = start_.data() + lv.first_bucket;
    for (std::uint32_t p = st[0]; p < st[lv.mask + 1]; ++p)
      if (!take(entries_[p])) return false;
    return true;
  }

  /// Bytes held (capacities).
  std::size_t memory_bytes() const;
  /// Lets go of all memory.
  void release();

 private:
  struct Level {
    double h = 0;    // cell side (a power of two)
    double inv = 0;  // 1 / h, rounded: every cell is floor(x * inv), monotone in x
    std::uint32_t first_bucket = 0;
    std::uint32_t mask = 0;
    std::uint32_t count = 0;
    // The cell hash is cx + cy ky + cz kz (mod 2^32, then the mask). When
    // the level's occupied cells fit, ky and kz are powers of two that lay
    // its cells out row by row without two sharing a bucket, and a probe's
    // 9 rows are read as 9 streams when probing in bucket order; otherwise
    // they are odd multipliers that scatter the rows.
    std::uint64_t ky = 0x9E3779B1ull;
    std::uint64_t kz = 0x85EBCA77C2B2AE63ull;
    std::uint64_t shift = 0;  // dense: the occupied cells' buckets do not wrap
    bool dense = false;
    std::int64_t lo[3] = {0, 0, 0};  // the occupied cells, per axis
    std::int64_t hi[3] = {0, 0, 0};
    // Hashed levels: the summary's blocks of 2^sum_shift cells a side, its
    // width and depth in blocks and its first word in `summary_`.
    int sum_shift = 0;
    std::uint64_t sum_nx = 0, sum_ny = 0;
    std::size_t sum_first = 0;
    // No two cells of a probe's block (offsets up to 2 per axis) share a
    // bucket, so a probe needs no check for buckets seen twice.
    bool distinct = false;
  };
  static constexpr std::uint8_t kBig = 0xFF;

  static std::int64_t cell(double x, double inv);
  static std::uint32_t hash(const Level& lv, std::int64_t cx, std::int64_t cy, std::int64_t cz);
  // The cells of `lv` that can hold the low corner of an object whose box
  // overlaps `box`: x0..x1, y0..y1, z0..z1.
  struct Block {
    std::int64_t x0, x1, y0, y1, z0, z1;
  };
  static Block block(const AabbF& box, const Level& lv);
  static std::uint64_t summary_bit(const Level& lv, std::int64_t cx, std::int64_t cy,
                                   std::int64_t cz) {
    return ((static_cast<std::uint64_t>(cz - lv.lo[2]) >> lv.sum_shift) * lv.sum_ny +
            (static_cast<std::uint64_t>(cy - lv.lo[1]) >> lv.sum_shift)) *
               lv.sum_nx +
           (static_cast<std::uint64_t>(cx - lv.lo[0]) >> lv.sum_shift);
  }
  // False when the summary shows no object of hashed level `lv` with its
  // cell in x0..x1, y0..y1, z0..z1 (clipped to the occupied cells).
  bool may_hold(const Level& lv, std::int64_t x0, std::int64_t x1, std::int64_t y0, std::int64_t y1,
                std::int64_t z0, std::int64_t z1) const;
  // Calls `take(p)` once for every entry p of `lv` whose box overlaps `box`
  // and whose cell lies in `blk` (the block of `box`).
  template <class Take>
  void scan_block(const Level& lv, const AabbF& box, const Block& blk, Take&& take) const;

  std::vector<Level> levels_;
  BigVector<std::uint8_t> level_of_;
  BigVector<std::uint32_t> start_;  // per bucket, then one past the end
  BigVector<GridEntry> entries_;
  std::vector<std::uint32_t> big_;
  std::vector<std::uint64_t> summary_;  // a bit per block of cells, hashed levels
  // The boxes of the last build by object (for big probes), or after
  // `slim` by place.
  std::span<const AabbF> boxes_;
  std::vector<std::uint32_t> slim_;  // the entries' objects, after `slim`
  bool slimmed_ = false;

  std::size_t placed() const { return slimmed_ ? slim_.size() : entries_.size(); }
  std::uint32_t entry_index(std::size_t k) const { return slimmed_ ? slim_[k] : entries_[k].index; }
  const AabbF& entry_box(std::size_t k) const { return slimmed_ ? boxes_[k] : entries_[k].box; }
};

inline std::int64_t ArrayGrid::cell(double x, double inv) {
  // Clamping is monotone, so a clamped probe range still covers every
  // clamped cell in it; far-away objects only share cells.
  constexpr double kLimit = 0x1p40;
  const double c = std::floor(x * inv);
  if (!(c > -kLimit)) return -static_cast<std::int64_t>(kLimit);
  if (c > kLimit) return static_cast<std::int64_t>(kLimit);
  return static_cast<std::int64_t>(c);
}

inline std::uint32_t ArrayGrid::hash(const Level& lv, std::int64_t cx, std::int64_t cy,
                                     std::int64_t cz) {
  // Linear in x: cells next to each other along x share or neighbour a
  // bucket, so probes made in bucket order read memory close to the last
  // probe's (measured at scaled-even 102 400: a mixing hash left the probes
  // waiting on a cache miss per bucket).
  // Linear modulo 2^32, so two cells of one probe share a bucket exactly
  // when their offset maps to 0 under the level's mask (see `distinct`).
  const std::uint64_t h = static_cast<std::uint64_t>(cx) + static_cast<std::uint64_t>(cy) * lv.ky +
                          static_cast<std::uint64_t>(cz) * lv.kz + lv.shift;
  return static_cast<std::uint32_t>(h);
}

inline ArrayGrid::Block ArrayGrid::block(const AabbF& box, const Level& lv) {
  // Object j on level lv has its low corner in its cell and
  // hi_j <= lo_j + h (1 - 2^-20), so it overlaps `box` only if lo_j lies in
  // [box.lo - h, box.hi]; rounding box.lo - h moves it by less than that
  // margin (cells are at least a float ulp of the coordinates wide).
  return {cell(static_cast<double>(box.lo[0]) - lv.h, lv.inv), cell(box.hi[0], lv.inv),
          cell(static_cast<double>(box.lo[1]) - lv.h, lv.inv), cell(box.hi[1], lv.inv),
          cell(static_cast<double>(box.lo[2]) - lv.h, lv.inv), cell(box.hi[2], lv.inv)};
}

template <class Visit>
void ArrayGrid::probe(std::size_t k, Visit&& visit) const {
  const std::uint32_t i = probe_object(k);
  const AabbF& box = probe_box(k);
  auto emit = [&](std::uint32_t j, std::uint32_t place) {
    if constexpr (std::is_invocable_v<Visit&, std::uint32_t, std::uint32_t>)
      visit(j, place);
    else
      visit(j);
  };
  // The level from the place (levels own consecutive ranges of buckets,
  // so of entries): level_of_[i] would be a cache miss per probe, as i
  // runs over the objects at random (13% of a one-shot call at 10^6).
  std::size_t li = kBig;
  if (k < placed()) {
    li = 0;
    while (li + 1 < levels_.size() && k >= start_[levels_[li + 1].first_bucket]) ++li;
  }
  if (li == kBig) {
    const std::size_t n = level_of_.size();
    for (std::uint32_t j = 0; j < n; ++j) {
      if (j == i || (level_of_[j] == kBig && j < i)) continue;
      if (box.overlaps(boxes_[j])) emit(j, kNoPlace);
    }
    return;
  }
  // A probe covers at most 3 cells per axis on each level (cells are at
  // least as wide as the widest box on them): 9 rows of cells per level.
  for (std::size_t b = li; b < levels_.size(); ++b) {
    const Level& lv = levels_[b];
    if (lv.count == 0) continue;
    const Block blk = block(box, lv);
    if (b == li && lv.dense) {
      // On its own dense level a pair is found once, by the object whose
      // cell comes first in (z, y, x) order, or the lower index in one
      // cell: the probe reads its own row from just after itself (a cell
      // lists its objects by index) and the rows after it, half the block.
      // A row of cells along x is a run of buckets, clipped to the level's
      // occupied cells (inside which no run wraps).
      const std::uint32_t* st = start_.data() + lv.first_bucket;
      const std::int64_t xa = std::max(blk.x0, lv.lo[0]), xb = std::min(blk.x1, lv.hi[0]);
      // The box tests without a branch each (about half of a row's boxes
      // pass, so a branch per box is a coin toss): the places that pass are
      // gathered, then visited.
      auto scan = [&](std::uint32_t p, std::uint32_t e) {
        constexpr std::uint32_t kBatch = 32;
        std::uint32_t hit[kBatch];
        while (p < e) {
          const std::uint32_t stop = std::min(e, p + kBatch);
          std::uint32_t m = 0;
          for (; p < stop; ++p) {
            hit[m] = p;
            m += box.overlaps_flat(entries_[p].box);
          }
          for (std::uint32_t q = 0; q < m; ++q) emit(entries_[hit[q]].index, hit[q]);
        }
      };
      auto row = [&](std::int64_t cy, std::int64_t cz) {
        if (cy < lv.lo[1] || cy > lv.hi[1] || cz < lv.lo[2] || cz > lv.hi[2]) return;
        const std::uint32_t h = hash(lv, xa, cy, cz) & lv.mask;
        scan(st[h], st[h + static_cast<std::uint32_t>(xb - xa) + 1]);
      };
      const std::int64_t oy = cell(box.lo[1], lv.inv), oz = cell(box.lo[2], lv.inv);
      scan(static_cast<std::uint32_t>(k) + 1, st[(hash(lv, xb, oy, oz) & lv.mask) + 1]);
      for (std::int64_t cy = oy + 1; cy <= blk.y1; ++cy) row(cy, oz);
      for (std::int64_t cz = oz + 1; cz <= blk.z1; ++cz)
        for (std::int64_t cy = blk.y0; cy <= blk.y1; ++cy) row(cy, cz);
      continue;
    }
    scan_block(lv, box, blk, [&](std::uint32_t p) {
      if (b != li || entries_[p].index > i) emit(entries_[p].index, p);
    });
  }
}

template <class Visit>
void ArrayGrid::query(const AabbF& box, Visit&& visit) const {
  auto emit = [&](std::uint32_t j, std::size_t at) {
    if constexpr (std::is_invocable_v<Visit&, std::uint32_t, std::uint32_t>)
      visit(j, static_cast<std::uint32_t>(at));
    else
      visit(j);
  };
  for (std::size_t b = 0; b < big_.size(); ++b)
    if (box.overlaps(slimmed_ ? boxes_[placed() + b] : boxes_[big_[b]]))
      emit(big_[b], placed() + b);
  for (const Level& lv : levels_) {
    if (lv.count == 0) continue;
    scan_block(lv, box, block(box, lv), [&](std::uint32_t p) { emit(entry_index(p), p); });
  }
}

template <class Take>
void ArrayGrid::scan_block(const Level& lv, const AabbF& box, const Block& blk, Take&& take) const {
  // Cells outside the level's occupied ones hold nothing: clip to them.
  const std::int64_t x0 = std::max(blk.x0, lv.lo[0]), x1 = std::min(blk.x1, lv.hi[0]);
  const std::int64_t y0 = std::max(blk.y0, lv.lo[1]), y1 = std::min(blk.y1, lv.hi[1]);
  const std::int64_t z0 = std::max(blk.z0, lv.lo[2]), z1 = std::min(blk.z1, lv.hi[2]);
  if (x0 > x1 || y0 > y1 || z0 > z1) return;
  if (!lv.dense && !may_hold(lv, x0, x1, y0, y1, z0, z1)) return;
  const double cells = static_cast<double>(x1 - x0 + 1) * static_cast<double>(y1 - y0 + 1) *
                       static_cast<double>(z1 - z0 + 1);
  const std::uint32_t size = lv.mask + 1;
  const std::uint32_t* st = start_.data() + lv.first_bucket;
  if (cells >= static_cast<double>(size)) {
    // A box wide against this level's cells: every bucket, once.
    for (std::uint32_t p = st[0]; p < st[size]; ++p)
      if (box.overlaps(entry_box(p))) take(p);
    return;
  }
  // The hash is linear in x, so a row of cells along x is a run of
  // consecutive buckets (wrapping at the level's end), whose entries are
  // consecutive too: one run per (y, z) instead of one lookup per cell.
  // Several cells of the range may share a bucket: an entry is then taken
  // only from its own cell (that of its low corner, which lies in the
  // range when it overlaps), so each once, without a set of seen buckets.
  const bool may_share = !lv.distinct || x1 - x0 > 2 || y1 - y0 > 2 || z1 - z0 > 2;
  const auto len = static_cast<std::uint32_t>(x1 - x0 + 1);
  auto run = [&](std::uint32_t p, std::uint32_t e, std::int64_t cy, std::int64_t cz) {
    for (; p < e; ++p) {
      const AabbF& eb = entry_box(p);
      if (!box.overlaps(eb)) continue;
      if (may_share) {
        const std::int64_t ex = cell(eb.lo[0], lv.inv);
        if (ex < x0 || ex > x1 || cell(eb.lo[1], lv.inv) != cy || cell(eb.lo[2], lv.inv) != cz)
          continue;
      }
      take(p);
    }
  };
  // A query wider than a probe's block on a hashed level (a big box on a
  // fine level: up to 100 rows) asks the summary before each row, whose
  // bucket would be a cache miss (renewals at scaled-even 1 024 000).
  const bool ask_rows = !lv.dense && (y1 - y0 + 1) * (z1 - z0 + 1) > 9;
  for (std::int64_t cz = z0; cz <= z1; ++cz)
    for (std::int64_t cy = y0; cy <= y1; ++cy) {
      if (ask_rows && !may_hold(lv, x0, x1, cy, cy, cz, cz)) continue;
      const std::uint32_t h = hash(lv, x0, cy, cz) & lv.mask;
      if (h + len <= size) {
        run(st[h], st[h + len], cy, cz);
      } else {
        run(st[h], st[size], cy, cz);
        run(st[0], st[h + len - size], cy, cz);
      }
    }
}

inline bool ArrayGrid::may_hold(const Level& lv, std::int64_t x0, std::int64_t x1, std::int64_t y0,
                                std::int64_t y1, std::int64_t z0, std::int64_t z1) const {
  const int s = lv.sum_shift;
  const auto bx0 = static_cast<std::uint64_t>(x0 - lv.lo[0]) >> s,
             bx1 = static_cast<std::uint64_t>(x1 - lv.lo[0]) >> s;
  const auto by0 = static_cast<std::uint64_t>(y0 - lv.lo[1]) >> s,
             by1 = static_cast<std::uint64_t>(y1 - lv.lo[1]) >> s;
  const auto bz0 = static_cast<std::uint64_t>(z0 - lv.lo[2]) >> s,
             bz1 = static_cast<std::uint64_t>(z1 - lv.lo[2]) >> s;
  // A wide box covers many blocks: reading the level is then no waste.
  if ((bx1 - bx0 + 1) * (by1 - by0 + 1) * (bz1 - bz0 + 1) > 64) return true;
  for (std::uint64_t bz = bz0; bz <= bz1; ++bz)
    for (std::uint64_t by = by0; by <= by1; ++by)
      for (std::uint64_t bx = bx0; bx <= bx1; ++bx) {
        const std::uint64_t bit = (bz * lv.sum_ny + by) * lv.sum_nx + bx;
        if (summary_[lv.sum_first + bit / 64] >> (bit % 64) & 1) return true;
      }
  return false;
}

}  // namespace broadphase::arrays::detail
