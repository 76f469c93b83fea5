#include "box_grid.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <climits>

namespace broadphase::arrays::detail {
namespace {

// Each level's cells are twice those of the one below; an object sits on
// the finest level whose cell side is at least its widest side, so a probe
// spans at most 3 cells per axis. Levels above the base: 2^40 times the smallest cell covers any
// spread of sizes a finite float box set can sensibly have; wider objects are "big".
constexpr int kMaxLevels = 40;
// A hashed level is laid out row by row, wrapped, when its occupied cells
// are at most 2^kWrapBits times its buckets (see `build`).
constexpr int kWrapBits = 3;

double widest_side(const AabbF& b) {
  double w = 0;
  for (int a = 0; a < 3; ++a)
    w = std::max(w, static_cast<double>(b.hi[a]) - static_cast<double>(b.lo[a]));
  return w;
}

bool finite_box(const AabbF& b) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a])) return false;
  return true;
}

}  // namespace

void ArrayGrid::build(std::span<const AabbF> boxes, std::uint32_t dense, double min_cell) {
  boxes_ = boxes;
  const std::size_t n = boxes.size();
  levels_.clear();
  big_.clear();
  level_of_.assign(n, kBig);

  // The base cell: about the width of a small object (the 1st percentile
  // of a sample), so that the finest level fits the small objects and a few
  // tiny outliers do not open many empty levels below them. Levels double
  // from it; of four bases a quarter octave apart, the one that gives the
  // sample the smallest total cell volume is taken: with all objects of one
  // size a power-of-two base would leave cells up to twice their width
  // (27 cells of a probe's block then hold up to 8 times the partners).
  std::vector<double> sample;
  const std::size_t step = std::max<std::size_t>(1, n / 4096);
  for (std::size_t i = 0; i < n; i += step)
    if (finite_box(boxes[i])) sample.push_back(widest_side(boxes[i]));
  double base = 1;
  if (!sample.empty()) {
    const std::size_t k = sample.size() / 100;
    std::nth_element(sample.begin(), sample.begin() + static_cast<std::ptrdiff_t>(k), sample.end());
    double w = sample[k];
    if (w <= 0) {
      w = 0;
      for (double s : sample)
        if (s > 0 && (w == 0 || s < w)) w = s;
    }
    if (min_cell > 0 && w <= min_cell && std::isfinite(min_cell)) {
      // The caller's finest cells, exactly: rounding them up like a
      // sample's width (below) raised a tracker's cells by a quarter octave
      // at each compaction, 8 times in 100 frames of its moving workload,
      // and the calls grew from 17 to 900 ms.
      base = min_cell;
    } else if (w > 0 && std::isfinite(w)) {
      int e = 0;
      std::frexp(w, &e);  // w in [2^(e-1), 2^e)
      base = std::ldexp(1.0, e);
      double best = HUGE_VAL;
      const double first = base;
      for (int q = 0; q < 4; ++q) {
        // Smaller bases down to the 1st percentile's width (+ the margin).
        const double b = first * std::exp2(-0.25 * q);
        if (b < w * (1 + 0x1p-20)) break;
        double volume = 0;
        for (double s : sample) {
          double h = b;
          for (int lv = 0; h < s * (1 + 0x1p-20) && lv < kMaxLevels; ++lv) h *= 2;
          volume += h * h * h;
        }
        if (volume < best) {
          best = volume;
          base = b;
        }
      }
    }
  }
  if (!std::isfinite(base) || base <= 0) base = 1;

  std::vector<std::uint32_t> count(kMaxLevels, 0);
  // Each level's occupied cells: low and high cell per axis.
  std::vector<std::array<std::int64_t, 6>> span(
      kMaxLevels, {INT64_MAX, INT64_MIN, INT64_MAX, INT64_MIN, INT64_MAX, INT64_MIN});
  int top = -1;
  for (std::size_t i = 0; i < n; ++i) {
    const AabbF& b = boxes[i];
    if (!finite_box(b)) {
      big_.push_back(static_cast<std::uint32_t>(i));
      continue;
    }
    // A cell a hair wider than the box (see the probe's bound), so that the
    // probe's rounding of lo - h can never skip a partner's cell.
    const double w2 = widest_side(b) * (1 + 0x1p-20);
    int k = 0;
    double h = base;
    while (h < w2 && k < kMaxLevels) {
      h *= 2;
      ++k;
    }
    if (k >= kMaxLevels || !std::isfinite(h)) {
      big_.push_back(static_cast<std::uint32_t>(i));
      continue;
    }
    level_of_[i] = static_cast<std::uint8_t>(k);
    ++count[k];
    const double inv = 1 / h;
    auto& sp = span[k];
    for (int a = 0; a < 3; ++a) {
      const std::int64_t c = cell(b.lo[a], inv);
      sp[2 * a] = std::min(sp[2 * a], c);
      sp[2 * a + 1] = std::max(sp[2 * a + 1], c);
    }
    top = std::max(top, k);
  }

  std::uint32_t buckets = 0;
  std::size_t summary_words = 0;
  for (int k = 0; k <= top; ++k) {
    Level lv;
    lv.h = std::ldexp(base, k);
    lv.inv = 1 / lv.h;
    lv.count = count[k];
    std::uint32_t size = lv.count == 0 ? 0 : std::bit_ceil(lv.count);
    if (lv.count > 0) {
      // Bits per axis for the occupied span and a probe's margin of two
      // cells either side: the cells of the span then never share a bucket.
      int bits[3];
      for (int a = 0; a < 3; ++a) {
        const std::uint64_t extent =
            static_cast<std::uint64_t>(span[k][2 * a + 1] - span[k][2 * a]) + 5;
        bits[a] = std::bit_width(extent - 1);
      }
      const int total = bits[0] + bits[1] + bits[2];
      // Dense: one bucket per cell of the occupied span. Wrapped: too many
      // cells for a bucket each, but few enough for the same row by row
      // layout wrapped around the buckets, so that z-slabs
      // 2^(m - bits x - bits y) apart share buckets (at most 2^kWrapBits
      // cells a bucket, by construction, whatever the occupancy). Either
      // way rows of cells next to each other in y and z sit in buckets at
      // fixed distances, and probing in bucket order reads the 9 rows of a
      // block as 9 streams; odd multipliers sent each row to a cold bucket
      // (the tracker's scan and renewals at scaled-even 1 024 000, where the
      // level of a third of the objects is hashed).
      const int m = std::bit_width(size) - 1;
      const bool fits = total <= 30 && (std::uint64_t{1} << total) <= std::uint64_t{dense} * size;
      if (fits || (bits[0] + bits[1] <= m && total <= m + kWrapBits)) {
        lv.ky = std::uint64_t{1} << bits[0];
        lv.kz = std::uint64_t{1} << (bits[0] + bits[1]);
        lv.shift = 0 - (static_cast<std::uint64_t>(span[k][0] - 2) +
                        static_cast<std::uint64_t>(span[k][2] - 2) * lv.ky +
                        static_cast<std::uint64_t>(span[k][4] - 2) * lv.kz);
      }
      if (fits) {
        lv.dense = true;
        size = std::uint32_t{1} << total;
      }
      for (int a = 0; a < 3; ++a) {
        lv.lo[a] = span[k][2 * a];
        lv.hi[a] = span[k][2 * a + 1];
      }
      if (!lv.dense) {
        // A hashed level's cells are sparse: a bit per block of 2^s cells
        // a side, about 8 bits an object, tells a probe whether anything
        // of the level lies near before it reads the level's buckets.
        const std::uint64_t budget = 8 * std::uint64_t{lv.count} + 64;
        for (lv.sum_shift = 0; lv.sum_shift < 62; ++lv.sum_shift) {
          const double cells = static_cast<double>(((lv.hi[0] - lv.lo[0]) >> lv.sum_shift) + 1) *
                               static_cast<double>(((lv.hi[1] - lv.lo[1]) >> lv.sum_shift) + 1) *
                               static_cast<double>(((lv.hi[2] - lv.lo[2]) >> lv.sum_shift) + 1);
          if (cells <= static_cast<double>(budget)) break;
        }
        lv.sum_nx = static_cast<std::uint64_t>((lv.hi[0] - lv.lo[0]) >> lv.sum_shift) + 1;
        lv.sum_ny = static_cast<std::uint64_t>((lv.hi[1] - lv.lo[1]) >> lv.sum_shift) + 1;
        const std::uint64_t nz =
            static_cast<std::uint64_t>((lv.hi[2] - lv.lo[2]) >> lv.sum_shift) + 1;
        lv.sum_first = summary_words;
        summary_words += (lv.sum_nx * lv.sum_ny * nz + 63) / 64;
      }
    }
    lv.first_bucket = buckets;
    lv.mask = size == 0 ? 0 : size - 1;
    lv.distinct = true;
    for (int dx = -2; dx <= 2; ++dx)
      for (int dy = -2; dy <= 2; ++dy)
        for (int dz = -2; dz <= 2; ++dz)
          if ((dx || dy || dz) && ((hash(lv, dx, dy, dz) - hash(lv, 0, 0, 0)) & lv.mask) == 0)
            lv.distinct = false;  // (the hash's shift cancels)
    buckets += size;
    levels_.push_back(lv);
  }

  // Counting sort of the indices by bucket; stable, so a bucket lists its
  // objects in increasing index order whatever the thread count.
  BigVector<std::uint32_t> key(n);
  start_.assign(static_cast<std::size_t>(buckets) + 1, 0);
  summary_.assign(summary_words, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (level_of_[i] == kBig) continue;
    const Level& lv = levels_[level_of_[i]];
    const AabbF& b = boxes[i];
    const std::int64_t cx = cell(b.lo[0], lv.inv), cy = cell(b.lo[1], lv.inv),
                       cz = cell(b.lo[2], lv.inv);
    key[i] = lv.first_bucket + (hash(lv, cx, cy, cz) & lv.mask);
    ++start_[key[i] + 1];
    if (!lv.dense) {
      const std::uint64_t bit = summary_bit(lv, cx, cy, cz);
      summary_[lv.sum_first + bit / 64] |= std::uint64_t{1} << (bit % 64);
    }
  }
  for (std::size_t b = 1; b < start_.size(); ++b) start_[b] += start_[b - 1];
  entries_.resize(n - big_.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (level_of_[i] == kBig) continue;
    entries_[start_[key[i]]++] = {boxes[i], static_cast<std::uint32_t>(i)};
  }
  for (std::size_t b = start_.size() - 1; b > 0; --b) start_[b] = start_[b - 1];
  start_[0] = 0;
}

std::size_t ArrayGrid::memory_bytes() const {
  return levels_.capacity() * sizeof(Level) + level_of_.capacity() +
         start_.capacity() * sizeof(std::uint32_t) + entries_.capacity() * sizeof(GridEntry) +
         big_.capacity() * sizeof(std::uint32_t) + summary_.capacity() * sizeof(std::uint64_t);
}

void ArrayGrid::release() {
  free_vector(levels_);
  free_vector(level_of_);
  free_vector(start_);
  free_vector(entries_);
  free_vector(big_);
  free_vector(summary_);
  boxes_ = {};
}

}  // namespace broadphase::arrays::detail
