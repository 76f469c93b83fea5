/// \file neighbours.cpp
/// The neighbour-list engine of neighbours.hpp: a cell list over fractional
/// coordinates, a conservative prefilter on wrapped positions, the exact
/// rule on the positions as given, and a counting sort into the output order.
#include <algorithm>
#include <broadphase/neighbours.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "engine.hpp"
#include "frame.hpp"
#include "vector_pass.hpp"

namespace broadphase {
namespace {

using arrays::Column;
using neighbours_detail::Binned;
using neighbours_detail::PackedFound;
using neighbours_detail::Run;
using neighbours_detail::VectorReaches;
#if BROADPHASE_NEIGHBOURS_AVX512
using neighbours_detail::pick_avx512;
using neighbours_detail::records_avx512;
#endif
using neighbours_detail::WideFound;
namespace rule = neighbour_rule;

// Limits that keep every integer in range: |floor(s)| of a point on a
// periodic axis, and a cutoff's reach in bins.
constexpr double kMaxWrap = 268435456.0;  // 2^28
constexpr std::int64_t kMaxReach = 1 << 20;
constexpr double kMaxBinsPerAxis = 1048576.0;  // 2^20

[[noreturn]] void refuse(const std::string& what) { throw InvalidNeighbourInput(what); }

Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
double norm(Vec3 a) { return std::sqrt(dot(a, a)); }
Vec3 unit(Vec3 a) { return a * (1.0 / norm(a)); }

}  // namespace

namespace neighbours_detail {

std::string number(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

Frame make_frame(const NeighbourCell& cell) {
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(cell.vectors[r][k]))
        refuse("cell[" + std::to_string(r) + ", " + std::to_string(k) + "]: not finite (" +
               number(cell.vectors[r][k]) + ")");
  std::array<Vec3, 3> b = cell.vectors;
  std::vector<int> per, free;
  for (int k = 0; k < 3; ++k) (cell.periodic[k] ? per : free).push_back(k);
  for (int k : per)
    if (norm(b[k]) == 0) refuse("cell: periodic vector " + std::to_string(k) + " is zero");
  if (per.empty()) {
    b = {Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
  } else if (per.size() == 1) {
    const Vec3 a = b[per[0]];
    const Vec3 e = std::fabs(a.x) <= std::fabs(a.y) && std::fabs(a.x) <= std::fabs(a.z)
                       ? Vec3{1, 0, 0}
                       : (std::fabs(a.y) <= std::fabs(a.z) ? Vec3{0, 1, 0} : Vec3{0, 0, 1});
    const Vec3 u = unit(cross(a, e));
    b[free[0]] = u;
    b[free[1]] = unit(cross(a, u));
  } else if (per.size() == 2) {
    const Vec3 n = cross(b[per[0]], b[per[1]]);
    if (norm(n) == 0) refuse("cell: the periodic vectors are parallel");
    b[free[0]] = unit(n);
  }
  const double det = dot(b[0], cross(b[1], b[2]));
  // A cell much thinner than its vectors are long reads as dependent.
  const double size = norm(b[0]) * norm(b[1]) * norm(b[2]);
  if (!(std::fabs(det) > size * 1e-12))
    refuse("cell: the periodic vectors are linearly dependent (volume " + number(det) + ")");
  Frame f;
  f.col[0] = cross(b[1], b[2]) * (1.0 / det);
  f.col[1] = cross(b[2], b[0]) * (1.0 / det);
  f.col[2] = cross(b[0], b[1]) * (1.0 / det);
  for (int k = 0; k < 3; ++k) f.spread[k] = norm(f.col[k]);
  return f;
}

void check_cutoff(double v, const std::string& name) {
  if (!std::isfinite(v) || v < 0) refuse(name + ": must be finite and >= 0 (" + number(v) + ")");
}

}  // namespace neighbours_detail

namespace {

using neighbours_detail::check_cutoff;
using neighbours_detail::Frame;
using neighbours_detail::make_frame;
using neighbours_detail::number;
using neighbours_detail::parts_for;
using neighbours_detail::reserve_large;
using neighbours_detail::resize_large;
using neighbours_detail::run_parts;

/// One set of points as the engine reads it: positions as given, fractional
/// coordinates, and on periodic axes the wrap count n = floor(s).
struct PointSet {
  NeighbourVector<Vec3> x;
  NeighbourVector<std::array<double, 3>> s;
  NeighbourVector<std::array<std::int32_t, 3>> n;
  double max_abs_x = 0;
  double max_abs_s = 0;
  std::array<double, 3> lo{}, hi{};            // fractional range on each axis
  std::array<std::int32_t, 3> n_lo{}, n_hi{};  // range of the wrap counts
};

PointSet read_points(const NeighbourPoints& p, const NeighbourCell& cell, const Frame& f,
                     const char* name, unsigned threads) {
  if (p.count > std::numeric_limits<std::uint32_t>::max() - 1)
    refuse(std::string(name) + ": more than 2^32 - 2 points");
  PointSet out;
  resize_large(out.x, p.count);
  resize_large(out.s, p.count);
  resize_large(out.n, p.count);
  // By parts of the points, each with its own ranges, joined after; the
  // first part's error is the first row's.
  const unsigned parts = parts_for(p.count, threads);
  std::vector<PointSet> range(parts);
  const Column cols[3] = {p.x, p.y, p.z};
  run_parts(parts, [&](unsigned part) {
    PointSet& r = range[part];
    r.lo = {HUGE_VAL, HUGE_VAL, HUGE_VAL};
    r.hi = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (std::size_t i = p.count * part / parts, end = p.count * (part + 1) / parts; i < end; ++i) {
      Vec3 v;
      for (int k = 0; k < 3; ++k) {
        v[k] = cols[k].at(i);
        if (!std::isfinite(v[k]))
          refuse(std::string(name) + "[" + std::to_string(i) + ", " + std::to_string(k) +
                 "]: not finite (" + number(v[k]) + ")");
        r.max_abs_x = std::max(r.max_abs_x, std::fabs(v[k]));
      }
      out.x[i] = v;
      for (int k = 0; k < 3; ++k) {
        const double s = dot(v, f.col[k]);
        out.s[i][k] = s;
        r.max_abs_s = std::max(r.max_abs_s, std::fabs(s));
        r.lo[k] = std::min(r.lo[k], s);
        r.hi[k] = std::max(r.hi[k], s);
        std::int32_t n = 0;
        if (cell.periodic[k]) {
          const double w = std::floor(s);
          if (!(std::fabs(w) <= kMaxWrap))
            refuse(std::string(name) + "[" + std::to_string(i) +
                   "]: more than 2^28 cells away from the cell on axis " + std::to_string(k));
          n = static_cast<std::int32_t>(w);
        }
        out.n[i][k] = n;
        r.n_lo[k] = std::min(r.n_lo[k], n);
        r.n_hi[k] = std::max(r.n_hi[k], n);
      }
    }
  });
  out.lo = {HUGE_VAL, HUGE_VAL, HUGE_VAL};
  out.hi = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  for (const PointSet& r : range) {
    out.max_abs_x = std::max(out.max_abs_x, r.max_abs_x);
    out.max_abs_s = std::max(out.max_abs_s, r.max_abs_s);
    for (int k = 0; k < 3; ++k) {
      out.lo[k] = std::min(out.lo[k], r.lo[k]);
      out.hi[k] = std::max(out.hi[k], r.hi[k]);
      out.n_lo[k] = std::min(out.n_lo[k], r.n_lo[k]);
      out.n_hi[k] = std::max(out.n_hi[k], r.n_hi[k]);
    }
  }
  return out;
}

/// The bins: nb[k] per axis over [lo, lo + nb * width) in fractional units
/// ([0, 1) on a periodic axis), and the reach in bins of the largest
/// cutoff, rounding margin included.
struct Grid {
  std::array<std::int64_t, 3> nb{1, 1, 1};
  std::array<double, 3> lo{}, width{1, 1, 1};
  std::array<std::int64_t, 3> reach{0, 0, 0};
  std::array<bool, 3> periodic{};
  double margin = 0;  // length added to every reach in the prefilter

  std::int64_t bins() const { return nb[0] * nb[1] * nb[2]; }
  /// The bin coordinate of fractional coordinate s on axis k, clamped to
  /// [-reach - 1, nb + reach] (a query far outside reaches no bin).
  std::int64_t coordinate(int k, double s) const {
    double t = periodic[k] ? (s - std::floor(s)) / width[k] : (s - lo[k]) / width[k];
    t = std::floor(t);
    const double top = static_cast<double>(periodic[k] ? nb[k] - 1 : nb[k] + reach[k]);
    const double bottom = periodic[k] ? 0.0 : static_cast<double>(-reach[k] - 1);
    return static_cast<std::int64_t>(std::clamp(t, bottom, top));
  }
};

Grid make_grid(const NeighbourCell& cell, const Frame& f, const PointSet& pts,
               const PointSet* queries, double reach) {
  Grid g;
  g.periodic = cell.periodic;
  const std::size_t n = pts.x.size();
  double max_abs_x = pts.max_abs_x, max_abs_s = pts.max_abs_s;
  if (queries) {
    max_abs_x = std::max(max_abs_x, queries->max_abs_x);
    max_abs_s = std::max(max_abs_s, queries->max_abs_s);
  }
  // Bins about one reach wide across their planes: a neighbour lies in the
  // 27 bins around (13 of them and the own bin for a half list), ~2.7
  // points a bin at liquid density with a 3 Å cutoff.
  std::array<double, 3> ideal{};
  for (int k = 0; k < 3; ++k) {
    const double extent = cell.periodic[k] ? 1.0 : (n ? pts.hi[k] - pts.lo[k] : 0.0);
    const double per_bin = reach * f.spread[k] * (1 + 0x1p-30);
    ideal[k] = per_bin > 0 ? extent / per_bin : kMaxBinsPerAxis;
    ideal[k] = std::clamp(std::floor(std::min(ideal[k], kMaxBinsPerAxis)), 1.0, kMaxBinsPerAxis);
  }
  // At most about two bins a point (the empty ones cost a visit each).
  const double limit = std::max(64.0, 2.0 * static_cast<double>(n));
  while (ideal[0] * ideal[1] * ideal[2] > limit) {
    const int k = static_cast<int>(std::max_element(ideal.begin(), ideal.end()) - ideal.begin());
    ideal[k] = std::max(1.0, std::floor(ideal[k] / 2));
  }
  double scale = 3 * max_abs_x + reach;
  for (int k = 0; k < 3; ++k) {
    g.nb[k] = static_cast<std::int64_t>(ideal[k]);
    if (cell.periodic[k]) {
      g.lo[k] = 0;
      g.width[k] = 1.0 / ideal[k];
      const Vec3 v = cell.vectors[k];
      scale += (max_abs_s + reach * f.spread[k] + 3) *
               (std::fabs(v.x) + std::fabs(v.y) + std::fabs(v.z));
    } else {
      g.lo[k] = n ? pts.lo[k] : 0.0;
      const double extent = n ? pts.hi[k] - pts.lo[k] : 0.0;
      g.width[k] = extent > 0 ? extent / ideal[k] : 1.0;
    }
  }
  // Rounding: positions, fractional coordinates and wrapped positions are
  // each within a few ulps of `scale` (|x|, |n·cell|, |S·cell| together) of
  // their real values; 2^-40 of it is thousands of times that.
  g.margin = 0x1p-40 * scale;
  const double frac_error = 0x1p-40 * (1 + max_abs_s);
  for (int k = 0; k < 3; ++k) {
    const double r =
        std::ceil(((reach + g.margin) * f.spread[k] * (1 + 0x1p-40) + 4 * frac_error) / g.width[k]);
    if (cell.periodic[k]) {
      if (!(r <= static_cast<double>(kMaxReach)))
        refuse("cutoff: reaches more than 2^20 cells on axis " + std::to_string(k));
      g.reach[k] = static_cast<std::int64_t>(r);
    } else {
      // Only offsets that land in [0, nb) are walked; the reach itself
      // decides which bins a query outside the points' range sees.
      g.reach[k] = static_cast<std::int64_t>(std::min(r, 0x1p40));
    }
  }
  return g;
}

Binned bin_points(const Grid& g, const NeighbourCell& cell, const PointSet& pts,
                  const std::vector<double>& cut, unsigned threads) {
  const std::size_t n = pts.x.size();
  const std::int64_t bins = g.bins();
  const unsigned parts = parts_for(n, threads);
  // The bins of points, and the gather below, by parts of the points and of
  // the slots; counting and placing the ids stay on one thread (a pass of
  // 4 or 8 bytes a point).
  NeighbourVector<std::int64_t> bin;
  resize_large(bin, n);
  run_parts(parts, [&](unsigned p) {
    for (std::size_t i = n * p / parts, hi = n * (p + 1) / parts; i < hi; ++i) {
      std::int64_t c[3];
      for (int k = 0; k < 3; ++k)
        c[k] = std::clamp<std::int64_t>(g.coordinate(k, pts.s[i][k]), 0, g.nb[k] - 1);
      bin[i] = (c[0] * g.nb[1] + c[1]) * g.nb[2] + c[2];
    }
  });
  Binned b;
  b.start.assign(static_cast<std::size_t>(bins) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++b.start[static_cast<std::size_t>(bin[i]) + 1];
  for (std::int64_t k = 0; k < bins; ++k) b.start[k + 1] += b.start[k];
  // The ids by bin (a scatter of 4 bytes a point), then the slots' data
  // gathered in slot order: at 10^6 points, scattering the whole records
  // took a sixth of the list (perf).
  {
    std::vector<std::int64_t> fill(b.start.begin(), b.start.end() - 1);
    resize_large(b.id, n);
    for (std::size_t i = 0; i < n; ++i)
      b.id[static_cast<std::size_t>(fill[static_cast<std::size_t>(bin[i])]++)] =
          static_cast<std::uint32_t>(i);
  }
  for (auto* v : {&b.wx, &b.wy, &b.wz}) resize_large(*v, n);
  if (!cut.empty()) resize_large(b.wc, n);
  resize_large(b.x, n);
  resize_large(b.n, n);
  run_parts(parts, [&](unsigned p) {
    // The points are read in bin order, a miss each: fetched 16 slots ahead.
    constexpr std::size_t kAhead = 16;
    for (std::size_t slot = n * p / parts, hi = n * (p + 1) / parts; slot < hi; ++slot) {
      if (slot + kAhead < hi) {
        const std::uint32_t ahead = b.id[slot + kAhead];
        __builtin_prefetch(&pts.x[ahead]);
        __builtin_prefetch(&pts.n[ahead]);
      }
      const std::uint32_t i = b.id[slot];
      const Vec3 o = rule::image_offset(cell, pts.n[i][0], pts.n[i][1], pts.n[i][2]);
      b.wx[slot] = pts.x[i].x - o.x;
      b.wy[slot] = pts.x[i].y - o.y;
      b.wz[slot] = pts.x[i].z - o.z;
      if (!cut.empty()) b.wc[slot] = cut[i];
      b.x[slot] = pts.x[i];
      b.n[slot] = pts.n[i];
    }
  });
  return b;
}

/// Per axis, the bin and wrap shift of every bin coordinate t in
/// [-reach, nb + reach) (periodic axes; -1 for a coordinate outside a
/// non-periodic axis): a table instead of a division per bin and offset.
struct Wraps {
  std::array<std::vector<std::int64_t>, 3> bin, shift;
  std::array<std::int64_t, 3> base{};

  Wraps(const Grid& g, const std::array<std::int64_t, 3>& reach) {
    for (int k = 0; k < 3; ++k) {
      base[k] = reach[k];
      const std::int64_t size = g.nb[k] + 2 * reach[k];
      bin[k].resize(static_cast<std::size_t>(size));
      shift[k].resize(static_cast<std::size_t>(size));
      for (std::int64_t u = 0; u < size; ++u) {
        const std::int64_t t = u - reach[k];
        std::int64_t sh = 0, b = t;
        if (g.periodic[k]) {
          sh = t >= 0 ? t / g.nb[k] : -((-t + g.nb[k] - 1) / g.nb[k]);
          b = t - sh * g.nb[k];
        } else if (t < 0 || t >= g.nb[k]) {
          b = -1;
        }
        bin[k][static_cast<std::size_t>(u)] = b;
        shift[k][static_cast<std::size_t>(u)] = sh;
      }
    }
  }
  /// False when t lies outside a non-periodic axis.
  bool resolve(int k, std::int64_t t, std::int64_t& b, std::int64_t& sh) const {
    const auto u = static_cast<std::size_t>(t + base[k]);
    b = bin[k][u];
    sh = shift[k][u];
    return b >= 0;
  }
};

/// Everything a pair test needs.
struct Context {
  const NeighbourCell* cell;
  const PointSet* home;            // the points of `i` (queries in the between mode)
  const PointSet* other;           // the points of `j`
  const std::vector<double>* cut;  // per-point cutoffs, or empty
  double cutoff;                   // the one cutoff
  CutoffRule rule;
};

/// The exact rule for i at xi and j at xj (cutoffs ci, cj) under shift S.
inline bool exact(const Context& c, Vec3 xi, Vec3 xj, double ci, double cj,
                  const std::int64_t s[3]) {
  const Vec3 d = rule::pair_vector(xi, xj, rule::image_offset(*c.cell, s[0], s[1], s[2]));
  const double reach = c.cut->empty() ? c.cutoff : ci + cj;
  return rule::within(rule::squared_length(d), reach, c.rule);
}

/// The pairs found, grouped by the point they belong to (the home point
/// for the self list, the query for the two-set list). The search runs in
/// parts, one a thread, each over consecutive groups (part p ends before
/// group part_end[p]) with records of its own: group k is
/// [start[k], start[k] + count[k]) of its part's records, and at[k] points
/// at its first record once the search is done (`seal`).
template <class Found>
struct Groups {
  std::vector<NeighbourVector<Found>> parts;
  std::vector<std::size_t> part_end;
  std::vector<std::int64_t> start;
  std::vector<std::uint32_t> count;
  std::vector<Found*> at;

  explicit Groups(std::size_t groups) {
    resize_large(start, groups);
    resize_large(count, groups);
  }
  void seal() {
    resize_large(at, start.size());
    std::size_t k = 0;
    for (std::size_t p = 0; p < parts.size(); ++p)
      for (; k < part_end[p]; ++k) at[k] = parts[p].data() + start[k];
  }
};

template <class Found>
void push(NeighbourVector<Found>& found, std::uint32_t j, const std::int64_t s[3]) {
  found.push_back(Found::make(j, s));
}

/// Whether every shift of a pair between `home` and `other` found through
/// the bins of `wraps` fits the packed record: |S| <= |bin shift| + the
/// spread of the wrap counts.
bool packed_shifts_fit(const std::array<std::vector<std::int64_t>, 3>& bin_shifts,
                       const PointSet& home, const PointSet& other) {
  for (int k = 0; k < 3; ++k) {
    std::int64_t most = 0;
    for (std::int64_t v : bin_shifts[k]) most = std::max(most, v < 0 ? -v : v);
    const std::int64_t spread = std::max<std::int64_t>(std::int64_t{home.n_hi[k]} - other.n_lo[k],
                                                       std::int64_t{other.n_hi[k]} - home.n_lo[k]);
    if (most + spread > PackedFound::kLimit) return false;
  }
  return true;
}

/// The runs of the bins at offsets [-r, r] from bin bc (per axis) that
/// `wraps` resolves, in the order for_each_bin_around visits their bins.
void runs_around(const Grid& g, const Wraps& wraps, const Binned& b, const NeighbourCell& cell,
                 const std::int64_t (&bc)[3], const std::int64_t (&r)[3], std::vector<Run>& runs) {
  runs.clear();
  for (std::int64_t o0 = -r[0]; o0 <= r[0]; ++o0) {
    std::int64_t n0, s0;
    if (!wraps.resolve(0, bc[0] + o0, n0, s0)) continue;
    for (std::int64_t o1 = -r[1]; o1 <= r[1]; ++o1) {
      std::int64_t n1, s1;
      if (!wraps.resolve(1, bc[1] + o1, n1, s1)) continue;
      const std::int64_t base = (n0 * g.nb[1] + n1) * g.nb[2];
      std::int64_t first = -1, last = -1, s2 = 0;
      const auto flush = [&] {
        if (first < 0) return;
        const std::int64_t lo = b.start[static_cast<std::size_t>(base + first)];
        const std::int64_t hi = b.start[static_cast<std::size_t>(base + last + 1)];
        if (lo < hi)
          runs.push_back({static_cast<std::uint32_t>(lo),
                          static_cast<std::uint32_t>(hi),
                          {static_cast<std::int32_t>(s0), static_cast<std::int32_t>(s1),
                           static_cast<std::int32_t>(s2)},
                          rule::image_offset(cell, s0, s1, s2)});
        first = -1;
      };
      for (std::int64_t o2 = -r[2]; o2 <= r[2]; ++o2) {
        std::int64_t n2, t2;
        if (!wraps.resolve(2, bc[2] + o2, n2, t2)) {
          flush();
          continue;
        }
        if (first >= 0 && t2 == s2 && n2 == last + 1) {
          last = n2;
          continue;
        }
        flush();
        first = last = n2;
        s2 = t2;
      }
      flush();
    }
  }
}

/// Calls f(nb, sb) for each bin at the offsets lo to hi (per axis) from bin
/// bc that `wraps` resolves: nb the bin's index, sb the image shift of its
/// points. The two-set search's stencil walk (the self search walks the
/// same bins as runs, runs_around).
template <class F>
void for_each_bin_around(const Grid& g, const Wraps& wraps, const std::int64_t (&bc)[3],
                         const std::int64_t (&lo)[3], const std::int64_t (&hi)[3], F&& f) {
  for (std::int64_t o0 = lo[0]; o0 <= hi[0]; ++o0)
    for (std::int64_t o1 = lo[1]; o1 <= hi[1]; ++o1)
      for (std::int64_t o2 = lo[2]; o2 <= hi[2]; ++o2) {
        const std::int64_t o[3] = {o0, o1, o2};
        std::int64_t nbin[3], sb[3];
        bool inside = true;
        for (int k = 0; k < 3 && inside; ++k)
          inside = wraps.resolve(k, bc[k] + o[k], nbin[k], sb[k]);
        if (!inside) continue;
        f((nbin[0] * g.nb[1] + nbin[1]) * g.nb[2] + nbin[2], sb);
      }
}

/// The self search's bins: on an axis that is not periodic, no offset
/// beyond nb - 1 lands in a bin.
Wraps self_wraps(const Grid& g) {
  std::array<std::int64_t, 3> r{};
  for (int k = 0; k < 3; ++k) r[k] = g.periodic[k] ? g.reach[k] : std::min(g.reach[k], g.nb[k] - 1);
  return Wraps(g, r);
}

/// The self search over the home bins [bin_lo, bin_hi): the groups of their
/// points, with records in `found`. Every point's pairs are found from the
/// point itself in bin order, so that each point's pairs come out together:
/// the output is then in index order by moving whole groups, not single
/// pairs. At 10^6 points a half search (each pair found once, from either
/// end) spent a third of the list scattering its pairs into index order
/// (perf); a full search visits twice the candidates but rejects half of
/// them by index after the distance test.
template <class Found>
void find_self_part(const Context& c, const Grid& g, const Wraps& wraps, const Binned& b, bool full,
                    bool self_interaction, std::int64_t bin_lo, std::int64_t bin_hi,
                    Groups<Found>& out, NeighbourVector<Found>& found) {
  const std::int64_t r[3] = {wraps.base[0], wraps.base[1], wraps.base[2]};
  const bool one = c.cut->empty();
  std::vector<Run> runs;
  std::vector<std::uint64_t> pick;  // run << 32 | slot
  const double one_reach = c.cutoff + g.margin;
  // Within `inner` of each other (cutoff less the margin), the prefilter's
  // distance decides for the exact rule: the margin bounds how far the two
  // differ, as it does for the prefilter's outer reach. At 10^6 points the
  // exact test of every candidate kept was a seventh of the list.
  const double one_inner = std::max(0.0, c.cutoff - g.margin);
  const int any_id = full ? 1 : 0;
#if BROADPHASE_NEIGHBOURS_AVX512
  const bool vector = neighbours_detail::vector_search();
  // Every point inside the cell (wrap counts all zero, as most codes keep
  // them) and packed records: the vector pass writes the records itself.
  const PointSet& ps = *c.home;
  const bool records = vector && std::is_same_v<Found, PackedFound> &&
                       ps.n_lo == std::array<std::int32_t, 3>{} && ps.n_hi == ps.n_lo;
#endif
  for (std::int64_t home = bin_lo; home < bin_hi; ++home) {
    const std::int64_t hs = b.start[static_cast<std::size_t>(home)];
    const std::int64_t he = b.start[static_cast<std::size_t>(home) + 1];
    if (hs == he) continue;
    const std::int64_t bc[3] = {home / (g.nb[1] * g.nb[2]), (home / g.nb[2]) % g.nb[1],
                                home % g.nb[2]};
    runs_around(g, wraps, b, *c.cell, bc, r, runs);
    std::size_t m = 0;
    for (const Run& run : runs) m += run.hi - run.lo;
    if (pick.size() < m + 8) pick.resize(2 * (m + 8));  // the vector pick writes 8 past
    for (std::int64_t p = hs; p < he; ++p) {
      const auto pi = static_cast<std::size_t>(p);
      const double cp = one ? 0.0 : b.wc[pi];
      const std::uint32_t ip = b.id[pi];
      out.start[pi] = static_cast<std::int64_t>(found.size());
      if (self_interaction) {
        const std::int64_t zero[3] = {0, 0, 0};
        if (exact(c, b.x[pi], b.x[pi], cp, cp, zero)) push(found, ip, zero);
      }
      const double px = b.wx[pi], py = b.wy[pi], pz = b.wz[pi];
      // The candidates within reach (and, in a half list, not found from
      // their own end), read in place run by run and compacted without a
      // branch: the branch on each distance test was a tenth of the list,
      // mispredicted about one time in six (perf, 10^4 points); copying
      // the candidates of each home bin into columns first cost more than
      // the runs' loops (perf, 10^4 and 10^6 points).
      // The point is moved by -off rather than each candidate by +off: the
      // same rounding bound (a few ulps of the magnitudes the margin is
      // taken of), three additions fewer a candidate.
      std::size_t picked = 0;
#if BROADPHASE_NEIGHBOURS_AVX512
      if (records) {
        if constexpr (std::is_same_v<Found, PackedFound>) {
          const std::size_t size = found.size();
          found.resize(size + m + 8);
          const std::size_t written = records_avx512(
              b, runs, px, py, pz,
              VectorReaches{one, one_reach * one_reach, one_inner * one_inner, cp, g.margin}, ip,
              full, found.data() + size, pick.data(), picked);
          found.resize(size + written);
        }
      } else if (vector) {
        picked = pick_avx512(
            b, runs, px, py, pz,
            VectorReaches{one, one_reach * one_reach, one_inner * one_inner, cp, g.margin}, ip,
            full, pick.data());
      } else
#endif
        for (std::size_t k = 0; k < runs.size(); ++k) {
          const Run& run = runs[k];
          const double qx = px - run.off.x, qy = py - run.off.y, qz = pz - run.off.z;
          for (std::uint32_t q = run.lo; q < run.hi; ++q) {
            const double dx = b.wx[q] - qx, dy = b.wy[q] - qy, dz = b.wz[q] - qz;
            const double d2 = dx * dx + dy * dy + dz * dz;
            const double reach = one ? one_reach : (cp + b.wc[q]) + g.margin;
            pick[picked] = std::uint64_t{k} << 32 | q;
            picked += static_cast<std::size_t>(static_cast<int>(d2 <= reach * reach) &
                                               (any_id | static_cast<int>(b.id[q] >= ip)));
          }
        }
      for (std::size_t e = 0; e < picked; ++e) {
        const std::size_t qi = static_cast<std::uint32_t>(pick[e]);
        const Run& run = runs[pick[e] >> 32];
        const std::uint32_t iq = b.id[qi];
        std::int64_t s[3];
        for (int a = 0; a < 3; ++a) s[a] = std::int64_t{run.sb[a]} + b.n[pi][a] - b.n[qi][a];
        const bool zero = s[0] == 0 && s[1] == 0 && s[2] == 0;
        if (iq == ip && zero) continue;  // the point itself
        // Canonical: the smaller index first; a point with its own
        // image under the kept one of S and -S.
        const bool canonical = ip < iq || (ip == iq && rule::kept_self_shift(s[0], s[1], s[2]));
        if (!full && !canonical) continue;
        const double cq = one ? 0.0 : b.wc[qi];
        const double dx = b.wx[qi] - (px - run.off.x), dy = b.wy[qi] - (py - run.off.y),
                     dz = b.wz[qi] - (pz - run.off.z);
        const double inner = one ? one_inner : std::max(0.0, (cp + cq) - g.margin);
        bool pair = dx * dx + dy * dy + dz * dz < inner * inner;
        if (!pair) {
          const std::int64_t mirror[3] = {-s[0], -s[1], -s[2]};
          pair = canonical ? exact(c, b.x[pi], b.x[qi], cp, cq, s)
                           : exact(c, b.x[qi], b.x[pi], cq, cp, mirror);
        }
        if (pair) push(found, iq, s);
      }
      out.count[pi] =
          static_cast<std::uint32_t>(static_cast<std::int64_t>(found.size()) - out.start[pi]);
    }
  }
}

/// The self search in parts of about equal numbers of points, each a run
/// of whole bins.
template <class Found>
Groups<Found> find_self(const Context& c, const Grid& g, const Wraps& wraps, const Binned& b,
                        bool full, bool self_interaction, unsigned threads) {
  const std::size_t n = b.id.size();
  Groups<Found> out(n);
  const unsigned parts = parts_for(n, threads);
  std::vector<std::int64_t> cut(parts + 1, 0);
  cut[parts] = g.bins();
  for (unsigned p = 1; p < parts; ++p) {
    const auto want = static_cast<std::int64_t>(n * p / parts);
    const auto it = std::upper_bound(b.start.begin(), b.start.end(), want);
    cut[p] = std::max(cut[p - 1], static_cast<std::int64_t>(it - b.start.begin()) - 1);
  }
  out.parts.resize(parts);
  out.part_end.resize(parts);
  for (unsigned p = 0; p < parts; ++p)
    out.part_end[p] = static_cast<std::size_t>(b.start[static_cast<std::size_t>(cut[p + 1])]);
  run_parts(parts, [&](unsigned p) {
    const std::size_t first = p == 0 ? 0 : out.part_end[p - 1];
    reserve_large(out.parts[p], (out.part_end[p] - first) * 8);
    find_self_part(c, g, wraps, b, full, self_interaction, cut[p], cut[p + 1], out, out.parts[p]);
  });
  out.seal();
  return out;
}

/// The pairs (q, p, S) of queries against binned points, query by query.
/// A query walks bins in [0, nb) on an axis that is not periodic.
Wraps between_wraps(const Grid& g) {
  return Wraps(g, {g.periodic[0] ? g.reach[0] : 0, g.periodic[1] ? g.reach[1] : 0,
                   g.periodic[2] ? g.reach[2] : 0});
}

template <class Found>
void find_between_part(const Context& c, const Grid& g, const Wraps& wraps, const Binned& b,
                       std::size_t q_lo, std::size_t q_hi, Groups<Found>& out,
                       NeighbourVector<Found>& found) {
  const PointSet& qs = *c.home;
  for (std::size_t qi = q_lo; qi < q_hi; ++qi) {
    out.start[qi] = static_cast<std::int64_t>(found.size());
    std::int64_t bc[3];
    for (int k = 0; k < 3; ++k) bc[k] = g.coordinate(k, qs.s[qi][k]);
    const Vec3 qo = rule::image_offset(*c.cell, qs.n[qi][0], qs.n[qi][1], qs.n[qi][2]);
    const Vec3 wq{qs.x[qi].x - qo.x, qs.x[qi].y - qo.y, qs.x[qi].z - qo.z};
    const double r = c.cutoff + g.margin;
    // The offsets to walk: all within the reach on a periodic axis, those
    // that land in [0, nb) on the others.
    std::int64_t lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = g.periodic[k] ? -g.reach[k] : std::max(-g.reach[k], -bc[k]);
      hi[k] = g.periodic[k] ? g.reach[k] : std::min(g.reach[k], g.nb[k] - 1 - bc[k]);
    }
    for_each_bin_around(g, wraps, bc, lo, hi, [&](std::int64_t nb, const std::int64_t(&sb)[3]) {
      const std::int64_t ns = b.start[static_cast<std::size_t>(nb)];
      const std::int64_t ne = b.start[static_cast<std::size_t>(nb) + 1];
      if (ns == ne) return;
      const Vec3 off = rule::image_offset(*c.cell, sb[0], sb[1], sb[2]);
      const double px = wq.x - off.x, py = wq.y - off.y, pz = wq.z - off.z;
      for (std::int64_t p = ns; p < ne; ++p) {
        const auto pw = static_cast<std::size_t>(p);
        const double dx = b.wx[pw] - px, dy = b.wy[pw] - py, dz = b.wz[pw] - pz;
        if (dx * dx + dy * dy + dz * dz > r * r) continue;
        const auto pj = static_cast<std::size_t>(p);
        std::int64_t s[3];
        for (int k = 0; k < 3; ++k) s[k] = sb[k] + qs.n[qi][k] - b.n[pj][k];
        if (exact(c, qs.x[qi], b.x[pj], 0.0, 0.0, s)) push(found, b.id[pj], s);
      }
    });
    out.count[qi] =
        static_cast<std::uint32_t>(static_cast<std::int64_t>(found.size()) - out.start[qi]);
  }
}

/// The two-set search in parts of equal numbers of queries.
template <class Found>
Groups<Found> find_between(const Context& c, const Grid& g, const Wraps& wraps, const Binned& b,
                           unsigned threads) {
  const std::size_t n = c.home->x.size();
  Groups<Found> out(n);
  const unsigned parts = parts_for(n, threads);
  out.parts.resize(parts);
  out.part_end.resize(parts);
  for (unsigned p = 0; p < parts; ++p) out.part_end[p] = n * (p + 1) / parts;
  run_parts(parts, [&](unsigned p) {
    find_between_part(c, g, wraps, b, p == 0 ? 0 : out.part_end[p - 1], out.part_end[p], out,
                      out.parts[p]);
  });
  out.seal();
  return out;
}

/// Groups of at most this many records are placed by rank (assemble).
constexpr std::size_t kRankedGroup = 32;

/// The groups in index order (`group_of[i]` is point i's group), each
/// sorted by second, then shift, with the quantities asked for. D is that
/// of the canonical orientation (negated for a mirror) unless `between`.
template <class Found>
NeighbourList assemble(const Context& c, Groups<Found>& gr,
                       const std::vector<std::uint32_t>* group_of, const NeighbourOptions& opt,
                       bool between, NeighbourVector<neighbours_detail::Candidate>* candidates) {
  const std::size_t n = gr.start.size();
  const auto group = [&](std::size_t i) -> std::size_t { return group_of ? (*group_of)[i] : i; };
  // Parts of equal numbers of points, each written by a thread where the
  // prefix sums of the group sizes place it.
  const unsigned parts = parts_for(n, opt.threads);
  const auto part_lo = [&](unsigned p) { return n * p / parts; };
  NeighbourVector<std::int64_t> offsets(n + 1);
  offsets[0] = 0;
  std::vector<std::int64_t> part_total(parts + 1, 0);
  run_parts(parts, [&](unsigned p) {
    std::int64_t sum = 0;
    for (std::size_t i = part_lo(p), hi = part_lo(p + 1); i < hi; ++i) {
      if (i + 16 < hi) __builtin_prefetch(&gr.count[group(i + 16)]);
      sum += gr.count[group(i)];
      offsets[i + 1] = sum;
    }
    part_total[p + 1] = sum;
  });
  for (unsigned p = 0; p < parts; ++p) part_total[p + 1] += part_total[p];
  const auto total = static_cast<std::size_t>(part_total[parts]);
  NeighbourList out;
  // Sized without being written, then each value written once by its part.
  if (candidates) {
    resize_large(*candidates, total);
  } else {
    resize_large(out.first, total);
    resize_large(out.second, total);
    if (opt.shifts) resize_large(out.shifts, 3 * total);
    if (opt.distances) resize_large(out.distances, total);
    if (opt.vectors) resize_large(out.vectors, 3 * total);
  }
  const auto less = [](const Found& a, const Found& b) { return a < b; };
  // Point i's record e at output position at.
  const auto emit = [&](std::size_t i, const Found& e, std::size_t at) {
    if (candidates) {
      (*candidates)[at] = {e.j(),
                           {static_cast<std::int32_t>(e.s(0)), static_cast<std::int32_t>(e.s(1)),
                            static_cast<std::int32_t>(e.s(2))}};
      return;
    }
    out.first[at] = static_cast<std::int64_t>(i);
    out.second[at] = e.j();
    if (opt.shifts)
      for (int a = 0; a < 3; ++a) out.shifts[3 * at + a] = e.s(a);
    if (opt.distances || opt.vectors) {
      const auto j = static_cast<std::size_t>(e.j());
      Vec3 d;
      const bool canonical = between || i < j ||
                             (i == j && (rule::kept_self_shift(e.s(0), e.s(1), e.s(2)) ||
                                         (e.s(0) == 0 && e.s(1) == 0 && e.s(2) == 0)));
      if (canonical) {
        d = rule::pair_vector(c.home->x[i], c.other->x[j],
                              rule::image_offset(*c.cell, e.s(0), e.s(1), e.s(2)));
      } else {
        d = rule::pair_vector(c.home->x[j], c.other->x[i],
                              rule::image_offset(*c.cell, -e.s(0), -e.s(1), -e.s(2)));
        d = Vec3{-d.x, -d.y, -d.z};
      }
      if (opt.distances) out.distances[at] = std::sqrt(rule::squared_length(d));
      if (opt.vectors)
        for (int a = 0; a < 3; ++a) out.vectors[3 * at + a] = d[a];
    }
  };
  run_parts(parts, [&](unsigned p) {
    const std::size_t lo_i = part_lo(p), hi_i = part_lo(p + 1);
    for (std::size_t i = lo_i; i < hi_i; ++i) offsets[i + 1] += part_total[p];
    // Groups are read in index order from bin order: a cache and TLB miss
    // each, so the group 8 points ahead is fetched while this one is
    // written (and where it is and its size 16 ahead); at 10^6 points the
    // misses were two thirds of this function (perf).
    constexpr std::size_t kAhead = 8;
    auto e_out = static_cast<std::size_t>(part_total[p]);
    for (std::size_t i = lo_i; i < hi_i; ++i) {
      if (i + 2 * kAhead < hi_i) {
        __builtin_prefetch(&gr.at[group(i + 2 * kAhead)]);
        __builtin_prefetch(&gr.count[group(i + 2 * kAhead)]);
      }
      if (i + kAhead < hi_i) __builtin_prefetch(gr.at[group(i + kAhead)]);
      const std::size_t k = group(i);
      Found* lo = gr.at[k];
      const std::size_t size = gr.count[k];
      // A group goes out sorted. A small one (a point has a few
      // neighbours) places each record at its rank, the number of records
      // before it (records differ): comparisons without a branch, where
      // sorting in place mispredicted about one in two and took two fifths
      // of this function at 10^6 points (perf).
      if (size <= kRankedGroup) {
        for (std::size_t a = 0; a < size; ++a) {
          std::size_t rank = 0;
          for (std::size_t b = 0; b < size; ++b)
            rank += static_cast<std::size_t>(less(lo[b], lo[a]));
          emit(i, lo[a], e_out + rank);
        }
      } else {
        std::sort(lo, lo + size, less);
        for (std::size_t a = 0; a < size; ++a) emit(i, lo[a], e_out + a);
      }
      e_out += size;
    }
  });
  if (opt.offsets) out.offsets = std::move(offsets);
  return out;
}

NeighbourList self_list(const NeighbourPoints& points, const NeighbourCell& cell, double cutoff,
                        const Column* cutoffs, const NeighbourOptions& opt,
                        NeighbourVector<neighbours_detail::Candidate>* candidates = nullptr) {
  const Frame f = make_frame(cell);
  std::vector<double> cut;
  double reach = cutoff;
  if (cutoffs) {
    cut.resize(points.count);
    double most = 0;
    for (std::size_t i = 0; i < points.count; ++i) {
      cut[i] = cutoffs->at(i);
      check_cutoff(cut[i], "cutoffs[" + std::to_string(i) + "]");
      most = std::max(most, cut[i]);
    }
    reach = most + most;
  } else {
    check_cutoff(cutoff, "cutoff");
  }
  const PointSet pts = read_points(points, cell, f, "positions", opt.threads);
  const Grid g = make_grid(cell, f, pts, nullptr, reach);
  const Binned b = bin_points(g, cell, pts, cut, opt.threads);
  const Context c{&cell, &pts, &pts, &cut, cutoff, opt.rule};
  const Wraps wraps = self_wraps(g);
  // Point i's group is its slot.
  std::vector<std::uint32_t> group_of;
  resize_large(group_of, pts.x.size());
  for (std::size_t slot = 0; slot < b.id.size(); ++slot)
    group_of[b.id[slot]] = static_cast<std::uint32_t>(slot);
  const auto run = [&](auto record) {
    using Found = decltype(record);
    Groups<Found> gr =
        find_self<Found>(c, g, wraps, b, opt.full, opt.self_interaction, opt.threads);
    return assemble(c, gr, &group_of, opt, false, candidates);
  };
  return packed_shifts_fit(wraps.shift, pts, pts) ? run(PackedFound{}) : run(WideFound{});
}

}  // namespace

namespace neighbours_detail {

NeighbourVector<Candidate> candidate_list(const NeighbourPoints& points, const NeighbourCell& cell,
                                          double cutoff, const arrays::Column* cutoffs,
                                          const NeighbourOptions& options,
                                          NeighbourVector<std::int64_t>& offsets) {
  NeighbourOptions o = options;
  o.shifts = o.distances = o.vectors = false;
  o.offsets = true;
  NeighbourVector<Candidate> out;
  offsets = self_list(points, cell, cutoff, cutoffs, o, &out).offsets;
  return out;
}

}  // namespace neighbours_detail

NeighbourList neighbour_list(const NeighbourPoints& points, const NeighbourCell& cell,
                             double cutoff, const NeighbourOptions& options) {
  return self_list(points, cell, cutoff, nullptr, options);
}

NeighbourList neighbour_list(const NeighbourPoints& points, const NeighbourCell& cell,
                             Column cutoffs, const NeighbourOptions& options) {
  if (cutoffs.empty() && points.count > 0) refuse("cutoffs: no array given");
  return self_list(points, cell, 0.0, &cutoffs, options);
}

NeighbourList neighbour_list_between(const NeighbourPoints& queries, const NeighbourPoints& points,
                                     const NeighbourCell& cell, double cutoff,
                                     const NeighbourOptions& options) {
  check_cutoff(cutoff, "cutoff");
  const Frame f = make_frame(cell);
  const PointSet qs = read_points(queries, cell, f, "queries", options.threads);
  const PointSet ps = read_points(points, cell, f, "points", options.threads);
  const Grid g = make_grid(cell, f, ps, &qs, cutoff);
  const std::vector<double> none;
  const Binned b = bin_points(g, cell, ps, none, options.threads);
  const Context c{&cell, &qs, &ps, &none, cutoff, options.rule};
  const Wraps wraps = between_wraps(g);
  const auto run = [&](auto record) {
    using Found = decltype(record);
    Groups<Found> gr = find_between<Found>(c, g, wraps, b, options.threads);
    return assemble(c, gr, nullptr, options, true, nullptr);
  };
  return packed_shifts_fit(wraps.shift, qs, ps) ? run(PackedFound{}) : run(WideFound{});
}

}  // namespace broadphase
