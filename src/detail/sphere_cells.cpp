#include "sphere_cells.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace broadphase::detail {

bool SphereCells::build(const Objects& o) {
  const std::size_t n = o.count;
  if (n < kMinObjects || n >= 0xFFFFFFFFu || o.radius.empty()) return false;
  if (o.kind != nullptr)
    for (std::size_t i = 0; i < n; ++i)
      if (o.kind[static_cast<std::ptrdiff_t>(i) * o.kind_stride] != 0) return false;
  double rmin = HUGE_VAL, rmax = 0;
  double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  const Column* col[3] = {&o.x, &o.y, &o.z};
  for (std::size_t i = 0; i < n; ++i) {
    const double r = o.radius.at(i);
    rmin = std::min(rmin, r);
    rmax = std::max(rmax, r);
    for (int a = 0; a < 3; ++a) {
      const double v = col[a]->at(i);
      lo[a] = std::min(lo[a], v);
      hi[a] = std::max(hi[a], v);
    }
  }
  // Two spheres that overlap are at most 2 rmax apart per axis, so less
  // than a cell: their cells differ by at most one per axis. The 2^-20
  // margin covers the rounding of (x - lo) / h, whose error is a few ulps
  // of a value below 2^26, far below 2^-20. A sparse set gets wider cells,
  // so that the grid stays dense (at most kMaxCellsPerObject cells an
  // object); the guard on the cells' occupancy below catches sets that
  // are sparse only on the whole (clusters far apart).
  const double reach = 2 * rmax * (1 + 0x1p-20);
  double h = reach;
  if (!(h > 0)) h = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1.0}) * 0x1p-10;
  std::size_t dims[3];
  auto grid_cells = [&](double side) {
    const double inv = 1 / side;
    double cells = 1;
    for (int a = 0; a < 3; ++a) {
      const double extent = (hi[a] - lo[a]) * inv;
      if (!(extent < 0x1p26)) return HUGE_VAL;
      dims[a] = static_cast<std::size_t>(extent) + 3;  // an empty cell either side
      cells *= static_cast<double>(dims[a]);
    }
    return cells;
  };
  const double most = static_cast<double>(kMaxCellsPerObject * n + 64);
  for (int k = 0; k < 400 && std::isfinite(h) && grid_cells(h) > most; ++k) h *= 1.25;
  const double inv = 1 / h;
  if (!std::isfinite(h) || !std::isfinite(inv) || grid_cells(h) > most) return false;
  // Radii far apart: cells as wide as the largest diameter would hold many
  // small spheres each (the multi-level grid suits those).
  if (h == reach && rmax > kMaxSpread * rmin) return false;
  nx_ = dims[0];
  nxy_ = dims[0] * dims[1];
  cells_ = nxy_ * dims[2];

  BigVector<std::uint32_t> key(n);
  start_.assign(cells_ + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t c = 0;
    for (int a = 2; a >= 0; --a)
      c = c * dims[a] + static_cast<std::size_t>((col[a]->at(i) - lo[a]) * inv) + 1;
    key[i] = static_cast<std::uint32_t>(c);
    ++start_[c + 1];
  }
  // The work of the scan grows as the sum of the cells' squared counts:
  // where spheres crowd into few cells, the multi-level grid is better.
  double crowd = 0;
  for (std::size_t c = 1; c <= cells_; ++c) crowd += static_cast<double>(start_[c]) * start_[c];
  if (crowd > static_cast<double>(kMaxCrowd * n)) {
    release();
    return false;
  }
  for (std::size_t c = 1; c <= cells_; ++c) start_[c] += start_[c - 1];
  x_.resize(n);
  y_.resize(n);
  z_.resize(n);
  r_.resize(n);
  id_.resize(n);
  // Stable: a cell lists its spheres by increasing index.
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t p = start_[key[i]]++;
    x_[p] = o.x.at(i);
    y_[p] = o.y.at(i);
    z_[p] = o.z.at(i);
    r_[p] = o.radius.at(i);
    id_[p] = static_cast<std::uint32_t>(i);
  }
  for (std::size_t c = cells_; c > 0; --c) start_[c] = start_[c - 1];
  start_[0] = 0;
  return true;
}

void SphereCells::release() {
  cells_ = 0;
  start_ = {};
  x_ = {};
  y_ = {};
  z_ = {};
  r_ = {};
  id_ = {};
}

std::uint64_t SphereCells::pairs(std::size_t c0, std::size_t c1,
                                 std::vector<IndexPair>& out) const {
  constexpr std::uint32_t kBuffer = 256;
  IndexPair buf[kBuffer + 64];
  std::uint32_t m = 0;
  std::uint64_t tests = 0;
  const std::uint32_t* st = start_.data();
  const double* __restrict X = x_.data();
  const double* __restrict Y = y_.data();
  const double* __restrict Z = z_.data();
  const double* __restrict R = r_.data();
  const std::uint32_t* __restrict id = id_.data();
  const std::size_t nx = nx_, nxy = nxy_;
  for (std::size_t c = c0; c < c1; ++c) {
    for (std::uint32_t a = st[c]; a < st[c + 1]; ++a) {
      const double xi = X[a], yi = Y[a], zi = Z[a], ri = R[a];
      const std::uint32_t ia = id[a];
      // The exact test without a branch per partner (about half of the
      // partners overlap in a dense set, a coin toss for a branch): a mask
      // of hits per 64 partners, then one step per hit.
      auto run = [&](std::uint32_t b, std::uint32_t e) {
        tests += e - b;
        while (b < e) {
          const std::uint32_t len = std::min<std::uint32_t>(e - b, 64);
          std::uint64_t hits = 0;
          std::uint32_t t = 0;
          for (; t < len; ++t) {
            const double dx = xi - X[b + t], dy = yi - Y[b + t], dz = zi - Z[b + t];
            const double d2 = dx * dx + dy * dy + dz * dz;
            const double sr = ri + R[b + t];
            hits |= static_cast<std::uint64_t>(d2 <= sr * sr) << t;
          }
          for (; hits != 0; hits &= hits - 1) {
            const std::uint32_t jb = id[b + static_cast<std::uint32_t>(std::countr_zero(hits))];
            buf[m++] = {std::min(ia, jb), std::max(ia, jb)};
          }
          if (m >= kBuffer) {
            out.insert(out.end(), buf, buf + m);
            m = 0;
          }
          b += len;
        }
      };
      // Own row: the rest of this cell and the next one along x.
      run(a + 1, st[c + 2]);
      // The next row in y, and the three rows of the next layer in z.
      run(st[c + nx - 1], st[c + nx + 2]);
      const std::size_t up = c + nxy;
      run(st[up - nx - 1], st[up - nx + 2]);
      run(st[up - 1], st[up + 2]);
      run(st[up + nx - 1], st[up + nx + 2]);
    }
  }
  out.insert(out.end(), buf, buf + m);
  return tests;
}

}  // namespace broadphase::detail
