// KnnIndex: the grid of cells and the two searches (knn.hpp, docs/knn.md).
//
// The culling is conservative with respect to the double arithmetic of the
// distance rule, not to real numbers. A point sits in the cell
// floor((p - lo) * inv) computed in double, so it may lie a few ulps outside
// the cell's edges lo + c * h as computed; its dx = q - p rounds too, and so
// do a periodic image's p ± L. Every such error is below 2^-50 of
// |lo| + |hi| + |q| (+ L), so a cell's gap to the query on an axis is taken
// smaller by delta = 2^-40 of that (plus 2^-500 for the squares that
// underflow), and a sum of squared gaps smaller by a factor 1 - 2^-40. A
// point of a cell then has a computed d2 at least the cell's bound: a cell
// is skipped only when its bound is above the k-th best d2 (strictly, as a
// point at the same d2 with a smaller index would still enter), and the
// search stops only when every cell not visited has a bound above it.
#include <algorithm>
#include <array>
#include <atomic>
#include <broadphase/detail/in_order.hpp>
#include <broadphase/knn.hpp>
#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <utility>

namespace broadphase {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::uint32_t kNoSelf = 0xFFFFFFFFu;
constexpr double kShrink = 1 - 0x1p-40;
constexpr double kSlack = 0x1p-40;
constexpr double kFloor = 0x1p-500;
// Chebyshev radius of the sorted offsets a knn query walks first; beyond
// it, whole shells. At 2 points a cell, k = 32 stops within radius 2.
constexpr int kReach = 4;
constexpr int kSide = 2 * kReach + 1;
// Queries per piece of work handed to a thread: pieces are cut by index,
// so results never depend on the thread count.
constexpr std::size_t kChunk = 4096;

std::string row_text(const char* what, std::size_t i) {
  return std::string(what) + "[" + std::to_string(i) + "]";
}

// An explicit count is capped at 1024; 0 takes every core.
unsigned thread_count(unsigned threads) {
  return threads != 0 ? std::min(threads, 1024u) : broadphase::detail::thread_count(0);
}

// Runs job(c) for every chunk c in [0, chunks) on up to `threads` threads.
template <class Job>
void run_chunks(std::size_t chunks, unsigned threads, Job&& job) {
  const unsigned t = static_cast<unsigned>(std::min<std::size_t>(thread_count(threads), chunks));
  if (t <= 1) {
    for (std::size_t c = 0; c < chunks; ++c) job(c);
    return;
  }
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t c; (c = next.fetch_add(1)) < chunks;) job(c);
  };
  std::vector<std::jthread> pool;
  pool.reserve(t - 1);
  for (unsigned i = 1; i < t; ++i) pool.emplace_back(work);
  work();
}

double sq(double v) { return v * v; }

// The distance rule's term on a periodic axis: the nearest of the three
// images p, p + L, p - L.
double periodic_term(double q, double p, double length) {
  const double a = sq(q - p);
  const double b = sq(q - (p + length));
  const double c = sq(q - (p - length));
  return std::min(a, std::min(b, c));
}

// The k best (d2, index) of a query so far, kept sorted in its output row.
struct Best {
  double* d2;
  std::int64_t* index;
  std::size_t k;
  std::size_t count = 0;
  double worst = kInf;
  std::int64_t worst_index = std::numeric_limits<std::int64_t>::max();

  void offer(double d, std::int64_t id) {
    std::size_t at = count < k ? count : k - 1;
    while (at > 0 && (d < d2[at - 1] || (d == d2[at - 1] && id < index[at - 1]))) {
      d2[at] = d2[at - 1];
      index[at] = index[at - 1];
      --at;
    }
    d2[at] = d;
    index[at] = id;
    if (count < k) ++count;
    if (count == k) {
      worst = d2[k - 1];
      worst_index = index[k - 1];
    }
  }
};

}  // namespace

int KnnIndex::cell_on(int a, double v) const {
  if (m_[a] == 1) return 0;
  const double t = (v - lo_[a]) * inv_[a];
  if (!(t > 0)) return 0;
  if (t >= m_[a]) return m_[a] - 1;
  return static_cast<int>(t);
}

double KnnIndex::edge(int a, long c) const {
  if (c <= 0) return lo_[a];
  if (c >= m_[a]) return hi_[a];
  return lo_[a] + static_cast<double>(c) * h_[a];
}

void KnnIndex::offset_range(const int (&cq)[3], int a, int& lo, int& hi) const {
  if (periodic_[a]) {
    lo = -(m_[a] - 1) / 2;
    hi = m_[a] / 2;
  } else {
    lo = -cq[a];
    hi = m_[a] - 1 - cq[a];
  }
}

// The gap from q to the cell at offset `o` on axis a, made safe (see the top
// of the file); `c` is the query's cell on the axis. The cell must exist.
double KnnIndex::axis_gap(int a, double q, int c, int o, double delta) const {
  double g;
  if (periodic_[a]) {
    long w = (static_cast<long>(c) + o) % m_[a];
    if (w < 0) w += m_[a];
    const double lo = edge(a, w);
    const double hi = edge(a, w + 1);
    const double l = length_[a];
    auto dist = [q](double e0, double e1) { return std::max(std::max(e0 - q, q - e1), 0.0); };
    g = std::min(dist(lo, hi), std::min(dist(lo + l, hi + l), dist(lo - l, hi - l)));
  } else {
    const long u = static_cast<long>(c) + o;
    g = std::max(std::max(edge(a, u) - q, q - edge(a, u + 1)), 0.0);
  }
  g -= delta;
  return g > 0 ? g : 0;
}

long KnnIndex::wrapped(int a, int c, int o) const {
  long w = static_cast<long>(c) + o;
  if (periodic_[a]) {
    w %= m_[a];
    if (w < 0) w += m_[a];
  }
  return w;
}

KnnIndex::KnnIndex(const Points& points, const KnnConfig& config) {
  const std::size_t n = points.count;
  if (n > 0xFFFFFFFEull)
    throw InvalidPoints("knn: more than 2^32 - 2 points (" + std::to_string(n) + ")", SIZE_MAX);
  if (!(config.cell_points > 0) || !std::isfinite(config.cell_points))
    throw InvalidPoints("knn: cell_points must be positive and finite", SIZE_MAX);
  if (config.box) {
    for (int a = 0; a < 3; ++a) {
      if (!config.box->periodic[a]) continue;
      const double l = config.box->length[a];
      if (!(l > 0) || !std::isfinite(l))
        throw InvalidPoints("knn: the periodic box's length on axis " + std::string(1, "xyz"[a]) +
                                " must be finite and positive",
                            SIZE_MAX);
      periodic_[a] = true;
      length_[a] = l;
      any_periodic_ = true;
    }
  }
  std::vector<Point> pts(n);
  for (int a = 0; a < 3; ++a) {
    lo_[a] = n == 0 ? 0 : kInf;
    hi_[a] = n == 0 ? 0 : -kInf;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p = points.at(i);
    check_point(p, i, "points");
    pts[i] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      lo_[a] = std::min(lo_[a], p[a]);
      hi_[a] = std::max(hi_[a], p[a]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (periodic_[a]) {
      lo_[a] = 0;
      hi_[a] = length_[a];
    }
  }

  // Cells per axis: about n / cell_points cells over the extents, cubes
  // where possible; an axis of no (or infinite) extent gets one cell. At
  // most 4 n + 64 cells (4 bytes each in `start_`).
  const double cap = 4 * static_cast<double>(n) + 64;
  auto choose = [&](double target) {
    double log_volume = 0;
    int dims = 0;
    for (int a = 0; a < 3; ++a) {
      const double e = hi_[a] - lo_[a];
      if (e > 0 && std::isfinite(e)) {
        log_volume += std::log(e);
        ++dims;
      }
    }
    for (int a = 0; a < 3; ++a) {
      m_[a] = 1;
      h_[a] = 0;
      inv_[a] = 0;
    }
    if (dims == 0) return;
    const double log_h = (log_volume - std::log(target)) / dims;
    for (int a = 0; a < 3; ++a) {
      const double e = hi_[a] - lo_[a];
      if (!(e > 0) || !std::isfinite(e)) continue;
      const double m = std::exp(std::log(e) - log_h);
      m_[a] = m >= 0x1p20 ? (1 << 20) : std::max(1, static_cast<int>(std::lround(m)));
    }
    // Rounding and lone long axes may overshoot.
    while (static_cast<double>(m_[0]) * m_[1] * m_[2] > std::min(4 * target + 64, cap)) {
      const int a = static_cast<int>(std::max_element(m_, m_ + 3) - m_);
      m_[a] = (m_[a] + 1) / 2;
    }
    for (int a = 0; a < 3; ++a) {
      if (m_[a] > 1) {
        h_[a] = (hi_[a] - lo_[a]) / m_[a];
        inv_[a] = m_[a] / (hi_[a] - lo_[a]);
      }
    }
  };
  auto cell_key = [&](const Point& p) {
    return (static_cast<std::size_t>(cell_on(2, p.z)) * m_[1] + cell_on(1, p.y)) * m_[0] +
           cell_on(0, p.x);
  };
  // Clustered points crowd the cells of a grid over their bounding box.
  // Finer cells where the occupied ones held over twice cell_points (up to
  // 8 n cells) measured no faster: 1.59 s with them, 1.61 s without, and
  // 1.55 s against 1.59 s, for k = 8 on 2 x 10^5 points in 1 000 blobs of
  // sigma 0.01 and 0.002 (knn_bench): crowded cells are read in long runs.
  choose(std::max(1.0, static_cast<double>(n) / config.cell_points));
  for (int a = 0; a < 3; ++a)
    magnitude_[a] = 2 * std::max(std::fabs(lo_[a]), std::fabs(hi_[a])) + length_[a];

  // Counting sort of the points by cell (x fastest), stable: a cell's
  // points in index order.
  const std::size_t cells = static_cast<std::size_t>(m_[0]) * m_[1] * m_[2];
  start_.assign(cells + 1, 0);
  std::vector<std::uint32_t> cell_of(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t c = cell_key(pts[i]);
    cell_of[i] = static_cast<std::uint32_t>(c);
    ++start_[c + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
  points_.resize(n);
  ids_.resize(n);
  {
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t at = fill[cell_of[i]]++;
      points_[at] = pts[i];
      ids_[at] = static_cast<std::uint32_t>(i);
    }
  }

  // The offsets within Chebyshev radius kReach, by the least squared
  // distance between a point of the centre cell and one of theirs.
  struct Ranked {
    double g;
    Offset o;
  };
  std::vector<Ranked> ranked;
  for (int z = -kReach; z <= kReach; ++z)
    for (int y = -kReach; y <= kReach; ++y)
      for (int x = -kReach; x <= kReach; ++x) {
        const int o[3] = {x, y, z};
        double g = 0;
        for (int a = 0; a < 3; ++a) g += sq(std::max(std::abs(o[a]) - 1, 0) * h_[a]);
        ranked.push_back({g,
                          {{static_cast<std::int8_t>(x), static_cast<std::int8_t>(y),
                            static_cast<std::int8_t>(z)}}});
      }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const Ranked& a, const Ranked& b) { return a.g < b.g; });
  for (const Ranked& r : ranked) {
    offsets_.push_back(r.o);
    offset_bound_.push_back(r.g);
  }
}

void KnnIndex::check_point(const Vec3& p, std::size_t row, const char* what) const {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(p[a]))
      throw InvalidPoints("knn: " + row_text(what, row) + " has a coordinate that is not finite",
                          row);
    if (periodic_[a] && !(p[a] >= 0 && p[a] <= length_[a]))
      throw InvalidPoints("knn: " + row_text(what, row) + " lies outside the periodic box on " +
                              std::string(1, "xyz"[a]) + " (coordinates must be in [0, L])",
                          row);
  }
}

std::size_t KnnIndex::memory_bytes() const {
  return points_.capacity() * sizeof(Point) + ids_.capacity() * 4 + start_.capacity() * 4 +
         offsets_.capacity() * sizeof(Offset) + offset_bound_.capacity() * sizeof(double);
}

template <bool kPeriodic>
void KnnIndex::knn_one(const Vec3& q, const int (&cq)[3], std::size_t k, std::uint32_t self,
                       double* d2_row, std::int64_t* index_row) const {
  Best best{d2_row, index_row, k};
  const double qx = q.x, qy = q.y, qz = q.z;
  const Point* pts = points_.data();
  const std::uint32_t* ids = ids_.data();
  auto scan = [&](std::size_t cell) {
    const std::uint32_t end = start_[cell + 1];
    for (std::uint32_t j = start_[cell]; j < end; ++j) {
      const Point& p = pts[j];
      double d;
      if constexpr (kPeriodic) {
        const double tx = periodic_[0] ? periodic_term(qx, p.x, length_[0]) : sq(qx - p.x);
        const double ty = periodic_[1] ? periodic_term(qy, p.y, length_[1]) : sq(qy - p.y);
        const double tz = periodic_[2] ? periodic_term(qz, p.z, length_[2]) : sq(qz - p.z);
        d = tx + ty + tz;
      } else {
        const double dx = qx - p.x;
        const double dy = qy - p.y;
        const double dz = qz - p.z;
        d = dx * dx + dy * dy + dz * dz;
      }
      if (d > best.worst) continue;
      const std::int64_t id = ids[j];
      if (d == best.worst && id > best.worst_index) continue;
      if (ids[j] == self) continue;
      best.offer(d, id);
    }
  };

  double delta[3], gaps[3][kSide];
  long cellc[3][kSide];
  int rlo[3], rhi[3];
  double shrink = kShrink;  // the sorted bounds' scale for delta (see below)
  double beyond = kInf;     // bound of every cell outside the sorted offsets
  for (int a = 0; a < 3; ++a) {
    delta[a] = kSlack * (magnitude_[a] + std::fabs(q[a])) + kFloor;
    offset_range(cq, a, rlo[a], rhi[a]);
    for (int o = std::max(rlo[a], -kReach); o <= std::min(rhi[a], kReach); ++o) {
      gaps[a][o + kReach] = axis_gap(a, q[a], cq[a], o, delta[a]);
      cellc[a][o + kReach] = wrapped(a, cq[a], o);
    }
    // (i h - delta)+ >= i (h - delta)+ for i >= 1, so the sorted bound
    // G(o) times min_a ((h_a - delta_a)+ / h_a)^2 bounds every later offset.
    if (h_[a] > 0) shrink = std::min(shrink, kShrink * sq(std::max(h_[a] - delta[a], 0.0) / h_[a]));
    if (rlo[a] < -kReach || rhi[a] > kReach)
      beyond = std::min(beyond, kShrink * sq(std::max(kReach * h_[a] - delta[a], 0.0)));
  }

  bool done = false;
  for (std::size_t t = 0; t < offsets_.size(); ++t) {
    if (best.worst < std::min(offset_bound_[t] * shrink, beyond)) {
      done = true;
      break;
    }
    const Offset& off = offsets_[t];
    const int ox = off.o[0], oy = off.o[1], oz = off.o[2];
    if (ox < rlo[0] || ox > rhi[0] || oy < rlo[1] || oy > rhi[1] || oz < rlo[2] || oz > rhi[2])
      continue;
    const double gx = gaps[0][ox + kReach], gy = gaps[1][oy + kReach], gz = gaps[2][oz + kReach];
    if ((gx * gx + gy * gy + gz * gz) * kShrink > best.worst) continue;
    scan(static_cast<std::size_t>((cellc[2][oz + kReach] * m_[1] + cellc[1][oy + kReach]) * m_[0] +
                                  cellc[0][ox + kReach]));
  }

  // Whole shells beyond the sorted offsets, while cells remain that could
  // hold a better point.
  for (int rho = kReach + 1; !done; ++rho) {
    double bound = kInf;
    bool more = false;
    for (int a = 0; a < 3; ++a) {
      if (rlo[a] <= -rho || rhi[a] >= rho) {
        more = true;
        bound = std::min(bound, kShrink * sq(std::max((rho - 1) * h_[a] - delta[a], 0.0)));
      }
    }
    if (!more || best.worst < bound) break;
    const int zl = std::max(rlo[2], -rho), zh = std::min(rhi[2], rho);
    const int yl = std::max(rlo[1], -rho), yh = std::min(rhi[1], rho);
    const int xl = std::max(rlo[0], -rho), xh = std::min(rhi[0], rho);
    for (int oz = zl; oz <= zh; ++oz) {
      const double gz = axis_gap(2, q.z, cq[2], oz, delta[2]);
      for (int oy = yl; oy <= yh; ++oy) {
        const double gy = axis_gap(1, q.y, cq[1], oy, delta[1]);
        const long row = (wrapped(2, cq[2], oz) * m_[1] + wrapped(1, cq[1], oy)) * m_[0];
        auto visit = [&](int ox) {
          const double gx = axis_gap(0, q.x, cq[0], ox, delta[0]);
          if ((gx * gx + gy * gy + gz * gz) * kShrink > best.worst) return;
          scan(static_cast<std::size_t>(row + wrapped(0, cq[0], ox)));
        };
        if (std::abs(oz) == rho || std::abs(oy) == rho) {
          for (int ox = xl; ox <= xh; ++ox) visit(ox);
        } else {
          if (xl <= -rho) visit(-rho);
          if (xh >= rho) visit(rho);
        }
      }
    }
  }
  for (std::size_t i = best.count; i < k; ++i) {
    d2_row[i] = kInf;
    index_row[i] = static_cast<std::int64_t>(ids_.size());
  }
}

template <bool kPeriodic>
void KnnIndex::within_one(const Vec3& q, const int (&cq)[3], double r, double r2,
                          std::uint32_t self,
                          std::vector<std::pair<double, std::uint32_t>>& out) const {
  const std::size_t first = out.size();
  double delta[3];
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    delta[a] = kSlack * (magnitude_[a] + std::fabs(q[a])) + kFloor;
    offset_range(cq, a, lo[a], hi[a]);
    // Cells further than this many on the axis are further than r: the
    // per-cell bound below decides the rest.
    if (h_[a] > 0) {
      const double reach = (r + 2 * delta[a]) / h_[a] + 2;
      if (reach < 0x1p30) {
        const int c = static_cast<int>(std::ceil(reach));
        lo[a] = std::max(lo[a], -c);
        hi[a] = std::min(hi[a], c);
      }
    }
  }
  const Point* pts = points_.data();
  for (int oz = lo[2]; oz <= hi[2]; ++oz) {
    const double gz = axis_gap(2, q.z, cq[2], oz, delta[2]);
    const long cz = wrapped(2, cq[2], oz);
    for (int oy = lo[1]; oy <= hi[1]; ++oy) {
      const double gy = axis_gap(1, q.y, cq[1], oy, delta[1]);
      const long row = (cz * m_[1] + wrapped(1, cq[1], oy)) * m_[0];
      for (int ox = lo[0]; ox <= hi[0]; ++ox) {
        const double gx = axis_gap(0, q.x, cq[0], ox, delta[0]);
        if ((gx * gx + gy * gy + gz * gz) * kShrink > r2) continue;
        const std::size_t cell = static_cast<std::size_t>(row + wrapped(0, cq[0], ox));
        for (std::uint32_t j = start_[cell]; j < start_[cell + 1]; ++j) {
          const Point& p = pts[j];
          double d;
          if constexpr (kPeriodic) {
            const double tx = periodic_[0] ? periodic_term(q.x, p.x, length_[0]) : sq(q.x - p.x);
            const double ty = periodic_[1] ? periodic_term(q.y, p.y, length_[1]) : sq(q.y - p.y);
            const double tz = periodic_[2] ? periodic_term(q.z, p.z, length_[2]) : sq(q.z - p.z);
            d = tx + ty + tz;
          } else {
            const double dx = q.x - p.x;
            const double dy = q.y - p.y;
            const double dz = q.z - p.z;
            d = dx * dx + dy * dy + dz * dz;
          }
          if (d <= r2 && ids_[j] != self) out.emplace_back(d, ids_[j]);
        }
      }
    }
  }
  std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end());
}

// The order in which queries are processed: by cell, so that neighbouring
// queries read the same cells (results do not depend on it).
std::vector<std::uint32_t> KnnIndex::query_order(const std::vector<Vec3>& qs,
                                                 std::vector<std::array<int, 3>>& cq) const {
  const std::size_t cells = start_.size() - 1;
  std::vector<std::uint32_t> count(cells + 1, 0), order(qs.size());
  std::vector<std::uint32_t> key(qs.size());
  cq.resize(qs.size());
  for (std::size_t i = 0; i < qs.size(); ++i) {
    for (int a = 0; a < 3; ++a) cq[i][a] = cell_on(a, qs[i][a]);
    key[i] = static_cast<std::uint32_t>(
        (static_cast<std::size_t>(cq[i][2]) * m_[1] + cq[i][1]) * m_[0] + cq[i][0]);
    ++count[key[i] + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) count[c + 1] += count[c];
  for (std::size_t i = 0; i < qs.size(); ++i)
    order[count[key[i]]++] = static_cast<std::uint32_t>(i);
  return order;
}

std::vector<Vec3> KnnIndex::read_queries(const Points& queries) const {
  if (queries.count > 0xFFFFFFFEull)
    throw InvalidPoints("knn: more than 2^32 - 2 queries", SIZE_MAX);
  std::vector<Vec3> qs(queries.count);
  for (std::size_t i = 0; i < queries.count; ++i) {
    qs[i] = queries.at(i);
    check_point(qs[i], i, "queries");
  }
  return qs;
}

void KnnIndex::check_knn_out(std::size_t rows, std::size_t k, std::span<double> d2,
                             std::span<std::int64_t> index) const {
  if (k == 0) throw InvalidPoints("knn: k must be at least 1", SIZE_MAX);
  if (d2.size() / k != rows || d2.size() % k != 0 || index.size() != d2.size())
    throw InvalidPoints("knn: the outputs must hold queries x k = " + std::to_string(rows) + " x " +
                            std::to_string(k) + " values",
                        SIZE_MAX);
}

void KnnIndex::knn(const Points& queries, std::size_t k, std::span<double> d2,
                   std::span<std::int64_t> index, unsigned threads) const {
  check_knn_out(queries.count, k, d2, index);
  const std::vector<Vec3> qs = read_queries(queries);
  std::vector<std::array<int, 3>> cq;
  const std::vector<std::uint32_t> order = query_order(qs, cq);
  run_chunks((qs.size() + kChunk - 1) / kChunk, threads, [&](std::size_t c) {
    const std::size_t end = std::min(qs.size(), (c + 1) * kChunk);
    for (std::size_t t = c * kChunk; t < end; ++t) {
      const std::uint32_t i = order[t];
      const int cell[3] = {cq[i][0], cq[i][1], cq[i][2]};
      if (any_periodic_)
        knn_one<true>(qs[i], cell, k, kNoSelf, d2.data() + i * k, index.data() + i * k);
      else
        knn_one<false>(qs[i], cell, k, kNoSelf, d2.data() + i * k, index.data() + i * k);
    }
  });
}

void KnnIndex::knn_self(std::size_t k, bool exclude_self, std::span<double> d2,
                        std::span<std::int64_t> index, unsigned threads) const {
  check_knn_out(size(), k, d2, index);
  // The points in cell order are their own best query order.
  run_chunks((size() + kChunk - 1) / kChunk, threads, [&](std::size_t c) {
    const std::size_t end = std::min(size(), (c + 1) * kChunk);
    for (std::size_t j = c * kChunk; j < end; ++j) {
      const Vec3 q{points_[j].x, points_[j].y, points_[j].z};
      const int cell[3] = {cell_on(0, q.x), cell_on(1, q.y), cell_on(2, q.z)};
      const std::size_t i = ids_[j];
      const std::uint32_t self = exclude_self ? ids_[j] : kNoSelf;
      if (any_periodic_)
        knn_one<true>(q, cell, k, self, d2.data() + i * k, index.data() + i * k);
      else
        knn_one<false>(q, cell, k, self, d2.data() + i * k, index.data() + i * k);
    }
  });
}

// Gathers per-chunk results (queries in processing order) into CSR by
// query index.
Neighbours KnnIndex::within_run(
    std::size_t rows, double r, unsigned threads,
    const std::function<void(std::size_t, Vec3&, int (&)[3], std::uint32_t&, std::uint32_t&)>&
        query) const {
  if (!(r >= 0)) throw InvalidPoints("within: r must be >= 0 (not NaN)", SIZE_MAX);
  const double r2 = r * r;
  const std::size_t chunks = (rows + kChunk - 1) / kChunk;
  struct Part {
    std::vector<std::pair<double, std::uint32_t>> found;
    std::vector<std::uint32_t> row, count;
  };
  std::vector<Part> parts(chunks);
  run_chunks(chunks, threads, [&](std::size_t c) {
    Part& part = parts[c];
    const std::size_t end = std::min(rows, (c + 1) * kChunk);
    for (std::size_t t = c * kChunk; t < end; ++t) {
      Vec3 q;
      int cell[3];
      std::uint32_t row, self;
      query(t, q, cell, row, self);
      const std::size_t before = part.found.size();
      if (any_periodic_)
        within_one<true>(q, cell, r, r2, self, part.found);
      else
        within_one<false>(q, cell, r, r2, self, part.found);
      part.row.push_back(row);
      part.count.push_back(static_cast<std::uint32_t>(part.found.size() - before));
    }
  });
  Neighbours out;
  out.offsets.assign(rows + 1, 0);
  for (const Part& part : parts)
    for (std::size_t t = 0; t < part.row.size(); ++t) out.offsets[part.row[t] + 1] = part.count[t];
  for (std::size_t i = 0; i < rows; ++i) out.offsets[i + 1] += out.offsets[i];
  out.index.resize(static_cast<std::size_t>(out.offsets[rows]));
  out.d2.resize(out.index.size());
  for (const Part& part : parts) {
    std::size_t from = 0;
    for (std::size_t t = 0; t < part.row.size(); ++t) {
      std::size_t at = static_cast<std::size_t>(out.offsets[part.row[t]]);
      for (std::uint32_t u = 0; u < part.count[t]; ++u, ++at, ++from) {
        out.d2[at] = part.found[from].first;
        out.index[at] = part.found[from].second;
      }
    }
  }
  return out;
}

Neighbours KnnIndex::within(const Points& queries, double r, unsigned threads) const {
  if (!(r >= 0)) throw InvalidPoints("within: r must be >= 0 (not NaN)", SIZE_MAX);
  const std::vector<Vec3> qs = read_queries(queries);
  std::vector<std::array<int, 3>> cq;
  const std::vector<std::uint32_t> order = query_order(qs, cq);
  return within_run(
      qs.size(), r, threads,
      [&](std::size_t t, Vec3& q, int(&cell)[3], std::uint32_t& row, std::uint32_t& self) {
        row = order[t];
        q = qs[row];
        for (int a = 0; a < 3; ++a) cell[a] = cq[row][a];
        self = kNoSelf;
      });
}

Neighbours KnnIndex::within_self(double r, bool exclude_self, unsigned threads) const {
  return within_run(
      size(), r, threads,
      [&](std::size_t j, Vec3& q, int(&cell)[3], std::uint32_t& row, std::uint32_t& self) {
        q = {points_[j].x, points_[j].y, points_[j].z};
        for (int a = 0; a < 3; ++a) cell[a] = cell_on(a, q[a]);
        row = ids_[j];
        self = exclude_self ? ids_[j] : kNoSelf;
      });
}

KnnResult knn(const Points& points, const std::optional<Points>& queries, std::size_t k,
              const KnnConfig& config, bool exclude_self, unsigned threads) {
  if (k == 0) throw InvalidPoints("knn: k must be at least 1", SIZE_MAX);
  const KnnIndex index(points, config);
  KnnResult out;
  out.k = k;
  const std::size_t rows = queries ? queries->count : points.count;
  out.d2.resize(rows * k);
  out.index.resize(rows * k);
  if (queries)
    index.knn(*queries, k, out.d2, out.index, threads);
  else
    index.knn_self(k, exclude_self, out.d2, out.index, threads);
  return out;
}

Neighbours within(const Points& points, const std::optional<Points>& queries, double r,
                  const KnnConfig& config, bool exclude_self, unsigned threads) {
  if (!(r >= 0)) throw InvalidPoints("within: r must be >= 0 (not NaN)", SIZE_MAX);
  const KnnIndex index(points, config);
  return queries ? index.within(*queries, r, threads) : index.within_self(r, exclude_self, threads);
}

}  // namespace broadphase
