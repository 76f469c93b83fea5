#include "sphere_kernel.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace broadphase::arrays::detail {

namespace {
// Two spheres that overlap are at most ri + rj apart per axis. A sphere
// sits on a grid whose cell is a hair wider than its diameter, and grids
// are coarser the later they come, so for a pair on one grid or on two,
// the coarser grid's cells are wider than that distance: the spheres'
// cells there differ by at most one per axis. The 2^-20 margin covers
// the rounding of (x - lo) / h, whose error is a few ulps of a value
// below 2^26, far below 2^-20.
constexpr double kMargin = 1 + 0x1p-20;
// NaN entries past the end of the columns (add_columns): the AVX2 scan
// reads eight partners from the start of each run, and a run may start at
// the end (an empty one).
constexpr std::size_t kColumnPad = 8;
}  // namespace

bool SphereCells::build(const Objects& o) { return build(o, kMaxCellsPerObject); }

bool SphereCells::build(const Objects& o, std::size_t cells_per_object) {
  return build_over(
      o, o.count, [](std::size_t k) { return k; }, std::max<std::size_t>(cells_per_object, 1));
}

bool SphereCells::build(const Objects& o, std::span<const std::uint32_t> subset,
                        std::size_t cells_per_object) {
  for (const std::uint32_t i : subset)
    if (i >= o.count) return fail();
  return build_over(
      o, subset.size(), [subset](std::size_t k) -> std::size_t { return subset[k]; },
      std::max<std::size_t>(cells_per_object, 1));
}

// The k-th sphere of the set is object at(k) of `o`.
template <class At>
bool SphereCells::build_over(const Objects& o, std::size_t n, At at, std::size_t cells_per_object) {
  release();
  if (n < kMinObjects || n >= 0xFFFFFFFFu || o.radius.empty()) return false;
  if (o.kind != nullptr)
    for (std::size_t i = 0; i < n; ++i)
      if (o.kind[static_cast<std::ptrdiff_t>(at(i)) * o.kind_stride] != 0) return false;
  if (o.x.empty() || o.y.empty() || o.z.empty()) return false;
  // One pass for the centres' box, the radii's extremes and the values'
  // check (a bad value: false, and the caller's check names it). A pass of
  // its own for the check cost 5% of a call at 1 000 000 spheres.
  double hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  for (double& v : lo_) v = HUGE_VAL;
  double rmin = HUGE_VAL, rmax_left = 0;
  bool valid = true;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = at(i);
    const double x = o.x.at(k), y = o.y.at(k), z = o.z.at(k), r = o.radius.at(k);
    // Bitwise on purpose (no branch per value); clang wants the operands as ints.
    valid &=
        static_cast<bool>(static_cast<int>(std::isfinite(x)) & static_cast<int>(std::isfinite(y)) &
                          static_cast<int>(std::isfinite(z)) & static_cast<int>(std::isfinite(r)) &
                          static_cast<int>(r >= 0));
    lo_[0] = std::min(lo_[0], x);
    hi[0] = std::max(hi[0], x);
    lo_[1] = std::min(lo_[1], y);
    hi[1] = std::max(hi[1], y);
    lo_[2] = std::min(lo_[2], z);
    hi[2] = std::max(hi[2], z);
    rmin = std::min(rmin, r);
    rmax_left = std::max(rmax_left, r);
  }
  if (!valid) return false;

  std::size_t dims[3];
  auto grid_cells = [&](double side) {
    const double inv = 1 / side;
    double cells = 1;
    for (int a = 0; a < 3; ++a) {
      const double extent = (hi[a] - lo_[a]) * inv;
      if (!(extent < 0x1p26)) return HUGE_VAL;
      dims[a] = static_cast<std::size_t>(extent) + 3;  // an empty cell either side
      cells *= static_cast<double>(dims[a]);
    }
    return cells;
  };
  // A grid of m spheres has at most cells_per_object cells a sphere (and
  // 64), or, while all grids together stay within that many cells per
  // sphere of the set, as many as its own diameter needs: a grid of few
  // large spheres is then as fine as they are (with one budget for all
  // grids the finest took nearly all of it, and the largest spheres of
  // scaled-uneven got cells 1.25 times their diameter, twice the tests).
  const double budget = static_cast<double>(cells_per_object * n + 64 * kMaxLevels);
  auto most = [&](std::size_t m) { return static_cast<double>(cells_per_object * m + 64); };
  auto allowed = [&](std::size_t m) {
    return std::max(most(m), budget - static_cast<double>(cells_));
  };
  // The narrowest cell from `h` up (in steps of a quarter) that fits in
  // `room` cells.
  auto dense = [&](double h, double room) {
    if (!(h > 0)) h = std::max({hi[0] - lo_[0], hi[1] - lo_[1], hi[2] - lo_[2], 1.0}) * 0x1p-10;
    for (int k = 0; k < 400 && std::isfinite(h) && grid_cells(h) > room; ++k) h *= 1.25;
    return h;
  };

  // The remaining spheres' smallest and largest radius (rmin, rmax_left),
  // found with the box above and again with each grid's members: spheres
  // of one size (or within a factor 2) need no pass of their own here.
  BigVector<std::uint8_t> level;
  std::size_t remaining = n;
  while (remaining > 0) {
    const std::size_t l = levels_.size();
    // The smallest remaining spheres, with all up to twice their size or
    // up to the narrowest cell the budget allows.
    const double cap =
        l + 1 < kMaxLevels ? dense(4 * kMargin * rmin, allowed(remaining)) : HUGE_VAL;
    const bool all = 2 * kMargin * rmax_left <= cap;
    double h = 0, rmax = rmax_left;
    std::size_t members = remaining;
    if (all) {
      h = dense(2 * kMargin * rmax, allowed(members));
    } else {
      if (level.empty()) {
        level.resize(n);
        for (std::size_t i = 0; i < n; ++i) level[i] = 0xFF;
      }
      // The members of that cap, then of their own cell (which may take
      // more: it is at least as wide as their largest diameter).
      double limit = cap;
      for (int round = 0; round < 2; ++round) {
        rmax = 0;
        members = 0;
        for (std::size_t i = 0; i < n; ++i)
          if (level[i] == 0xFF) {
            const double r = o.radius.at(at(i));
            if (2 * kMargin * r <= limit) {
              rmax = std::max(rmax, r);
              ++members;
            }
          }
        h = dense(2 * kMargin * rmax, allowed(members));
        limit = h;
      }
    }
    const double cells = grid_cells(h);
    if (!std::isfinite(h) || !(h > 0) || !std::isfinite(1 / h) || cells > allowed(members) ||
        cells_ + cells >= 0x1p32 || members == 0)
      return fail();
    Level lv;
    lv.h = h;
    lv.inv = 1 / h;
    lv.rmax = rmax;
    for (int a = 0; a < 3; ++a) lv.dims[a] = dims[a];
    lv.nx = dims[0];
    lv.nxy = dims[0] * dims[1];
    lv.cells = lv.nxy * dims[2];
    lv.first = cells_;
    cells_ += lv.cells;
    levels_.push_back(lv);
    if (all) {
      if (!level.empty())
        for (std::size_t i = 0; i < n; ++i)
          if (level[i] == 0xFF) level[i] = static_cast<std::uint8_t>(l);
      break;
    }
    rmin = HUGE_VAL;
    rmax_left = 0;
    double rmax_taken = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (level[i] == 0xFF) {
        const double r = o.radius.at(at(i));
        if (2 * kMargin * r <= h) {
          level[i] = static_cast<std::uint8_t>(l);
          --remaining;
          rmax_taken = std::max(rmax_taken, r);
        } else {
          rmin = std::min(rmin, r);
          rmax_left = std::max(rmax_left, r);
        }
      }
    // The grid's largest radius is that of the spheres it took: its cell,
    // widened to fit the budget in the second round, can be wider than the
    // limit that round counted members by, and then take larger spheres
    // than the rmax it found. Probes from finer grids reached only that far
    // and missed their pairs (a sphere of radius 183 on a grid whose rmax
    // said 161, in 3 of 14 640 slabs of the reference scene sizes-500).
    levels_.back().rmax = rmax_taken;
  }

  BigVector<std::uint32_t> key(n);
  start_.assign(cells_ + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Level& lv = level.empty() ? levels_[0] : levels_[level[i]];
    const std::size_t k = at(i);
    const std::size_t c = lv.cell_of(lo_, o.x.at(k), o.y.at(k), o.z.at(k));
    key[i] = static_cast<std::uint32_t>(c);
    ++start_[c + 1];
  }
  // The work of the scan grows as the sum of the cells' squared counts:
  // where spheres crowd into few cells, the multi-level grid is better.
  for (const Level& lv : levels_) {
    double crowd = 0, count = 0;
    for (std::size_t c = lv.first + 1; c <= lv.first + lv.cells; ++c) {
      crowd += static_cast<double>(start_[c]) * start_[c];
      count += start_[c];
    }
    if (crowd > static_cast<double>(kMaxCrowd) * count) return fail();
    if (count > 0) crowd_ = std::max(crowd_, crowd / count);
  }
  for (std::size_t c = 1; c <= cells_; ++c) start_[c] += start_[c - 1];
  // Three records past the end that overlap nothing (a NaN centre fails
  // every comparison): the scan reads partners four at a time.
  placed_.resize(n + 3);
  for (std::size_t k = n; k < n + 3; ++k) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    placed_[k] = {nan, nan, nan, 0, 0};
  }
  // Stable: a cell lists its spheres by increasing index.
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t p = start_[key[i]]++;
    const std::size_t k = at(i);
    placed_[p] = {o.x.at(k), o.y.at(k), o.z.at(k), o.radius.at(k), static_cast<std::uint32_t>(k)};
  }
  for (std::size_t c = cells_; c > 0; --c) start_[c] = start_[c - 1];
  start_[0] = 0;
  return true;
}

void SphereCells::validate() const {
  auto fail = [](const std::string& why) { throw std::logic_error("sphere kernel: " + why); };
  if (placed_.size() < 3) {
    if (!levels_.empty() || cells_ != 0) fail("grids without records");
    return;
  }
  const std::size_t n = size();
  if (levels_.empty() || levels_.size() > kMaxLevels) fail("no grids or too many");
  std::size_t first = 0;
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    const Level& g = levels_[l];
    const std::string name = "grid " + std::to_string(l);
    if (g.first != first || g.cells != g.dims[0] * g.dims[1] * g.dims[2] || g.nx != g.dims[0] ||
        g.nxy != g.dims[0] * g.dims[1])
      fail(name + "'s cells are counted wrongly");
    if (!(g.h > 0) || g.inv != 1 / g.h || !(2 * kMargin * g.rmax <= g.h))
      fail(name + "'s cell is not wider than its largest diameter");
    if (l > 0 && !(levels_[l - 1].h < g.h)) fail(name + " is not coarser than the one before");
    first += g.cells;
  }
  if (first != cells_ || start_.size() != cells_ + 1 || start_[0] != 0 || start_[cells_] != n)
    fail("the cells' starts do not cover the records");
  std::size_t l = 0;
  for (std::size_t c = 0; c < cells_; ++c) {
    if (start_[c] > start_[c + 1]) fail("cell " + std::to_string(c) + " ends before it starts");
    while (c >= levels_[l].first + levels_[l].cells) ++l;
    const Level& g = levels_[l];
    for (std::uint32_t k = start_[c]; k < start_[c + 1]; ++k) {
      const Placed& p = placed_[k];
      // (The name is made only for a failure: the tracker's validate()
      // runs this over every quiet sphere after each step of its tests.)
      auto fail_sphere = [&](const char* why) {
        fail("sphere " + std::to_string(p.id) + " (record " + std::to_string(k) + ", grid " +
             std::to_string(l) + ") " + why);
      };
      if (g.cell_of(lo_, p.x, p.y, p.z) != c) fail_sphere("is not in the cell of its centre");
      if (!(p.r <= g.rmax))
        fail_sphere("is larger than its grid's largest radius: probes fall short of it");
      if (!(2 * kMargin * p.r <= g.h)) fail_sphere("is wider than its grid's cell");
      if (k > start_[c] && !(placed_[k - 1].id < p.id)) fail_sphere("is out of order in its cell");
    }
  }
  for (std::size_t k = n; k < n + 3; ++k)
    if (!std::isnan(placed_[k].x) || !std::isnan(placed_[k].y) || !std::isnan(placed_[k].z))
      fail("record " + std::to_string(k) + " past the end overlaps");
  if (!cx_.empty()) {
    const std::size_t len = n + kColumnPad;
    if (cx_.size() != len || cy_.size() != len || cz_.size() != len || cr_.size() != len ||
        cid_.size() != len)
      fail("the columns are not as long as the records and their padding");
    auto same = [](double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); };
    for (std::size_t k = 0; k < len; ++k) {
      const Placed& p = placed_[std::min(k, n + 2)];
      if (!same(cx_[k], p.x) || !same(cy_[k], p.y) || !same(cz_[k], p.z) || !same(cr_[k], p.r) ||
          (k < n && cid_[k] != p.id))
        fail("column entry " + std::to_string(k) + " differs from its record");
    }
  }
}

bool SphereCells::fail() {
  release();
  return false;
}

void SphereCells::release() {
  levels_.clear();
  cells_ = 0;
  crowd_ = 0;
  free_vector(start_);
  free_vector(placed_);
  free_vector(cx_);
  free_vector(cy_);
  free_vector(cz_);
  free_vector(cr_);
  free_vector(cid_);
}

void SphereCells::add_columns() {
  // kColumnPad NaN entries past the end (the records have three): the
  // AVX2 scan reads eight partners from the start of each run.
  if (placed_.size() < 3) return;  // (not built)
  const std::size_t n = size();
  cx_.resize(n + kColumnPad);
  cy_.resize(n + kColumnPad);
  cz_.resize(n + kColumnPad);
  cr_.resize(n + kColumnPad);
  cid_.resize(n + kColumnPad);
  for (std::size_t k = 0; k < n + kColumnPad; ++k) {
    const Placed& p = placed_[std::min(k, n + 2)];
    cx_[k] = p.x;
    cy_[k] = p.y;
    cz_[k] = p.z;
    cr_[k] = p.r;
    cid_[k] = p.id;
  }
}

namespace {

std::atomic<SphereCells::Wide> wide_when{SphereCells::Wide::where_crowded};
std::atomic<SphereCells::Isa> isa_cap{SphereCells::Isa::avx512};

bool turned_off(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0';
}

// What the processor has, less what the environment turns off.
SphereCells::Isa isa_present() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  static const SphereCells::Isa present = [] {
    __builtin_cpu_init();
    if (!__builtin_cpu_supports("avx2") || turned_off("BROADPHASE_NO_AVX2"))
      return SphereCells::Isa::scalar;
    if (!__builtin_cpu_supports("avx512f") || turned_off("BROADPHASE_NO_AVX512"))
      return SphereCells::Isa::avx2;
    return SphereCells::Isa::avx512;
  }();
  return present;
#else
  return SphereCells::Isa::scalar;
#endif
}

}  // namespace

SphereCells::Isa SphereCells::isa() {
  const Isa use = std::min(isa_present(), isa_cap.load(std::memory_order_relaxed));
  isa_in_use_.store(static_cast<int>(use), std::memory_order_relaxed);
  return use;
}

void SphereCells::use_isa(Isa most) {
  isa_cap.store(most, std::memory_order_relaxed);
  isa();
}

void SphereCells::use_wide(Wide when) { wide_when.store(when, std::memory_order_relaxed); }

namespace {

// A sphere's partners after it on its own grid, as five runs of records
// [from, to): half the neighbours, the rest of its cell (record a is it)
// and the next one along x, the next row in y, the three rows of the next
// layer. The scans' one layout of them.
[[gnu::always_inline]] inline void own_runs(const std::uint32_t* st, std::size_t c, std::uint32_t a,
                                            std::size_t nx, std::size_t nxy, std::uint32_t from[5],
                                            std::uint32_t to[5]) {
  const std::size_t up = c + nxy;
  from[0] = a + 1;
  to[0] = st[c + 2];
  from[1] = st[c + nx - 1];
  to[1] = st[c + nx + 2];
  from[2] = st[up - nx - 1];
  to[2] = st[up - nx + 2];
  from[3] = st[up - 1];
  to[3] = st[up + 2];
  from[4] = st[up + nx - 1];
  to[4] = st[up + nx + 2];
}

}  // namespace

std::uint32_t SphereCells::pair_block(const Placed* __restrict P, const Placed& i, std::uint32_t b,
                                      std::uint32_t len, IndexPair* out) {
  std::uint32_t m = 0;
  test_block(P, i.x, i.y, i.z, i.r, b, len, [&](std::uint32_t k) {
    const std::uint32_t jb = P[k].id;
    out[m++] = {std::min(i.id, jb), std::max(i.id, jb)};
  });
  return m;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// GCC 12's AVX-512 intrinsics start from an undefined vector, which its
// -Wmaybe-uninitialized reports as ours (GCC bug 105593).
#pragma GCC diagnostic push
#if !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
namespace {

// Eight partners' (px, py, pz, pr, their indices pid) tests against the
// sphere (x, y, z, r) of index id, by the predicate of spheres_overlap in
// the arithmetic of `overlaps` (no fused multiply-add), lane by lane on
// `lanes`: the hits' pairs (min, max) written to `out` from its start
// without a branch; returns how many. The one wide arithmetic of both
// eight-at-a-time scans (records and columns).
[[gnu::always_inline]] __attribute__((target("avx512f"))) inline std::uint32_t wide_pairs(
    __m512d x, __m512d y, __m512d z, __m512d r, __m512i id, __m512d px, __m512d py, __m512d pz,
    __m512d pr, __m512i pid, __mmask8 lanes, IndexPair* out) {
  const __m512d dx = _mm512_sub_pd(x, px), dy = _mm512_sub_pd(y, py), dz = _mm512_sub_pd(z, pz);
  const __m512d sr = _mm512_add_pd(r, pr);
  const __m512d d2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                                   _mm512_mul_pd(dz, dz));
  const __mmask8 hit = _mm512_mask_cmp_pd_mask(lanes, d2, _mm512_mul_pd(sr, sr), _CMP_LE_OQ);
  // (min, max) as one 64-bit lane each: i in the low half, j in the high.
  const __m512i pair =
      _mm512_or_si512(_mm512_min_epu64(id, pid), _mm512_slli_epi64(_mm512_max_epu64(id, pid), 32));
  _mm512_storeu_si512(static_cast<void*>(out), _mm512_maskz_compress_epi64(hit, pair));
  return static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(hit)));
}

}  // namespace

// Measured on one core of the 2-core VM (AVX-512), 1 000 000 spheres of
// radius 0.00565 in the unit cube, 19 000 000 tests: the scan 94-97 ms
// one record at a time, 55-56 ms eight at a time. A run holds about four
// records: one at a time, each run's loop and its hits cost a mispredicted
// branch or two, about half the scan's time (a count of the hits alone,
// no pairs written, took 67 ms), the rest the tests in scalar arithmetic.
// Here a run up to eight long is one masked step, and its hits' pairs are
// written without a branch. A sketch with the fields in columns (masked
// loads instead of gathers) took 42 ms; the records stay, for the
// counting sort's scatter and the tracker's probes, which read a record
// per candidate.
__attribute__((target("avx512f"))) std::uint32_t SphereCells::pair_block_avx512(
    const Placed* __restrict P, const Placed& i, std::uint32_t b, std::uint32_t len,
    IndexPair* out) {
  static_assert(sizeof(Placed) == 36 && sizeof(IndexPair) == 8);
  const __m512d x = _mm512_set1_pd(i.x), y = _mm512_set1_pd(i.y), z = _mm512_set1_pd(i.z),
                r = _mm512_set1_pd(i.r);
  const __m512i id = _mm512_set1_epi64(i.id);
  const __m512i at = _mm512_setr_epi64(0, 36, 72, 108, 144, 180, 216, 252);
  const __m512d zero = _mm512_setzero_pd();
  std::uint32_t m = 0;
  for (std::uint32_t t = 0; t < len; t += 8) {
    const std::uint32_t left = len - t;
    const __mmask8 lanes = left >= 8 ? __mmask8(0xFF) : __mmask8((1u << left) - 1);
    const char* base = reinterpret_cast<const char*>(P + b + t);
    m += wide_pairs(x, y, z, r, id, _mm512_mask_i64gather_pd(zero, lanes, at, base, 1),
                    _mm512_mask_i64gather_pd(zero, lanes, at, base + 8, 1),
                    _mm512_mask_i64gather_pd(zero, lanes, at, base + 16, 1),
                    _mm512_mask_i64gather_pd(zero, lanes, at, base + 24, 1),
                    _mm512_cvtepu32_epi64(_mm512_mask_i64gather_epi32(_mm256_setzero_si256(), lanes,
                                                                      at, base + 32, 1)),
                    lanes, out + m);
  }
  return m;
}

// The arithmetic of pair_block_avx512, its partners read from the columns
// with masked loads, the whole scan compiled for AVX-512F (no call a run,
// the sphere's fields broadcast once for its five runs). For the tracker's
// movers among themselves (one coarse grid; at scaled-even 1 024 000, 3.4
// million tests in runs of about four), alternated on one core against
// the records: scaled-even 1 024 000, 40 calls, median 51.4-53.3 ->
// 47.7-49.3 ms; 102 400 3.92 -> 3.47 ms; study even 6 400 0.215 -> 0.196
// ms, uneven 0.381-0.384 -> 0.361-0.368 ms.
__attribute__((target("avx512f"))) std::uint64_t SphereCells::scan_columns(
    std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const {
  constexpr std::uint32_t kBuffer = 256;
  IndexPair buf[kBuffer + 64 + 8];
  std::uint32_t m = 0;
  std::uint64_t tests = 0;
  const std::uint32_t* st = start_.data();
  const double *X = cx_.data(), *Y = cy_.data(), *Z = cz_.data(), *R = cr_.data();
  const std::uint32_t* I = cid_.data();
  const std::size_t nx = levels_[0].nx, nxy = levels_[0].nxy;
  for (std::size_t c = c0; c < c1; ++c) {
    for (std::uint32_t a = st[c]; a < st[c + 1]; ++a) {
      const __m512d x = _mm512_set1_pd(X[a]), y = _mm512_set1_pd(Y[a]), z = _mm512_set1_pd(Z[a]),
                    r = _mm512_set1_pd(R[a]);
      const __m512i id = _mm512_set1_epi64(I[a]);
      // (A loop over the five runs: a lambda would not be compiled for
      // AVX-512F.)
      std::uint32_t from[5], to[5];
      own_runs(st, c, a, nx, nxy, from, to);
      for (int q = 0; q < 5; ++q) {
        const std::uint32_t e = to[q];
        tests += e - from[q];
        for (std::uint32_t b = from[q]; b < e; b += 8) {
          const std::uint32_t left = e - b;
          const __mmask8 lanes = left >= 8 ? __mmask8(0xFF) : __mmask8((1u << left) - 1);
          m += wide_pairs(x, y, z, r, id, _mm512_maskz_loadu_pd(lanes, X + b),
                          _mm512_maskz_loadu_pd(lanes, Y + b), _mm512_maskz_loadu_pd(lanes, Z + b),
                          _mm512_maskz_loadu_pd(lanes, R + b),
                          _mm512_cvtepu32_epi64(_mm512_castsi512_si256(
                              _mm512_maskz_loadu_epi32(__mmask16(lanes), I + b))),
                          lanes, buf + m);
          if (m >= kBuffer) {
            out.insert(out.end(), buf, buf + m);
            m = 0;
          }
        }
      }
    }
  }
  out.insert(out.end(), buf, buf + m);
  return tests;
}

namespace {

// For each mask of four lanes, the 32-bit words that put the hits' pairs
// (two words each) first, in order: _mm256_permutevar8x32_epi32's indices.
struct Compress4 {
  alignas(32) std::uint32_t idx[16][8];
  constexpr Compress4() : idx{} {
    for (unsigned m = 0; m < 16; ++m) {
      unsigned w = 0;
      for (unsigned lane = 0; lane < 4; ++lane)
        if (m >> lane & 1) {
          idx[m][w++] = 2 * lane;
          idx[m][w++] = 2 * lane + 1;
        }
    }
  }
};
constexpr Compress4 kCompress4;

// The predicate of spheres_overlap between the sphere (x, y, z, r) and
// four partners, in the arithmetic of `overlaps` (no fused multiply-add),
// lane by lane: the hits as four bits.
[[gnu::always_inline]] __attribute__((target("avx2"))) inline unsigned hits4(
    __m256d x, __m256d y, __m256d z, __m256d r, __m256d px, __m256d py, __m256d pz, __m256d pr) {
  const __m256d dx = _mm256_sub_pd(x, px), dy = _mm256_sub_pd(y, py), dz = _mm256_sub_pd(z, pz);
  const __m256d sr = _mm256_add_pd(r, pr);
  const __m256d d2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                                   _mm256_mul_pd(dz, dz));
  return static_cast<unsigned>(
      _mm256_movemask_pd(_mm256_cmp_pd(d2, _mm256_mul_pd(sr, sr), _CMP_LE_OQ)));
}

// The pairs (min, max) of the sphere of index `id` with the four partners
// of indices `pid` that `hit` marks, written to `out` from its start
// (four pairs' room) without a branch; returns how many.
[[gnu::always_inline]] __attribute__((target("avx2"))) inline std::uint32_t pairs4(__m128i id,
                                                                                   __m128i pid,
                                                                                   unsigned hit,
                                                                                   IndexPair* out) {
  const __m128i lo = _mm_min_epu32(id, pid), hi = _mm_max_epu32(id, pid);
  const __m256i pairs = _mm256_set_m128i(_mm_unpackhi_epi32(lo, hi), _mm_unpacklo_epi32(lo, hi));
  const __m256i order = _mm256_load_si256(reinterpret_cast<const __m256i*>(kCompress4.idx[hit]));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(out), _mm256_permutevar8x32_epi32(pairs, order));
  return static_cast<std::uint32_t>(std::popcount(hit));
}

// hits4 and pairs4 over the four column entries from b (columns' scan).
[[gnu::always_inline]] __attribute__((target("avx2"))) inline unsigned column_hits4(
    const double* X, const double* Y, const double* Z, const double* R, std::uint32_t b, __m256d x,
    __m256d y, __m256d z, __m256d r) {
  return hits4(x, y, z, r, _mm256_loadu_pd(X + b), _mm256_loadu_pd(Y + b), _mm256_loadu_pd(Z + b),
               _mm256_loadu_pd(R + b));
}
[[gnu::always_inline]] __attribute__((target("avx2"))) inline std::uint32_t column_pairs4(
    __m128i id, const std::uint32_t* I, std::uint32_t b, unsigned hit, IndexPair* out) {
  return pairs4(id, _mm_loadu_si128(reinterpret_cast<const __m128i*>(I + b)), hit, out);
}

// The x, y, z and r of four records (each read whole, 32 bytes from its
// start), transposed into a vector each.
[[gnu::always_inline]] __attribute__((target("avx2"))) inline void load4(
    const void* a, const void* b, const void* c, const void* d, __m256d& x, __m256d& y, __m256d& z,
    __m256d& r) {
  const __m256d r0 = _mm256_loadu_pd(static_cast<const double*>(a));
  const __m256d r1 = _mm256_loadu_pd(static_cast<const double*>(b));
  const __m256d r2 = _mm256_loadu_pd(static_cast<const double*>(c));
  const __m256d r3 = _mm256_loadu_pd(static_cast<const double*>(d));
  const __m256d xz01 = _mm256_unpacklo_pd(r0, r1), yr01 = _mm256_unpackhi_pd(r0, r1);
  const __m256d xz23 = _mm256_unpacklo_pd(r2, r3), yr23 = _mm256_unpackhi_pd(r2, r3);
  x = _mm256_permute2f128_pd(xz01, xz23, 0x20);
  z = _mm256_permute2f128_pd(xz01, xz23, 0x31);
  y = _mm256_permute2f128_pd(yr01, yr23, 0x20);
  r = _mm256_permute2f128_pd(yr01, yr23, 0x31);
}

}  // namespace

// Where the processor has AVX2 and no AVX-512F. Alternated on one core of
// a 2-core AMD EPYC VM (Zen 3) against one at a time, the same pairs
// (docs/arrays.md, "Vector forms"): study even 6 400 0.449-0.456 -> 0.360-0.384
// ms a call; one-shot clusters 200 000 50 -> 35-40 ms; the tracker at
// scaled-even 1 024 000 (also the probes and list tests below, and the
// columns' scan) 81-89 -> 68-75 ms.
__attribute__((target("avx2"))) std::uint32_t SphereCells::pair_block_avx2(
    const Placed* __restrict P, const Placed& i, std::uint32_t b, std::uint32_t len,
    IndexPair* out) {
  static_assert(sizeof(Placed) == 36 && sizeof(IndexPair) == 8);
  const __m256d x = _mm256_set1_pd(i.x), y = _mm256_set1_pd(i.y), z = _mm256_set1_pd(i.z),
                r = _mm256_set1_pd(i.r);
  const __m128i id = _mm_set1_epi32(static_cast<int>(i.id));
  std::uint32_t m = 0;
  for (std::uint32_t t = 0; t < len; t += 4) {
    const std::uint32_t left = len - t;
    const unsigned lanes = left >= 4 ? 0xFu : (1u << left) - 1;
    const Placed* q = P + b + t;  // (up to three past the run: see test_block)
    __m256d px, py, pz, pr;
    load4(q, q + 1, q + 2, q + 3, px, py, pz, pr);
    const __m128i pid = _mm_setr_epi32(static_cast<int>(q[0].id), static_cast<int>(q[1].id),
                                       static_cast<int>(q[2].id), static_cast<int>(q[3].id));
    m += pairs4(id, pid, hits4(x, y, z, r, px, py, pz, pr) & lanes, out + m);
  }
  return m;
}

__attribute__((target("avx2"))) std::uint64_t SphereCells::hits_avx2(const Placed* __restrict P,
                                                                     double x, double y, double z,
                                                                     double r, std::uint32_t b,
                                                                     std::uint32_t len) {
  const __m256d X = _mm256_set1_pd(x), Y = _mm256_set1_pd(y), Z = _mm256_set1_pd(z),
                R = _mm256_set1_pd(r);
  std::uint64_t hits = 0;
  for (std::uint32_t t = 0; t < len; t += 4) {
    const Placed* q = P + b + t;
    __m256d px, py, pz, pr;
    load4(q, q + 1, q + 2, q + 3, px, py, pz, pr);
    hits |= static_cast<std::uint64_t>(hits4(X, Y, Z, R, px, py, pz, pr)) << t;
  }
  return len < 64 ? hits & ((std::uint64_t{1} << len) - 1) : hits;
}

__attribute__((target("avx2"))) std::uint64_t SphereCells::hits_avx2(const Placed* __restrict P,
                                                                     const std::uint32_t* ks,
                                                                     std::size_t len, double x,
                                                                     double y, double z, double r) {
  const __m256d X = _mm256_set1_pd(x), Y = _mm256_set1_pd(y), Z = _mm256_set1_pd(z),
                R = _mm256_set1_pd(r);
  std::uint64_t hits = 0;
  std::size_t t = 0;
  __m256d px, py, pz, pr;
  for (; t + 4 <= len; t += 4) {
    load4(P + ks[t], P + ks[t + 1], P + ks[t + 2], P + ks[t + 3], px, py, pz, pr);
    hits |= static_cast<std::uint64_t>(hits4(X, Y, Z, R, px, py, pz, pr)) << t;
  }
  if (t < len) {  // the last one to three, the last record again in the lanes past them
    const std::size_t last = len - 1;
    load4(P + ks[t], P + ks[std::min(t + 1, last)], P + ks[std::min(t + 2, last)],
          P + ks[std::min(t + 3, last)], px, py, pz, pr);
    hits |= static_cast<std::uint64_t>(hits4(X, Y, Z, R, px, py, pz, pr) & ((1u << (len - t)) - 1))
            << t;
  }
  return hits;
}

// The wide scan of scan_columns with AVX2, four partners a step (the
// columns end in three NaN entries: a step may read past a run).
__attribute__((target("avx2"))) std::uint64_t SphereCells::scan_columns_avx2(
    std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const {
  constexpr std::uint32_t kBuffer = 256;
  IndexPair buf[kBuffer + 64 + 8];
  std::uint32_t m = 0;
  std::uint64_t tests = 0;
  const std::uint32_t* st = start_.data();
  const double *X = cx_.data(), *Y = cy_.data(), *Z = cz_.data(), *R = cr_.data();
  const std::uint32_t* I = cid_.data();
  const std::size_t nx = levels_[0].nx, nxy = levels_[0].nxy;
  for (std::size_t c = c0; c < c1; ++c) {
    for (std::uint32_t a = st[c]; a < st[c + 1]; ++a) {
      const __m256d x = _mm256_set1_pd(X[a]), y = _mm256_set1_pd(Y[a]), z = _mm256_set1_pd(Z[a]),
                    r = _mm256_set1_pd(R[a]);
      const __m128i id = _mm_set1_epi32(static_cast<int>(I[a]));
      std::uint32_t from[5], to[5];
      own_runs(st, c, a, nx, nxy, from, to);
      for (int q = 0; q < 5; ++q) {
        const std::uint32_t b0 = from[q], e = to[q], len = e - b0;
        tests += len;
        // The first eight partners without a branch on the run's length
        // (the columns end in eight NaN entries), and their pairs written
        // only when there is a hit (about one run in ten at scaled-even
        // 1 024 000's movers: 3.4 million tests in runs of 0 to 8 at about
        // one sphere a cell, for 103 000 pairs). Against a loop of four a
        // step writing every step's pairs, that scan alone, alternated on
        // one core of the AMD EPYC VM, three runs of 60: median 13.6-16.6
        // -> 11.2-13.4 ms.
        const unsigned lanes8 = len >= 8 ? 0xFFu : (1u << len) - 1;
        const unsigned hit0 = column_hits4(X, Y, Z, R, b0, x, y, z, r) & lanes8 & 0xFu;
        const unsigned hit1 = column_hits4(X, Y, Z, R, b0 + 4, x, y, z, r) & lanes8 >> 4;
        if ((hit0 | hit1) != 0) {
          m += column_pairs4(id, I, b0, hit0, buf + m);
          m += column_pairs4(id, I, b0 + 4, hit1, buf + m);
        }
        for (std::uint32_t b = b0 + 8; b < e; b += 4) {
          const std::uint32_t left = e - b;
          const unsigned lanes = left >= 4 ? 0xFu : (1u << left) - 1;
          m += column_pairs4(id, I, b, column_hits4(X, Y, Z, R, b, x, y, z, r) & lanes, buf + m);
          if (m >= kBuffer) {
            out.insert(out.end(), buf, buf + m);
            m = 0;
          }
        }
        if (m >= kBuffer) {
          out.insert(out.end(), buf, buf + m);
          m = 0;
        }
      }
    }
  }
  out.insert(out.end(), buf, buf + m);
  return tests;
}
#pragma GCC diagnostic pop
#else
std::uint32_t SphereCells::pair_block_avx512(const Placed* __restrict P, const Placed& i,
                                             std::uint32_t b, std::uint32_t len, IndexPair* out) {
  return pair_block(P, i, b, len, out);
}

std::uint32_t SphereCells::pair_block_avx2(const Placed* __restrict P, const Placed& i,
                                           std::uint32_t b, std::uint32_t len, IndexPair* out) {
  return pair_block(P, i, b, len, out);
}

std::uint64_t SphereCells::hits_avx2(const Placed* __restrict, double, double, double, double,
                                     std::uint32_t, std::uint32_t) {
  return 0;  // (isa() is scalar here: never called)
}

std::uint64_t SphereCells::hits_avx2(const Placed* __restrict, const std::uint32_t*, std::size_t,
                                     double, double, double, double) {
  return 0;
}

std::uint64_t SphereCells::scan_columns(std::size_t c0, std::size_t c1,
                                        std::vector<IndexPair>& out) const {
  return scan<Isa::scalar>(c0, c1, out);
}

std::uint64_t SphereCells::scan_columns_avx2(std::size_t c0, std::size_t c1,
                                             std::vector<IndexPair>& out) const {
  return scan<Isa::scalar>(c0, c1, out);
}
#endif

std::uint64_t SphereCells::pairs(std::size_t c0, std::size_t c1,
                                 std::vector<IndexPair>& out) const {
  // On sparse grids (radii over one or three decades, 100 000 spheres:
  // a crowd of 1.3-1.4, five tests a sphere, runs of one or two) the
  // scan took 8.3 and 6.6 ms one at a time, 9.7 and 8.0 ms eight at a time.
  const Isa use = isa();
  const bool wide =
      use != Isa::scalar &&
      (wide_when.load(std::memory_order_relaxed) == Wide::always || crowd_ >= kWideCrowd);
  if (wide && levels_.size() == 1 && cx_.size() >= size())
    return use == Isa::avx512 ? scan_columns(c0, c1, out) : scan_columns_avx2(c0, c1, out);
  if (!wide) return scan<Isa::scalar>(c0, c1, out);
  return use == Isa::avx512 ? scan<Isa::avx512>(c0, c1, out) : scan<Isa::avx2>(c0, c1, out);
}

template <SphereCells::Isa kIsa>
std::uint64_t SphereCells::scan(std::size_t c0, std::size_t c1, std::vector<IndexPair>& out) const {
  constexpr std::uint32_t kBuffer = 256;
  IndexPair buf[kBuffer + 64 + 8];
  std::uint32_t m = 0;
  std::uint64_t tests = 0;
  const std::uint32_t* st = start_.data();
  const Placed* __restrict P = placed_.data();
  std::size_t lv = 0;
  while (lv + 1 < levels_.size() && c0 >= levels_[lv + 1].first) ++lv;
  for (std::size_t c = c0; c < c1; ++c) {
    while (c >= levels_[lv].first + levels_[lv].cells) ++lv;
    const std::size_t nx = levels_[lv].nx, nxy = levels_[lv].nxy;
    for (std::uint32_t a = st[c]; a < st[c + 1]; ++a) {
      const Placed& i = P[a];
      // Partners after it: a pair per hit, handed on in batches.
      auto run = [&](std::uint32_t b, std::uint32_t e) {
        tests += e - b;
        for (; b < e; b += 64) {
          const std::uint32_t len = std::min<std::uint32_t>(e - b, 64);
          if constexpr (kIsa == Isa::avx512)
            m += pair_block_avx512(P, i, b, len, buf + m);
          else if constexpr (kIsa == Isa::avx2)
            m += pair_block_avx2(P, i, b, len, buf + m);
          else
            m += pair_block(P, i, b, len, buf + m);
          if (m >= kBuffer) {
            out.insert(out.end(), buf, buf + m);
            m = 0;
          }
        }
      };
      // Own grid, half the neighbours (own_runs), one call of `run` each:
      // as a loop over the five, the one-shot call at 200 000 coincident
      // spheres took 17.4-17.8 ms against 15.5-16.1.
      std::uint32_t from[5], to[5];
      own_runs(st, c, a, nx, nxy, from, to);
      run(from[0], to[0]);
      run(from[1], to[1]);
      run(from[2], to[2]);
      run(from[3], to[3]);
      run(from[4], to[4]);
      // Coarser grids: the cells within reach of this sphere, 2 or 3 a
      // side (a small sphere's reach, ri + the grid's largest radius, is
      // about half a cell there; all 27 cells read 3.4 times as many).
      // The reach is widened past the rounding of the predicate (relative
      // to the radii) and of xi - reach (relative to xi): a partner's
      // centre is then inside it, and the cells, monotone in x, hold it.
      const double centre[3] = {i.x, i.y, i.z};
      for (std::size_t k = lv + 1; k < levels_.size(); ++k) {
        const Level& g = levels_[k];
        const double reach = (i.r + g.rmax) * (1 + 0x1p-20);
        std::size_t from[3], to[3];
        for (int ax = 0; ax < 3; ++ax) {
          const double pad = reach + std::abs(centre[ax]) * 0x1p-48;
          from[ax] = g.index(ax, lo_[ax], centre[ax] - pad);
          to[ax] = g.index(ax, lo_[ax], centre[ax] + pad);
        }
        for (std::size_t cz = from[2]; cz <= to[2]; ++cz)
          for (std::size_t cy = from[1]; cy <= to[1]; ++cy) {
            const std::size_t row = g.first + cz * g.nxy + cy * g.nx;
            run(st[row + from[0]], st[row + to[0] + 1]);
          }
      }
    }
  }
  out.insert(out.end(), buf, buf + m);
  return tests;
}

}  // namespace broadphase::arrays::detail
