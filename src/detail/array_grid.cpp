#include "array_grid.hpp"

#include <algorithm>
#include <bit>

namespace broadphase::detail {
namespace {

// Each level's cells are twice those of the one below; an object sits on
// the finest level whose cell side is at least its widest side, so a probe
// spans at most 3 cells per axis. Levels above the base: 2^40 times the smallest cell covers any
// spread of sizes a finite float box set can sensibly have; wider objects are "big".
constexpr int kMaxLevels = 40;

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

void ArrayGrid::build(std::span<const AabbF> boxes) {
  boxes_ = boxes;
  const std::size_t n = boxes.size();
  levels_.clear();
  big_.clear();
  level_of_.assign(n, kBig);

  // The base cell: the width of a small object (the 1st percentile of a
  // sample), so that the finest level fits the small objects and a few
  // tiny outliers do not open many empty levels below them.
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
    if (w > 0 && std::isfinite(w)) {
      int e = 0;
      std::frexp(w, &e);  // w in [2^(e-1), 2^e)
      base = std::ldexp(1.0, e);
    }
  }
  if (!std::isfinite(base) || base <= 0) base = 1;

  std::vector<std::uint32_t> count(kMaxLevels, 0);
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
    top = std::max(top, k);
  }

  std::uint32_t buckets = 0;
  for (int k = 0; k <= top; ++k) {
    Level lv;
    lv.h = std::ldexp(base, k);
    lv.inv = 1 / lv.h;
    lv.count = count[k];
    const std::uint32_t size = lv.count == 0 ? 0 : std::bit_ceil(lv.count);
    lv.first_bucket = buckets;
    lv.mask = size == 0 ? 0 : size - 1;
    lv.distinct = true;
    for (int dx = -2; dx <= 2; ++dx)
      for (int dy = -2; dy <= 2; ++dy)
        for (int dz = -2; dz <= 2; ++dz)
          if ((dx || dy || dz) && (hash(dx, dy, dz) & lv.mask) == 0) lv.distinct = false;
    buckets += size;
    levels_.push_back(lv);
  }

  // Counting sort of the indices by bucket; stable, so a bucket lists its
  // objects in increasing index order whatever the thread count.
  std::vector<std::uint32_t> key(n);
  start_.assign(static_cast<std::size_t>(buckets) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (level_of_[i] == kBig) continue;
    const Level& lv = levels_[level_of_[i]];
    const AabbF& b = boxes[i];
    key[i] = lv.first_bucket +
             (hash(cell(b.lo[0], lv.inv), cell(b.lo[1], lv.inv), cell(b.lo[2], lv.inv)) & lv.mask);
    ++start_[key[i] + 1];
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
         big_.capacity() * sizeof(std::uint32_t);
}

void ArrayGrid::release() {
  levels_ = {};
  level_of_ = {};
  start_ = {};
  entries_ = {};
  big_ = {};
  boxes_ = {};
}

}  // namespace broadphase::detail
