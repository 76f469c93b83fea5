// The kernel for spheres (find_pairs on a single set of spheres, and the
// tracker's calls afresh): a few dense grids of cells, each a hair wider
// than the largest diameter on it, the spheres counting-sorted into them as
// records of doubles, and each sphere tested exactly, by the contract's
// predicate, against the spheres after it on its own grid (the rest of its
// cell and 13 neighbours: 5 runs of consecutive cells) and against every
// sphere within reach on the coarser grids (2 or 3 cells a side).
//
// The grids: the smallest remaining spheres, and all others up to twice
// their size or up to the narrowest cell that the budget of cells allows
// (kMaxCellsPerObject a sphere, each grid over the box of all centres), go
// to one grid; the rest to the next. Spheres of one size take one grid;
// radii over three decades three.
//
// Why beside ArrayGrid: ArrayGrid's power-of-two levels (one per octave)
// and float boxes cost a box test on about 30 partners a sphere before the
// exact test for spheres of one size, and a probe of every coarser octave
// for spheres of many sizes; here the cells are the diameters themselves,
// the levels few, and the exact test reads one record. Measured on one
// core (docs/arrays.md, "The sphere kernel"): 1 000 000 spheres of radius 0.00565 in
// the unit cube 135-150 ms against 310-420; 100 000 over three decades of
// radii 19-20 ms against 125.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <broadphase/arrays/arrays.hpp>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "big_vector.hpp"

namespace broadphase::arrays::detail {

class SphereCells {
 public:
  /// Sorts the spheres of `o` into grids. False, with nothing kept, when
  /// the kernel does not suit them: a box among them, fewer than
  /// `kMinObjects`, a grid that cannot be dense (under 2^26 cells along an
  /// axis), or spheres crowded into few cells (the sum of a grid's squared
  /// cell counts over `kMaxCrowd` times its spheres), or a value that
  /// check_objects refuses (a centre or radius not finite, a negative
  /// radius; the caller's check then names it). Missing columns: false.
  bool build(const Objects& o);
  /// The same with at most `cells_per_object` cells a sphere.
  bool build(const Objects& o, std::size_t cells_per_object);
  /// The same over the objects `subset` of `o` only (distinct indices):
  /// the pairs and probes then name them by their indices in `o`; at most
  /// `cells_per_object` cells a sphere (kMaxCellsPerObject by default).
  bool build(const Objects& o, std::span<const std::uint32_t> subset,
             std::size_t cells_per_object = kMaxCellsPerObject);

  static constexpr std::size_t kMinObjects = 64;
  static constexpr std::size_t kMaxCellsPerObject = 4;
  static constexpr std::size_t kMaxCrowd = 16;
  static constexpr std::size_t kMaxLevels = 8;
  /// The crowd (see crowd()) from which `pairs` tests several partners at
  /// a time: where spheres share their cells, runs are long enough to fill
  /// a step.
  static constexpr double kWideCrowd = 2.0;

  /// Cells of all grids, each with one empty layer around the centres' box.
  std::size_t cell_count() const { return cells_; }
  /// The grids.
  std::size_t level_count() const { return levels_.size(); }
  /// The largest over the grids of the mean, over their spheres, of the
  /// spheres in a sphere's cell (itself included): 1 when none shares.
  double crowd() const { return crowd_; }
  /// Appends the overlapping pairs found from the spheres of cells
  /// [c0, c1) to `out` (caller's indices, i < j), each pair of the set
  /// exactly once over all cells; returns the number of exact tests.
  std::uint64_t pairs(std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const;

  /// Copies the records into columns (x, y, z, r, index; 36 bytes a
  /// sphere more, dropped by the next build), from which `pairs` reads
  /// its partners with plain or masked loads rather than gathers where it
  /// tests several at a time on one grid; the pairs and their order are
  /// the same. For a set that is scanned once, right after its build (the
  /// tracker's movers among themselves); probes read the records.
  void add_columns();
  /// The vector instructions the tests use: AVX-512F (eight partners a
  /// step in the scan), AVX2 (four a step, in the scan, the probes and the
  /// list tests), or neither (one at a time). The pairs and their order
  /// are the same with each: the same arithmetic in the same order, lane by
  /// lane, without fused multiply-adds.
  enum class Isa { scalar, avx2, avx512 };
  /// The widest the processor has, less what the environment turns off
  /// (BROADPHASE_NO_AVX512 or BROADPHASE_NO_AVX2 set and not empty; the
  /// second turns off both), at most the cap of use_isa.
  static Isa isa();
  /// Caps the instructions used (the tests compare them); the widest by
  /// default. Not while a call runs.
  static void use_isa(Isa most);
  /// Where `pairs` tests several partners at a time (with isa() above
  /// scalar): on grids whose crowd (see crowd()) is at least kWideCrowd
  /// (the default), or always (for the tests that compare the ways). Not
  /// while a call runs.
  enum class Wide { where_crowded, always };
  static void use_wide(Wide when);
  /// Calls `hit(i)` for every sphere i of the set that overlaps the sphere
  /// (x, y, z, r) by the contract's predicate, any size, on every grid (in
  /// the grids' order); returns the number of exact tests. A probe reads
  /// the cells within reach, widened past the rounding as in `pairs`, or a
  /// whole grid's spheres when they are fewer than those cells.
  template <class Hit>
  std::uint64_t probe(double x, double y, double z, double r, Hit&& hit) const {
    return probe_records(x, y, z, r, [&](std::uint32_t k) { hit(placed_[k].id); });
  }
  /// As `probe`, but calls `hit(k)` with the record k of each sphere found
  /// (record_id(k) is its index; records are in the grids' order).
  template <class Hit>
  std::uint64_t probe_records(double x, double y, double z, double r, Hit&& hit) const {
    std::uint64_t tests = 0;
    const double centre[3] = {x, y, z};
    const std::uint32_t* st = start_.data();
    const Placed* P = placed_.data();
    auto test = [&](std::uint32_t b, std::uint32_t e) {
      tests += e - b;
      for (; b < e; b += 64) test_block(P, x, y, z, r, b, std::min<std::uint32_t>(e - b, 64), hit);
    };
    for (const Level& g : levels_) {
      const double reach = (r + g.rmax) * (1 + 0x1p-20);
      std::size_t from[3], to[3];
      double cells = 1;
      for (int ax = 0; ax < 3; ++ax) {
        const double pad = reach + std::abs(centre[ax]) * 0x1p-48;
        from[ax] = g.index(ax, lo_[ax], centre[ax] - pad);
        to[ax] = g.index(ax, lo_[ax], centre[ax] + pad);
        cells *= static_cast<double>(to[ax] - from[ax] + 1);
      }
      const std::uint32_t b0 = st[g.first], e0 = st[g.first + g.cells];
      if (cells > static_cast<double>(e0 - b0)) {
        test(b0, e0);
        continue;
      }
      for (std::size_t cz = from[2]; cz <= to[2]; ++cz)
        for (std::size_t cy = from[1]; cy <= to[1]; ++cy) {
          const std::size_t row = g.first + cz * g.nxy + cy * g.nx;
          test(st[row + from[0]], st[row + to[0] + 1]);
        }
    }
    return tests;
  }

  /// The largest radius in the set.
  double max_radius() const {
    double r = 0;
    for (const Level& g : levels_) r = std::max(r, g.rmax);
    return r;
  }
  /// Asks for record k's memory ahead of a test.
  void prefetch_record(std::uint32_t k) const { __builtin_prefetch(&placed_[k]); }
  /// The index of the sphere of record k.
  std::uint32_t record_id(std::uint32_t k) const { return placed_[k].id; }
  /// Calls `hit(k)` for each record k of `ks` whose sphere overlaps the
  /// sphere (x, y, z, r), by the predicate of spheres_overlap (the
  /// arithmetic of `overlaps`), in the order of `ks`, without a branch per
  /// record: a movers' list at scaled-even 1 024 000 holds about two
  /// candidates a partner, a coin toss for a branch.
  template <class Hit>
  void test_records(std::span<const std::uint32_t> ks, double x, double y, double z, double r,
                    Hit&& hit) const {
    const Placed* P = placed_.data();
    for (std::size_t b = 0; b < ks.size(); b += 64) {
      const std::size_t len = std::min<std::size_t>(ks.size() - b, 64);
      std::uint64_t hits = 0;
      if (avx2_tests())
        hits = hits_avx2(P, ks.data() + b, len, x, y, z, r);
      else
        for (std::size_t t = 0; t < len; ++t)
          hits |= static_cast<std::uint64_t>(overlaps(P[ks[b + t]], x, y, z, r)) << t;
      for (; hits != 0; hits &= hits - 1)
        hit(ks[b + static_cast<std::size_t>(std::countr_zero(hits))]);
    }
  }

  /// A key that orders points as the finest grid's cells do (clamped to
  /// its outer layer): probes made in its order read nearby memory.
  std::size_t cell_key(double x, double y, double z) const {
    const Level& g = levels_.front();
    return (g.index(2, lo_[2], z) * g.dims[1] + g.index(1, lo_[1], y)) * g.dims[0] +
           g.index(0, lo_[0], x);
  }

  /// Calls `f(i, x, y, z, r)` for every sphere of the set as it was read.
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t k = 0; k + 3 < placed_.size(); ++k)
      f(placed_[k].id, placed_[k].x, placed_[k].y, placed_[k].z, placed_[k].r);
  }
  /// Checks the invariants every query relies on, and throws
  /// std::logic_error naming the first it finds broken: grids coarser the
  /// later they come, each sphere in the cell of its centre on a grid whose
  /// cell is wider than its diameter and whose largest radius is at least
  /// its own (probes reach that far), cells listing their spheres by
  /// increasing index (the build is stable, and every subset the library
  /// builds over is in increasing order), the three NaN records past the
  /// end, and the columns (when made) equal to the records. Nothing to
  /// check when not built.
  void validate() const;
  /// Spheres in the set.
  std::size_t size() const { return placed_.size() < 3 ? 0 : placed_.size() - 3; }
  /// Bytes held (the cells' starts, the records and any columns).
  std::size_t memory_bytes() const {
    return (start_.capacity() + cid_.capacity()) * sizeof(std::uint32_t) +
           placed_.capacity() * sizeof(Placed) +
           (cx_.capacity() + cy_.capacity() + cz_.capacity() + cr_.capacity()) * sizeof(double);
  }

 private:
  struct Level {
    double h = 0, inv = 0;
    double rmax = 0;  // the largest radius on the grid
    std::size_t dims[3] = {0, 0, 0};
    std::size_t nx = 0, nxy = 0;
    std::size_t first = 0;  // its first cell in the cells of all grids
    std::size_t cells = 0;
    // The cell along axis `ax` of a coordinate anywhere (the empty outer
    // layer outside the centres' box).
    std::size_t index(int ax, double lo, double v) const {
      const double t = (v - lo) * inv;
      if (!(t >= 0)) return 0;
      if (t >= static_cast<double>(dims[ax] - 2)) return dims[ax] - 1;
      return static_cast<std::size_t>(t) + 1;
    }
    // The global cell of a point (inside the centres' box).
    std::size_t cell_of(const double* lo, double x, double y, double z) const {
      return first +
             ((static_cast<std::size_t>((z - lo[2]) * inv) + 1) * dims[1] +
              static_cast<std::size_t>((y - lo[1]) * inv) + 1) *
                 dims[0] +
             static_cast<std::size_t>((x - lo[0]) * inv) + 1;
    }
  };
  template <Isa kIsa>
  std::uint64_t scan(std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const;
  // The wide scan on one grid from the columns (see add_columns).
  std::uint64_t scan_columns(std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const;
  std::uint64_t scan_columns_avx2(std::size_t c0, std::size_t c1,
                                  std::vector<IndexPair>& out) const;
  template <class At>
  bool build_over(const Objects& o, std::size_t n, At at, std::size_t cells_per_object);

  void release();
  bool fail();  // release(), false

  double lo_[3] = {0, 0, 0};
  std::vector<Level> levels_;
  std::size_t cells_ = 0;
  double crowd_ = 0;
  BigVector<std::uint32_t> start_;  // per cell, then one past the end
  // A sphere in cell order, with its index: one record, so that the
  // counting sort's scatter writes one line per sphere (five columns were
  // five cache misses a sphere). Packed, 36 bytes rather than 40 (half the
  // records straddle two cache lines either way): 3.2 bytes an object less
  // for the quiet spheres at scaled-even 1 024 000, and the one-shot call
  // there 337 -> 298 ms on one core (less memory written and read).
  struct __attribute__((packed, aligned(4))) Placed {
    double x, y, z, r;
    std::uint32_t id;
  };
  BigVector<Placed> placed_;
  // The records' fields in columns, when add_columns made them.
  BigVector<double> cx_, cy_, cz_, cr_;
  BigVector<std::uint32_t> cid_;

  // The predicate of spheres_overlap between record q and the sphere
  // (x, y, z, r): the one arithmetic of every test here.
  [[gnu::always_inline]] static bool overlaps(const Placed& q, double x, double y, double z,
                                              double r) {
    const double dx = x - q.x, dy = y - q.y, dz = z - q.z;
    const double sr = r + q.r;
    return dx * dx + dy * dy + dz * dz <= sr * sr;
  }

  // Calls `hit(k)` for every record k in [b, b + len) (len at most 64)
  // that overlaps the sphere (x, y, z, r) by the predicate of
  // spheres_overlap, in increasing k, without a branch per record: four at
  // a time into a mask, then one step per hit (about half of the partners
  // overlap in a dense set, a coin toss for a branch; a loop per record
  // paid a mispredicted exit a run, a run holding 4 records on average).
  // Reads up to three records past the block: the three NaN records past
  // the end keep that in bounds. The callers go through a run a block at a
  // time (the kernel's scan hands its pairs on between blocks: doing so
  // between hits instead cost 9% of a call at 10^6 spheres).
  template <class Hit>
  static void test_block(const Placed* __restrict P, double x, double y, double z, double r,
                         std::uint32_t b, std::uint32_t len, Hit&& hit);
  // The pairs (i, records [b, b + len)) that overlap, written to `out`
  // from its start; returns how many. len at most 64; `out` has room for
  // len + 8.
  static std::uint32_t pair_block(const Placed* __restrict P, const Placed& i, std::uint32_t b,
                                  std::uint32_t len, IndexPair* out);
  // The same eight records at a time with AVX-512F: the records' fields
  // gathered, the predicate's arithmetic in the same order (no fused
  // multiply-add), the hits' pairs compressed into `out` without a branch.
  static std::uint32_t pair_block_avx512(const Placed* __restrict P, const Placed& i,
                                         std::uint32_t b, std::uint32_t len, IndexPair* out);
  // The same four records at a time with AVX2 (loaded whole and
  // transposed: AMD's gathers are slow).
  static std::uint32_t pair_block_avx2(const Placed* __restrict P, const Placed& i, std::uint32_t b,
                                       std::uint32_t len, IndexPair* out);
  // Whether test_block and test_records use AVX2 (isa() at least avx2):
  // a relaxed load once the first call has set it.
  static bool avx2_tests() {
    int v = isa_in_use_.load(std::memory_order_relaxed);
    if (v < 0) v = static_cast<int>(isa());
    return v >= static_cast<int>(Isa::avx2);
  }
  static inline std::atomic<int> isa_in_use_{-1};  // isa(), once known
  // The hits among records [b, b + len) (len at most 64; up to three
  // records past them read), bit t for record b + t, four at a time with
  // AVX2; with `ks`, among records ks[0 .. len) instead (none read past).
  static std::uint64_t hits_avx2(const Placed* __restrict P, double x, double y, double z, double r,
                                 std::uint32_t b, std::uint32_t len);
  static std::uint64_t hits_avx2(const Placed* __restrict P, const std::uint32_t* ks,
                                 std::size_t len, double x, double y, double z, double r);
};

template <class Hit>
void SphereCells::test_block(const Placed* __restrict P, double x, double y, double z, double r,
                             std::uint32_t b, std::uint32_t len, Hit&& hit) {
  std::uint64_t hits = 0;
  if (avx2_tests())
    hits = hits_avx2(P, x, y, z, r, b, len);
  else
    for (std::uint32_t t = 0; t < len; t += 4) {
      std::uint64_t four = 0;
      for (std::uint32_t u = 0; u < 4; ++u)
        four |= static_cast<std::uint64_t>(overlaps(P[b + t + u], x, y, z, r)) << u;
      hits |= four << t;
    }
  if (len < 64) hits &= (std::uint64_t{1} << len) - 1;
  for (; hits != 0; hits &= hits - 1) hit(b + static_cast<std::uint32_t>(std::countr_zero(hits)));
}

}  // namespace broadphase::arrays::detail
