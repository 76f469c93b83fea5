// The lean path's periodic pairs (include/broadphase/arrays/periodic.hpp):
// a multi-level grid whose cells wrap on the periodic axes, built over the
// caller's arrays for a call (one-shot) or for a tracker's candidates.
//
// Why it is exact. An object's level has cells at least `need` wide on
// every axis, where `need` is twice its largest half-extent (plus its
// allowance in a tracker) grown by 2^-20 of itself and of the largest
// magnitude in play: if i overlaps j moved by S·L in double, then on each axis the
// distance between them, the short way round on a periodic axis, is at
// most e_i + e_j up to rounding (2^-50 of those magnitudes), below the
// cell width of the coarser one's level by more than the rounding of the
// cell index itself (about n·2^-52 cells, n <= 2^20). So their cells, the
// coarser level's index computed for both centres, are equal or adjacent,
// modulo the cell count on a periodic axis. A periodic axis has
// n = floor(L / width) cells of width L / n, and a centre at exactly L
// falls in cell n, that is 0: no cell is clamped across the face. On
// the other axes cell indices are clamped to the level's cells, which
// keeps neighbours neighbours. Each unordered pair of objects is visited
// once (a cell pair once, the distinct neighbour cells of a cell listed
// once each when a periodic axis has fewer than three cells); for each,
// the shifts that the per-axis distances allow (with a slack of 2^-30 of
// the magnitudes) are evaluated by `overlaps()` on the contract's
// coordinates c_j + S_a·L_a, in increasing code.
#include <algorithm>
#include <bit>
#include <broadphase/arrays/periodic.hpp>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "calls.hpp"

namespace broadphase::arrays {
namespace {

// Relative and absolute slack of the per-axis shift filter: far above the
// rounding of the predicate (2^-50 of its magnitudes) and of the
// subtraction of L (2^-52 of L), and above the underflow of a square.
constexpr double kShiftSlack = 0x1p-30;
constexpr double kShiftFloor = 0x1p-500;
// Growth of a level's needed width over the objects' reach (see the top).
constexpr double kWidthSlack = 0x1p-20;
// The most cells on one axis of a level, so that the index's rounding stays
// far below the width's slack.
constexpr double kMaxAxisCells = 1 << 20;
// The tracker's allowance for an object that moved: this many calls of its
// speed since the last build, at most kAllowSizes times its size plus the
// median size (measured in Impl::build against one skin for all; the two
// numbers themselves were not tuned).
constexpr double kAllowCalls = 8;
constexpr double kAllowSizes = 4;
// Levels double in width; the last one has a single cell on every axis and
// takes every object too large for the others (any size, infinite reach).
constexpr int kLevels = 64;
// A level keeps at most this many cells per object of the call (at least
// kMinCells), wider cells otherwise, and the finest cells are at least as
// wide as the space of one object in eight cells: one-shot, 20 000
// half-boxes periodic xyz, 8.8 ms of CPU against 9.7 with two.
constexpr std::size_t kCellsPerObject = 8;
constexpr std::size_t kMinCells = 64;

char axis_name(int a) { return static_cast<char>('x' + a); }

std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void check_cell(const PeriodicCell& cell) {
  for (int a = 0; a < 3; ++a)
    if (cell.periodic[static_cast<std::size_t>(a)] &&
        !(std::isfinite(cell.length[a]) && cell.length[a] > 0))
      throw std::invalid_argument(std::string("periodic cell: the length of the periodic axis ") +
                                  axis_name(a) + " (" + number(cell.length[a]) +
                                  ") is not finite and positive");
}

// One axis of a level's cells.
struct AxisCells {
  double lo = 0, inv = 0;
  std::int64_t n = 1;
  bool wrap = false;

  std::int64_t of(double c) const {
    const double t = (c - lo) * inv;
    if (wrap) {
      // c in [0, L]: t in [0, n] up to rounding; n (c = L) is cell 0.
      const auto k = static_cast<std::int64_t>(std::min(t, static_cast<double>(n)));
      return k >= n ? k - n : k;
    }
    if (!(t >= 0)) return 0;
    return t < static_cast<double>(n) ? static_cast<std::int64_t>(t) : n - 1;
  }
  // The distinct cells next to k (k included), in increasing order.
  int around(std::int64_t k, std::int64_t out[3]) const {
    if (wrap) {
      if (n == 1) {
        out[0] = 0;
        return 1;
      }
      if (n == 2) {
        out[0] = 0, out[1] = 1;
        return 2;
      }
      out[0] = k == 0 ? n - 1 : k - 1, out[1] = k, out[2] = k + 1 == n ? 0 : k + 1;
      return 3;
    }
    int m = 0;
    if (k > 0) out[m++] = k - 1;
    out[m++] = k;
    if (k + 1 < n) out[m++] = k + 1;
    return m;
  }
};

struct Level {
  AxisCells axis[3];
  std::vector<std::uint32_t> start;  // cells + 1
  std::vector<std::uint32_t> items;  // object ids by cell

  std::size_t cells() const { return static_cast<std::size_t>(axis[0].n * axis[1].n * axis[2].n); }
  std::size_t index(std::int64_t kx, std::int64_t ky, std::int64_t kz) const {
    return static_cast<std::size_t>((kz * axis[1].n + ky) * axis[0].n + kx);
  }
  // Calls visit(j) for every object in the cells next to centre c.
  template <class Visit>
  void around(const Vec3& c, Visit&& visit) const {
    std::int64_t kx[3], ky[3], kz[3];
    const int nx = axis[0].around(axis[0].of(c.x), kx);
    const int ny = axis[1].around(axis[1].of(c.y), ky);
    const int nz = axis[2].around(axis[2].of(c.z), kz);
    for (int z = 0; z < nz; ++z)
      for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) {
          const std::size_t b = index(kx[x], ky[y], kz[z]);
          for (std::uint32_t q = start[b]; q < start[b + 1]; ++q) visit(items[q]);
        }
  }
};

// The shapes of a call, read once from the caller's columns.
std::vector<Shape> read_all(const Objects& o) {
  std::vector<Shape> s(o.count);
  for (std::size_t i = 0; i < o.count; ++i)
    s[i] = detail::read_shape(o, static_cast<std::uint32_t>(i));
  return s;
}

double largest_half(const Shape& s) { return std::max({s.half.x, s.half.y, s.half.z}); }

// The multi-level wrapping grid over `shapes`, each object i grown by
// `grow[i]` on every side (the tracker's allowances; none when null).
// pairs() calls visit(p, q) once for every unordered pair of objects that
// may overlap under some shift (p != q, in no particular order of the two).
class WrapGrid {
 public:
  WrapGrid(const std::vector<Shape>& shapes, const PeriodicCell& cell,
           const std::vector<double>* grow) {
    const std::size_t n = shapes.size();
    if (n < 2) return;
    double scale = 0;
    for (int a = 0; a < 3; ++a)
      if (cell.periodic[static_cast<std::size_t>(a)]) scale = std::max(scale, cell.length[a]);
    for (const Shape& s : shapes)
      scale =
          std::max({scale, std::fabs(s.center.x), std::fabs(s.center.y), std::fabs(s.center.z)});
    std::vector<double> need(n);
    double finest = HUGE_VAL;
    for (std::size_t i = 0; i < n; ++i) {
      const double reach = 2 * (largest_half(shapes[i]) + (grow != nullptr ? (*grow)[i] : 0));
      need[i] = reach + kWidthSlack * (reach + scale) + kShiftFloor;
      finest = std::min(finest, need[i]);
    }
    // Cells narrower than the space per object only add levels for every
    // object to probe: the smallest of 20 000 half-boxes made 14 levels and
    // the one-shot call 48 ms of CPU for 230 exact tests; with this floor,
    // one level and 9.7 ms.
    double volume = 1;
    for (int a = 0; a < 3; ++a) {
      double lo = HUGE_VAL, hi = -HUGE_VAL;
      for (const Shape& s : shapes) lo = std::min(lo, s.center[a]), hi = std::max(hi, s.center[a]);
      volume *=
          cell.periodic[static_cast<std::size_t>(a)] ? cell.length[a] : std::max(hi - lo, finest);
    }
    const double spaced = std::cbrt(volume / static_cast<double>(kCellsPerObject * n));
    if (std::isfinite(spaced)) finest = std::max(finest, spaced);
    level_of_.resize(n);
    std::vector<std::size_t> per_level(kLevels, 0);
    for (std::size_t i = 0; i < n; ++i) {
      int l = kLevels - 1;
      const double ratio = need[i] / finest;
      if (std::isfinite(ratio)) {
        int e = 0;
        std::frexp(ratio, &e);  // ratio < 2^e
        l = std::clamp(e - 1, 0, kLevels - 1);
        while (l < kLevels - 1 && std::ldexp(finest, l) < need[i]) ++l;
      }
      level_of_[i] = static_cast<std::uint8_t>(l);
      ++per_level[static_cast<std::size_t>(l)];
    }
    // Each used level's cells, then the objects counting-sorted into them.
    for (int l = 0; l < kLevels; ++l) {
      if (per_level[static_cast<std::size_t>(l)] == 0) continue;
      Level& lv = levels_.emplace_back();
      level_index_[static_cast<std::size_t>(l)] = static_cast<int>(levels_.size() - 1);
      shape_level(lv, l == kLevels - 1 ? HUGE_VAL : std::ldexp(finest, l), n, shapes, cell);
    }
    std::vector<std::uint32_t> cell_of(n);
    for (std::size_t i = 0; i < n; ++i) {
      Level& lv = level(i);
      const Vec3& c = shapes[i].center;
      cell_of[i] = static_cast<std::uint32_t>(
          lv.index(lv.axis[0].of(c.x), lv.axis[1].of(c.y), lv.axis[2].of(c.z)));
      ++lv.start[cell_of[i] + 1];
    }
    for (Level& lv : levels_) {
      for (std::size_t b = 1; b < lv.start.size(); ++b) lv.start[b] += lv.start[b - 1];
      lv.items.resize(lv.start.back());
    }
    std::vector<std::vector<std::uint32_t>> fill(levels_.size());
    for (std::size_t k = 0; k < levels_.size(); ++k)
      fill[k].assign(levels_[k].start.begin(), levels_[k].start.end() - 1);
    for (std::size_t i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(level_index_[level_of_[i]]);
      levels_[k].items[fill[k][cell_of[i]]++] = static_cast<std::uint32_t>(i);
    }
  }

  template <class Visit>
  void pairs(const std::vector<Shape>& shapes, Visit&& visit) const {
    for (std::size_t k = 0; k < levels_.size(); ++k) {
      const Level& lv = levels_[k];
      // Within the level: each cell with itself and with every distinct
      // neighbour of a higher index.
      for (std::int64_t kz = 0; kz < lv.axis[2].n; ++kz)
        for (std::int64_t ky = 0; ky < lv.axis[1].n; ++ky)
          for (std::int64_t kx = 0; kx < lv.axis[0].n; ++kx) {
            const std::size_t a = lv.index(kx, ky, kz);
            const std::uint32_t a0 = lv.start[a], a1 = lv.start[a + 1];
            if (a0 == a1) continue;
            for (std::uint32_t p = a0; p < a1; ++p)
              for (std::uint32_t q = p + 1; q < a1; ++q) visit(lv.items[p], lv.items[q]);
            std::int64_t nx[3], ny[3], nz[3];
            const int cx = lv.axis[0].around(kx, nx);
            const int cy = lv.axis[1].around(ky, ny);
            const int cz = lv.axis[2].around(kz, nz);
            for (int z = 0; z < cz; ++z)
              for (int y = 0; y < cy; ++y)
                for (int x = 0; x < cx; ++x) {
                  const std::size_t b = lv.index(nx[x], ny[y], nz[z]);
                  if (b <= a) continue;
                  for (std::uint32_t p = a0; p < a1; ++p)
                    for (std::uint32_t q = lv.start[b]; q < lv.start[b + 1]; ++q)
                      visit(lv.items[p], lv.items[q]);
                }
          }
      // With every coarser level: each object of this one probes there.
      for (std::size_t m = k + 1; m < levels_.size(); ++m)
        for (std::uint32_t p : lv.items)
          levels_[m].around(shapes[p].center, [&](std::uint32_t q) { visit(p, q); });
    }
  }

 private:
  Level& level(std::size_t i) {
    return levels_[static_cast<std::size_t>(level_index_[level_of_[i]])];
  }

  static void shape_level(Level& lv, double width, std::size_t objects,
                          const std::vector<Shape>& shapes, const PeriodicCell& cell) {
    // The objects' range on the axes that do not wrap.
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (const Shape& s : shapes)
      for (int a = 0; a < 3; ++a)
        lo[a] = std::min(lo[a], s.center[a]), hi[a] = std::max(hi[a], s.center[a]);
    // The cap counts every object of the call, not the level's own: a
    // level of a few wide objects with few wide cells put them in the
    // probes of every finer object (24 movers with long allowances met all
    // 20 000 objects at each tracker's rebuild: 1.2 million visits, 40 ms
    // of CPU; with the whole count 18.5 ms). The finest cells' floor
    // (kCellsPerObject) already bounds the cells of every level to about
    // 8/7 of this in all.
    const std::size_t cap = std::max(kMinCells, kCellsPerObject * objects);
    for (;;) {
      double cells = 1;
      for (int a = 0; a < 3; ++a) {
        AxisCells& ax = lv.axis[a];
        ax.wrap = cell.periodic[static_cast<std::size_t>(a)];
        double k = 1;
        if (ax.wrap) {
          const double L = cell.length[a];
          k = std::clamp(std::floor(L / width), 1.0, kMaxAxisCells);
          // L / k may round below the width: one cell fewer then.
          while (k > 1 && L / k < width) k -= 1;
          ax.lo = 0;
          ax.inv = k / L;
        } else {
          const double span = hi[a] - lo[a];
          k = std::clamp(std::floor(span / width) + 1, 1.0, kMaxAxisCells);
          if (!std::isfinite(width)) k = 1;
          ax.lo = lo[a];
          ax.inv = std::isfinite(width) ? 1 / width : 0;
        }
        ax.n = static_cast<std::int64_t>(k);
        cells *= k;
      }
      if (cells <= static_cast<double>(cap) || !std::isfinite(width)) break;
      width *= 2;
    }
    lv.start.assign(lv.cells() + 1, 0);
  }

  std::vector<std::uint8_t> level_of_;
  int level_index_[kLevels] = {};
  std::vector<Level> levels_;
};

// The shifts under which i (as it lies) may overlap j moved by S·L: per
// axis, the S whose distance the per-axis extents allow, with a slack far
// above the predicate's rounding (conservative), then each combination
// tested exactly as the contract writes it. Calls hit(code) in increasing
// code for every shift under which they overlap; returns the tests made.
template <class Hit>
std::uint32_t test_shifts(const Shape& si, const Shape& sj, const PeriodicCell& cell, Hit&& hit) {
  int shifts[3][3];
  int count[3];
  for (int a = 0; a < 3; ++a) {
    const double d = si.center[a] - sj.center[a];
    const double e = si.half[a] + sj.half[a];
    count[a] = 0;
    if (!cell.periodic[static_cast<std::size_t>(a)]) {
      if (std::fabs(d) <= e + kShiftSlack * (e + std::fabs(d)) + kShiftFloor)
        shifts[a][count[a]++] = 0;
    } else {
      const double L = cell.length[a];
      const double room = e + kShiftSlack * (e + std::fabs(d) + L) + kShiftFloor;
      if (std::fabs(d + L) <= room) shifts[a][count[a]++] = -1;
      if (std::fabs(d) <= room) shifts[a][count[a]++] = 0;
      if (std::fabs(d - L) <= room) shifts[a][count[a]++] = 1;
    }
    if (count[a] == 0) return 0;
  }
  std::uint32_t tests = 0;
  Shape moved = sj;
  for (int z = 0; z < count[2]; ++z) {
    moved.center.z = shifts[2][z] == 0 ? sj.center.z : sj.center.z + shifts[2][z] * cell.length.z;
    for (int y = 0; y < count[1]; ++y) {
      moved.center.y = shifts[1][y] == 0 ? sj.center.y : sj.center.y + shifts[1][y] * cell.length.y;
      for (int x = 0; x < count[0]; ++x) {
        moved.center.x =
            shifts[0][x] == 0 ? sj.center.x : sj.center.x + shifts[0][x] * cell.length.x;
        ++tests;
        if (overlaps(si, moved))
          hit((shifts[0][x] + 1) + 3 * (shifts[1][y] + 1) + 9 * (shifts[2][z] + 1));
      }
    }
  }
  return tests;
}

// Chunks of periodic pairs handed to the sink, filtered by the caller's
// columns at the hand-over (as the other lean calls do), sorted at the
// end when asked.
class ShiftedEmitter {
 public:
  ShiftedEmitter(const ShiftedPairSink& sink, bool sorted, ArrayCallStats& stats,
                 detail::PairFilterColumns filters)
      : sink_(sink), sorted_(sorted), stats_(stats), filters_(filters) {}

  // False once the sink asked to stop.
  bool add(std::uint32_t i, std::uint32_t j, int code) {
    if (filters_.active() && !filters_.pass({i, j})) return true;
    chunk_.push_back({i, j, Shift::of_code(code)});
    if (!sorted_ && chunk_.size() >= detail::kChunkItems) return flush();
    return true;
  }
  bool finish() {
    if (sorted_)
      std::sort(chunk_.begin(), chunk_.end(), [](const ShiftedPair& p, const ShiftedPair& q) {
        if (p.i != q.i) return p.i < q.i;
        if (p.j != q.j) return p.j < q.j;
        return p.shift.code() < q.shift.code();
      });
    return flush();
  }

 private:
  bool flush() {
    stats_.pairs += chunk_.size();
    if (!chunk_.empty() && !sink_(chunk_)) stats_.stopped = true;
    chunk_.clear();
    return !stats_.stopped;
  }
  const ShiftedPairSink& sink_;
  bool sorted_;
  ArrayCallStats& stats_;
  detail::PairFilterColumns filters_;
  std::vector<ShiftedPair> chunk_;
};

ShiftedPairSink append_shifted(std::vector<ShiftedPair>& out) {
  return [&out](std::span<const ShiftedPair> c) {
    out.insert(out.end(), c.begin(), c.end());
    return true;
  };
}

double median_largest_half(const std::vector<Shape>& shapes) {
  if (shapes.empty()) return 0;
  std::vector<double> h(shapes.size());
  for (std::size_t i = 0; i < shapes.size(); ++i) h[i] = largest_half(shapes[i]);
  auto mid = h.begin() + static_cast<std::ptrdiff_t>(h.size() / 2);
  std::nth_element(h.begin(), mid, h.end());
  return *mid;
}

}  // namespace

namespace {

// Object i against the cell (check_periodic).
void check_in_cell(const Objects& objects, const PeriodicCell& cell, std::size_t i,
                   const char* what) {
  const Shape s = detail::read_shape(objects, static_cast<std::uint32_t>(i));
  for (int a = 0; a < 3; ++a) {
    if (!cell.periodic[static_cast<std::size_t>(a)]) continue;
    const double L = cell.length[a];
    if (s.center[a] >= 0 && s.center[a] <= L && s.half[a] < L / 2) continue;
    const std::string name = std::string(what) + "[" + std::to_string(i) + "]: ";
    if (!(s.center[a] >= 0 && s.center[a] <= L))
      throw InvalidObjects(name + axis_name(a) + " (" + number(s.center[a]) +
                               ") is outside [0, L] = [0, " + number(L) +
                               "] on the periodic axis " + axis_name(a),
                           i);
    throw InvalidObjects(
        name + (s.is_sphere() ? std::string("radius") : std::string("half_") + axis_name(a)) +
            " (" + number(s.half[a]) + ") is not below L/2 = " + number(L / 2) +
            " on the periodic axis " + axis_name(a),
        i);
  }
}

}  // namespace

void check_periodic(const Objects& objects, const PeriodicCell& cell, const char* what) {
  check_cell(cell);
  check_objects(objects, what);
  for (std::size_t i = 0; i < objects.count; ++i) check_in_cell(objects, cell, i, what);
}

ArrayCallStats find_pairs(const Objects& objects, const PeriodicCell& cell,
                          const ShiftedPairSink& sink, const ArrayOptions& options) {
  options.check();
  check_periodic(objects, cell);
  detail::check_filter_columns(objects, "objects");
  ArrayCallStats stats;
  const std::vector<Shape> shapes = read_all(objects);
  const WrapGrid grid(shapes, cell, nullptr);
  // Filters are applied before the test here (the emitter gets none).
  ShiftedEmitter emit(sink, options.sorted, stats, {});
  const detail::PairFilterColumns filters = detail::PairFilterColumns::of(objects);
  bool going = true;
  // Stopping early: the walk goes on, but nothing more is tested.
  grid.pairs(shapes, [&](std::uint32_t p, std::uint32_t q) {
    if (!going) return;
    const std::uint32_t i = std::min(p, q), j = std::max(p, q);
    if (filters.active() && !filters.pass({i, j})) return;
    stats.tests += test_shifts(shapes[i], shapes[j], cell, [&](int code) {
      if (going) going = emit.add(i, j, code);
    });
  });
  if (going) emit.finish();
  return stats;
}

ArrayCallStats find_pairs(const Objects& objects, const PeriodicCell& cell,
                          std::vector<ShiftedPair>& out, const ArrayOptions& options) {
  return find_pairs(objects, cell, append_shifted(out), options);
}

// ---------------------------------------------------------------------------
// The tracker.

struct PeriodicPairTracker::Impl {
  PeriodicCell cell;
  ArrayOptions options;
  bool built = false;
  std::size_t count = 0;
  double skin = 0;         // absolute, of the last build
  double skin_factor = 0;  // relative to the median largest half-extent
  std::size_t calls_since_build = 0;
  std::vector<double> home;           // 3 per object: its centre at the build
  std::vector<double> reach;          // its largest half-extent at the build
  std::vector<double> allow;          // how far it may move from home (each axis)
  std::vector<IndexPair> candidates;  // sorted by (i, j)
  std::vector<std::uint32_t> hits;    // per candidate: bit `code` set when it overlapped
  std::vector<std::uint8_t> changed;  // scratch

  // How far object s has moved from its home on axis a, the short way
  // round on a periodic axis.
  double moved(const Shape& s, std::size_t i, int a) const {
    double d = std::fabs(s.center[a] - home[3 * i + static_cast<std::size_t>(a)]);
    if (cell.periodic[static_cast<std::size_t>(a)]) d = std::min(d, cell.length[a] - d);
    return d;
  }
  bool left(const Shape& s, std::size_t i) const {
    if (largest_half(s) > reach[i]) return true;
    for (int a = 0; a < 3; ++a)
      if (!(moved(s, i, a) <= allow[i])) return true;
    return false;
  }

  void build(const std::vector<Shape>& shapes) {
    const std::size_t n = shapes.size();
    const double typical = median_largest_half(shapes);
    skin = skin_factor * typical;
    // Each object may move half the skin, or, where it moved since the last
    // build, kAllowCalls calls of its speed since then (at most
    // kAllowSizes times its size and the median size): in a world where a
    // fifth of the objects move, the quiet ones keep tight candidates and
    // the movers rebuild less often. 20 000 half-boxes periodic xyz, 100
    // calls: one skin for all, doubled up to 4 while rebuilds came within
    // two calls, rebuilt 36 times (mean call 7.6 ms of CPU); with these
    // allowances 14 times (5.7 ms).
    std::vector<double> next(n, skin / 2);
    if (built && count == n && calls_since_build > 0)
      for (std::size_t i = 0; i < n; ++i) {
        double far = 0;
        for (int a = 0; a < 3; ++a) far = std::max(far, moved(shapes[i], i, a));
        const double ahead = kAllowCalls * far / static_cast<double>(calls_since_build);
        next[i] = std::max(next[i], std::min(ahead, kAllowSizes * (reach[i] + typical)));
      }
    allow = std::move(next);
    const WrapGrid grid(shapes, cell, &allow);
    // Candidates gathered in the grid's order, then counting-sorted by i
    // and each row sorted by j: the hand-over is then in (i, j) order.
    std::vector<IndexPair> raw;
    grid.pairs(shapes, [&](std::uint32_t p, std::uint32_t q) {
      const IndexPair c = detail::ordered(p, q);
      const Shape& si = shapes[c.i];
      const Shape& sj = shapes[c.j];
      // Keep only pairs within their allowances on every axis (short way
      // round).
      for (int a = 0; a < 3; ++a) {
        double d = std::fabs(si.center[a] - sj.center[a]);
        double L = 0;  // the length is not read on an axis that does not wrap
        if (cell.periodic[static_cast<std::size_t>(a)]) {
          L = cell.length[a];
          d = std::min(d, L - d);
        }
        const double e = largest_half(si) + largest_half(sj) + allow[c.i] + allow[c.j];
        if (!(d <= e + kShiftSlack * (e + d + L) + kShiftFloor)) return;
      }
      raw.push_back(c);
    });
    std::vector<std::uint32_t> start(n + 1, 0);
    for (const IndexPair& c : raw) ++start[c.i + 1];
    for (std::size_t i = 1; i <= n; ++i) start[i] += start[i - 1];
    candidates.resize(raw.size());
    {
      std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
      for (const IndexPair& c : raw) candidates[fill[c.i]++] = c;
    }
    for (std::size_t i = 0; i < n; ++i)
      std::sort(candidates.begin() + start[i], candidates.begin() + start[i + 1],
                [](const IndexPair& p, const IndexPair& q) { return p.j < q.j; });
    candidates.shrink_to_fit();
    hits.assign(candidates.size(), 0);
    home.resize(3 * n);
    reach.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      for (int a = 0; a < 3; ++a) home[3 * i + static_cast<std::size_t>(a)] = shapes[i].center[a];
      reach[i] = largest_half(shapes[i]);
    }
    count = n;
    built = true;
    calls_since_build = 0;
  }
};

PeriodicPairTracker::PeriodicPairTracker(const PeriodicCell& cell, const ArrayOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.check();
  check_cell(cell);
  impl_->cell = cell;
  impl_->options = options;
  impl_->skin_factor = options.skin > 0 ? options.skin : 0.25;
}
PeriodicPairTracker::~PeriodicPairTracker() = default;
PeriodicPairTracker::PeriodicPairTracker(PeriodicPairTracker&&) noexcept = default;
PeriodicPairTracker& PeriodicPairTracker::operator=(PeriodicPairTracker&&) noexcept = default;

const PeriodicCell& PeriodicPairTracker::cell() const { return impl_->cell; }
double PeriodicPairTracker::skin() const { return impl_->skin; }
void PeriodicPairTracker::clear() {
  Impl& im = *impl_;
  im.built = false;
  im.candidates = {};
  im.hits = {};
  im.home = {};
  im.reach = {};
  im.allow = {};
}

std::size_t PeriodicPairTracker::memory_bytes() const {
  const Impl& im = *impl_;
  return im.candidates.capacity() * sizeof(IndexPair) + im.hits.capacity() * sizeof(std::uint32_t) +
         im.home.capacity() * sizeof(double) + im.reach.capacity() * sizeof(double) +
         im.allow.capacity() * sizeof(double) + im.changed.capacity();
}

ArrayCallStats PeriodicPairTracker::find_pairs(const Objects& objects, const ShiftedPairSink& sink,
                                               const Changes& changes) {
  Impl& im = *impl_;
  const std::size_t n = objects.count;
  if (!changes.all)
    for (std::uint32_t k : changes.indices)
      if (k >= n)
        throw InvalidObjects(
            "changes: index " + std::to_string(k) + " is not below the count " + std::to_string(n),
            k);
  // A call that lists its changes on the same objects reads, so checks,
  // only those (the others were checked when last read and are promised
  // unchanged): a static frame at 20 000 half-boxes went from 0.76 ms of
  // CPU to 0.024 ms.
  if (changes.all || !im.built || n != im.count) {
    check_periodic(objects, im.cell);
  } else {
    check_cell(im.cell);
    std::vector<std::uint64_t> listed((n + 63) / 64, 0);
    for (std::uint32_t k : changes.indices) listed[k / 64] |= std::uint64_t{1} << (k % 64);
    detail::check_listed(objects, listed);
    for (std::uint32_t k : changes.indices) check_in_cell(objects, im.cell, k, "objects");
  }
  detail::check_filter_columns(objects, "objects");
  ArrayCallStats stats;
  bool rebuild = !im.built || n != im.count;
  im.changed.assign(n, changes.all ? 1 : 0);
  if (!changes.all)
    for (std::uint32_t k : changes.indices) im.changed[k] = 1;
  // Only the changed objects are read here (a steady call read every
  // object's shape twice before: 4.3 ms of CPU at 20 000 half-boxes).
  if (!rebuild)
    for (std::size_t i = 0; i < n && !rebuild; ++i)
      if (im.changed[i] && im.left(detail::read_shape(objects, static_cast<std::uint32_t>(i)), i))
        rebuild = true;
  if (rebuild) {
    im.build(read_all(objects));
    std::fill(im.changed.begin(), im.changed.end(), 1);
    stats.rebuilt = true;
  }
  ++im.calls_since_build;
  ShiftedEmitter emit(sink, false, stats, detail::PairFilterColumns::of(objects));
  bool going = true;
  for (std::size_t k = 0; k < im.candidates.size(); ++k) {
    const IndexPair c = im.candidates[k];
    if (im.changed[c.i] || im.changed[c.j]) {
      std::uint32_t bits = 0;
      stats.tests += test_shifts(detail::read_shape(objects, c.i), detail::read_shape(objects, c.j),
                                 im.cell, [&](int code) { bits |= 1u << code; });
      im.hits[k] = bits;
    }
    if (!going) continue;
    for (std::uint32_t bits = im.hits[k]; bits != 0; bits &= bits - 1)
      if (!(going = emit.add(c.i, c.j, std::countr_zero(bits)))) break;
  }
  if (going) emit.finish();
  return stats;
}

ArrayCallStats PeriodicPairTracker::find_pairs(const Objects& objects,
                                               std::vector<ShiftedPair>& out,
                                               const Changes& changes) {
  return find_pairs(objects, append_shifted(out), changes);
}

void PeriodicPairTracker::validate(const Objects& objects) const {
  const Impl& im = *impl_;
  if (!im.built) return;
  if (objects.count != im.count)
    throw std::logic_error("validate: the count is not the last call's");
  const std::vector<Shape> shapes = read_all(objects);
  for (std::size_t i = 0; i < im.count; ++i)
    if (im.left(shapes[i], i))
      throw std::logic_error("validate: object " + std::to_string(i) +
                             " is beyond its allowance from where its candidates were found");
  for (std::size_t k = 0; k < im.candidates.size(); ++k) {
    const IndexPair c = im.candidates[k];
    if (!(c.i < c.j && c.j < im.count))
      throw std::logic_error("validate: candidate " + std::to_string(k) + " is not i < j < n");
    if (k > 0) {
      const IndexPair p = im.candidates[k - 1];
      if (!(p.i < c.i || (p.i == c.i && p.j < c.j)))
        throw std::logic_error("validate: candidates not sorted and unique at " +
                               std::to_string(k));
    }
    std::uint32_t bits = 0;
    test_shifts(shapes[c.i], shapes[c.j], im.cell, [&](int code) { bits |= 1u << code; });
    if (bits != im.hits[k])
      throw std::logic_error("validate: candidate " + std::to_string(c.i) + ", " +
                             std::to_string(c.j) + " keeps an answer the exact test does not give");
  }
}

}  // namespace broadphase::arrays
