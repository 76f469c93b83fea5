// A multi-level hashed grid over float boxes, built by a counting sort of
// 32-bit object indices: the index behind the lean path (arrays.hpp).
//
// Each object sits once, in the cell of its box's low corner, on the finest
// level whose cells are at least as wide as its widest side. A probe from object
// i visits its own level (partners j > i only) and every coarser level (any
// partner), so each pair whose boxes overlap is visited exactly once, from
// the object on the finer level (or the lower index on the same level).
// Objects whose box is infinite or wider than the coarsest level sit in a
// "big" list and are tested against every object.
#pragma once

#include <algorithm>
#include <broadphase/geometry.hpp>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

namespace broadphase::detail {

/// A float box and the object it belongs to, stored in bucket order so that
/// a probe reads the boxes it tests from consecutive memory.
struct GridEntry {
  AabbF box;
  std::uint32_t index;
};

class ArrayGrid {
 public:
  /// Builds over `boxes` (object i's box at i). Keeps what it needs.
  void build(std::span<const AabbF> boxes);

  /// Calls `visit(j)` once for every object j whose box overlaps `box`,
  /// where i is the probing object (its box is `box`): j on i's level with
  /// j > i, j on a coarser level, and, when i is big, every other object
  /// (big ones with j > i). Objects on finer levels are not visited: they
  /// find i themselves.
  template <class Visit>
  void probe(std::uint32_t i, const AabbF& box, Visit&& visit) const;

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
  /// 28): `query` then reads the boxes from the span given to `build`, which
  /// must stay valid. `probe` and `probe_box` are then unavailable, and the
  /// grid is not built again (assign a new one instead).
  void slim() {
    slim_.resize(entries_.size());
    for (std::size_t k = 0; k < entries_.size(); ++k) slim_[k] = entries_[k].index;
    std::vector<GridEntry>().swap(entries_);  // `= {}` would keep the capacity
    slimmed_ = true;
  }
  /// Bytes of the index kept by `slim` (not in `memory_bytes`).
  std::size_t slim_bytes() const { return slim_.capacity() * sizeof(std::uint32_t); }

  /// Calls `visit(j)` once for every object j whose box, as given to the
  /// last build, overlaps `box` (every level and the big list).
  template <class Visit>
  void query(const AabbF& box, Visit&& visit) const;

  /// The objects whose box was infinite or too wide for any level.
  std::span<const std::uint32_t> big() const { return big_; }

  /// Bytes held (capacities).
  std::size_t memory_bytes() const;
  /// Lets go of all memory.
  void release();

 private:
  struct Level {
    double h = 0;    // cell side (a power of two)
    double inv = 0;  // 1 / h, exact
    std::uint32_t first_bucket = 0;
    std::uint32_t mask = 0;
    std::uint32_t count = 0;
    // No two cells of a probe's block (offsets up to 2 per axis) share a
    // bucket, so a probe needs no check for buckets seen twice.
    bool distinct = false;
  };
  static constexpr std::uint8_t kBig = 0xFF;
  static constexpr std::uint64_t kHashY = 0x9E3779B1ull;
  static constexpr std::uint64_t kHashZ = 0x85EBCA77C2B2AE63ull;

  static std::int64_t cell(double x, double inv);
  static std::uint32_t hash(std::int64_t cx, std::int64_t cy, std::int64_t cz);
  // The cells of `lv` that can hold the low corner of an object whose box
  // overlaps `box`: x0..x1, y0..y1, z0..z1.
  struct Block {
    std::int64_t x0, x1, y0, y1, z0, z1;
  };
  static Block block(const AabbF& box, const Level& lv);

  std::vector<Level> levels_;
  std::vector<std::uint8_t> level_of_;
  std::vector<std::uint32_t> start_;  // per bucket, then one past the end
  std::vector<GridEntry> entries_;
  std::vector<std::uint32_t> big_;
  std::span<const AabbF> boxes_;     // the boxes of the last build (for big probes)
  std::vector<std::uint32_t> slim_;  // the entries' objects, after `slim`
  bool slimmed_ = false;

  std::size_t placed() const { return slimmed_ ? slim_.size() : entries_.size(); }
  std::uint32_t entry_index(std::size_t k) const { return slimmed_ ? slim_[k] : entries_[k].index; }
  const AabbF& entry_box(std::size_t k) const {
    return slimmed_ ? boxes_[slim_[k]] : entries_[k].box;
  }
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

inline std::uint32_t ArrayGrid::hash(std::int64_t cx, std::int64_t cy, std::int64_t cz) {
  // Linear in x: cells next to each other along x share or neighbour a
  // bucket, so probes made in bucket order read memory close to the last
  // probe's (measured at scaled-even 102 400: a mixing hash left the probes
  // waiting on a cache miss per bucket).
  // Linear modulo 2^32, so two cells of one probe share a bucket exactly
  // when their offset maps to 0 under the level's mask (see `distinct`).
  const std::uint64_t h = static_cast<std::uint64_t>(cx) + static_cast<std::uint64_t>(cy) * kHashY +
                          static_cast<std::uint64_t>(cz) * kHashZ;
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
void ArrayGrid::probe(std::uint32_t i, const AabbF& box, Visit&& visit) const {
  const std::uint8_t li = level_of_[i];
  if (li == kBig) {
    const std::size_t n = level_of_.size();
    for (std::uint32_t j = 0; j < n; ++j) {
      if (j == i || (level_of_[j] == kBig && j < i)) continue;
      if (box.overlaps(boxes_[j])) visit(j);
    }
    return;
  }
  // A probe covers at most 3 cells per axis on each level (cells are at
  // least as wide as the widest box on them), so at most 27 buckets per level;
  // the room for 64 leaves a margin for rounding.
  std::uint32_t seen[64];
  for (std::size_t b = li; b < levels_.size(); ++b) {
    const Level& lv = levels_[b];
    if (lv.count == 0) continue;
    const Block blk = block(box, lv);
    const std::int64_t x0 = blk.x0, x1 = blk.x1, y0 = blk.y0, y1 = blk.y1, z0 = blk.z0, z1 = blk.z1;
    int nseen = 0;
    const bool check_dup = !lv.distinct || x1 - x0 > 2 || y1 - y0 > 2 || z1 - z0 > 2;
    if ((x1 - x0 + 1) * (y1 - y0 + 1) * (z1 - z0 + 1) > 64) std::abort();  // cannot happen
    for (std::int64_t cx = x0; cx <= x1; ++cx) {
      for (std::int64_t cy = y0; cy <= y1; ++cy) {
        for (std::int64_t cz = z0; cz <= z1; ++cz) {
          const std::uint32_t bucket = lv.first_bucket + (hash(cx, cy, cz) & lv.mask);
          const std::uint32_t s = start_[bucket];
          const std::uint32_t e = start_[bucket + 1];
          if (s == e) continue;
          if (check_dup) {
            // Two cells of one probe can share a bucket: visit it once.
            bool dup = false;
            for (int k = 0; k < nseen; ++k) dup |= seen[k] == bucket;
            if (dup) continue;
            seen[nseen++] = bucket;
          }
          for (std::uint32_t k = s; k < e; ++k) {
            const GridEntry& en = entries_[k];
            if (b == li && en.index <= i) continue;
            if (box.overlaps(en.box)) visit(en.index);
          }
        }
      }
    }
  }
}

template <class Visit>
void ArrayGrid::query(const AabbF& box, Visit&& visit) const {
  for (std::uint32_t j : big_)
    if (box.overlaps(boxes_[j])) visit(j);
  for (const Level& lv : levels_) {
    if (lv.count == 0) continue;
    // Plain variables, not a structured binding: clang 14 (the fuzz
    // build) cannot capture bindings in a lambda.
    const Block blk = block(box, lv);
    const std::int64_t x0 = blk.x0, x1 = blk.x1, y0 = blk.y0, y1 = blk.y1, z0 = blk.z0, z1 = blk.z1;
    const double cells = static_cast<double>(x1 - x0 + 1) * static_cast<double>(y1 - y0 + 1) *
                         static_cast<double>(z1 - z0 + 1);
    const std::uint32_t b0 = lv.first_bucket, b1 = lv.first_bucket + lv.mask + 1;
    if (cells >= static_cast<double>(lv.mask + 1)) {
      // A box wide against this level's cells: every bucket, once.
      for (std::uint32_t k = start_[b0]; k < start_[b1]; ++k)
        if (box.overlaps(entry_box(k))) visit(entry_index(k));
      continue;
    }
    // The hash is linear in x, so a row of cells along x is a run of
    // consecutive buckets (wrapping at the level's end), whose entries are
    // consecutive too: one run per (y, z) instead of one lookup per cell
    // (a wide fat box renewed against a fine level spans 9^3 cells).
    // Several cells of the range may share a bucket: an entry is then taken
    // only from its own cell (that of its low corner, which lies in the
    // range when it overlaps), so each once, without a set of seen buckets.
    const bool may_share = !lv.distinct || x1 - x0 > 2 || y1 - y0 > 2 || z1 - z0 > 2;
    const auto len = static_cast<std::uint32_t>(x1 - x0 + 1);
    auto run = [&](std::uint32_t r0, std::uint32_t r1, std::int64_t cy, std::int64_t cz) {
      for (std::uint32_t k = start_[b0 + r0]; k < start_[b0 + r1]; ++k) {
        const AabbF& eb = entry_box(k);
        if (!box.overlaps(eb)) continue;
        if (may_share) {
          const std::int64_t ex = cell(eb.lo[0], lv.inv);
          if (ex < x0 || ex > x1 || cell(eb.lo[1], lv.inv) != cy || cell(eb.lo[2], lv.inv) != cz)
            continue;
        }
        visit(entry_index(k));
      }
    };
    for (std::int64_t cy = y0; cy <= y1; ++cy)
      for (std::int64_t cz = z0; cz <= z1; ++cz) {
        const std::uint32_t h = hash(x0, cy, cz) & lv.mask;
        if (h + len <= lv.mask + 1) {
          run(h, h + len, cy, cz);
        } else {
          run(h, lv.mask + 1, cy, cz);
          run(0, h + len - (lv.mask + 1), cy, cz);
        }
      }
  }
}

}  // namespace broadphase::detail
