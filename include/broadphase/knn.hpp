/// \file knn.hpp
/// The k nearest neighbours and the neighbours within a radius of query
/// points among a set of points in 3-D, exact against brute force, with
/// optional periodic orthorhombic boxes (docs/knn.md).
///
/// The distance rule. For a query q and a point p, both read as double
/// (a float is widened exactly), the squared distance is, in double and
/// exactly as written (left to right, no fused multiply-add: the library
/// compiles with -ffp-contract=off):
///
///     dx = qx - px;  dy = qy - py;  dz = qz - pz;
///     d2 = dx*dx + dy*dy + dz*dz;
///
/// In a periodic box (PeriodicCell, periodic.hpp) a point counts once, at
/// its nearest image: on a periodic axis a, dx is the one of qx - px,
/// qx - (px + Lx), qx - (px - Lx) with the smallest dx*dx (the contract's
/// image `p + S*L` in double, S in {-1, 0, 1}), which gives the smallest
/// d2 over the 27 images because rounding is monotone. Points and queries
/// lie in [0, L_a] on a periodic axis, so these shifts reach the nearest
/// image. One image per point, as scipy's cKDTree(boxsize=...) reports.
///
/// The order: each query's neighbours by d2, then by the point's index.
/// `knn` keeps the first k of that order; `within` keeps every point with
/// d2 <= r*r (r*r in double; touching counts). Every path (one thread or
/// many, queries apart or the points themselves) reports exactly what a
/// brute force over every point with this arithmetic reports, bit for bit.
///
/// How: the points sorted into a grid of cells (about `cell_points` points
/// a cell over their bounding box, or over the periodic box), and each
/// query visits cells in the order of their least possible distance,
/// stopping when the k-th best is closer than every cell not yet visited.
/// The cell bounds are made conservative with respect to the double
/// arithmetic above, so the culling never drops a neighbour that the brute
/// force would keep (docs/knn.md, "Exact").
///
/// Thread safety: a KnnIndex is immutable after construction; its const
/// calls may run concurrently. It copies the points (24 bytes a point plus
/// a 4-byte index), so the caller's arrays may change after the build.
#pragma once

#include <array>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/periodic.hpp>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace broadphase {

/// Thrown for unusable input: a NaN or infinite coordinate, a coordinate
/// outside a periodic box, a bad box, k = 0, a negative or NaN radius,
/// more points than 32-bit indices can name, outputs of the wrong size.
/// `index` is the first bad row (SIZE_MAX when the error is not a row's).
class InvalidPoints : public std::invalid_argument {
 public:
  InvalidPoints(const std::string& what, std::size_t index)
      : std::invalid_argument(what), index_(index) {}
  std::size_t index() const { return index_; }

 private:
  std::size_t index_;
};

/// Points read from the caller's memory: row i is (x.at(i), y.at(i),
/// z.at(i)), double or float columns with any strides (arrays.hpp).
struct Points {
  std::size_t count = 0;
  arrays::Column x, y, z;

  /// `n` rows of three values (`xyz[3i + a]`), double or float.
  template <class T>
  static Points rows(const T* xyz, std::size_t n) {
    return {n, arrays::Column::of(xyz, 3), arrays::Column::of(xyz + 1, 3),
            arrays::Column::of(xyz + 2, 3)};
  }
  Vec3 at(std::size_t i) const { return {x.at(i), y.at(i), z.at(i)}; }
};

/// Options of a KnnIndex.
struct KnnConfig {
  /// A periodic box [0, L_a] per axis, each axis periodic or not; points
  /// and queries must lie in [0, L_a] on every periodic axis. Unset: no
  /// periodicity (the grid spans the points' bounding box).
  std::optional<PeriodicCell> box;
  /// Mean points a grid cell over the points' bounding box (or the box).
  /// 1, 2, 3 and 4 measured alike on 3 x 10^5 uniform points for k = 1, 8
  /// and 32 (knn_bench --cell-points, within the noise of a shared host).
  double cell_points = 2.0;
};

/// A query's neighbours as CSR: query q's are at [offsets[q], offsets[q+1])
/// of `index` and `d2` (the squared distance of the rule above), in order.
struct Neighbours {
  std::vector<std::int64_t> offsets;
  std::vector<std::int64_t> index;
  std::vector<double> d2;
};

/// The points sorted into cells, for knn and radius queries.
class KnnIndex {
 public:
  /// Builds over `points` (at most 2^32 - 2 of them). Throws InvalidPoints
  /// for a non-finite coordinate, a point outside the periodic box, a box
  /// whose periodic lengths are not finite and positive, or a
  /// `cell_points` that is not positive. O(n).
  KnnIndex(const Points& points, const KnnConfig& config = {});

  /// The k nearest points of every query, row q of the outputs (k
  /// columns, row-major): squared distances in `d2` and point indices in
  /// `index`, both of size queries.count * k. Rows with fewer than k
  /// points available end with d2 = +inf and index = size() (cKDTree's
  /// filling). Throws InvalidPoints (k = 0, a bad query, wrong sizes).
  /// `threads` 0 takes every core; the output does not depend on it.
  void knn(const Points& queries, std::size_t k, std::span<double> d2,
           std::span<std::int64_t> index, unsigned threads = 1) const;
  /// The same with the points as queries (row i for point i); with
  /// `exclude_self`, a point is not its own neighbour (other points at the
  /// same place are).
  void knn_self(std::size_t k, bool exclude_self, std::span<double> d2,
                std::span<std::int64_t> index, unsigned threads = 1) const;

  /// Every point within r of each query (d2 <= r*r), in order. Throws
  /// InvalidPoints (r negative or NaN, a bad query).
  Neighbours within(const Points& queries, double r, unsigned threads = 1) const;
  /// The same with the points as queries.
  Neighbours within_self(double r, bool exclude_self, unsigned threads = 1) const;

  std::size_t size() const { return ids_.size(); }
  /// Grid cells per axis (for the docs' measurements and the tests).
  std::array<int, 3> cells() const { return {m_[0], m_[1], m_[2]}; }
  std::size_t memory_bytes() const;

 private:
  struct Point {
    double x, y, z;
  };
  struct Offset {
    std::int8_t o[3];
  };

  int cell_on(int axis, double v) const;
  double edge(int axis, long c) const;
  long wrapped(int axis, int c, int o) const;
  double axis_gap(int axis, double q, int c, int o, double delta) const;
  // The offsets [lo, hi] on an axis that name a cell once: inside the grid
  // on a closed axis; one turn around a periodic one.
  void offset_range(const int (&cq)[3], int axis, int& lo, int& hi) const;
  void check_point(const Vec3& p, std::size_t row, const char* what) const;
  void check_knn_out(std::size_t rows, std::size_t k, std::span<double> d2,
                     std::span<std::int64_t> index) const;
  std::vector<Vec3> read_queries(const Points& queries) const;
  std::vector<std::uint32_t> query_order(const std::vector<Vec3>& qs,
                                         std::vector<std::array<int, 3>>& cq) const;
  template <bool kPeriodic>
  void knn_one(const Vec3& q, const int (&cq)[3], std::size_t k, std::uint32_t self, double* d2,
               std::int64_t* index) const;
  template <bool kPeriodic>
  void within_one(const Vec3& q, const int (&cq)[3], double r, double r2, std::uint32_t self,
                  std::vector<std::pair<double, std::uint32_t>>& out) const;
  Neighbours within_run(std::size_t rows, double r, unsigned threads,
                        const std::function<void(std::size_t, Vec3&, int (&)[3], std::uint32_t&,
                                                 std::uint32_t&)>& query) const;

  std::vector<Point> points_;       // in cell order
  std::vector<std::uint32_t> ids_;  // the caller's index of points_[j]
  std::vector<std::uint32_t> start_;
  std::vector<Offset> offsets_;       // Chebyshev radius <= kReach, by least distance
  std::vector<double> offset_bound_;  // their least squared distance
  double lo_[3] = {0, 0, 0}, hi_[3] = {0, 0, 0};
  double h_[3] = {0, 0, 0}, inv_[3] = {0, 0, 0};
  double length_[3] = {0, 0, 0};  // the box's length on a periodic axis, else 0
  double magnitude_[3] = {0, 0, 0};
  int m_[3] = {1, 1, 1};
  bool periodic_[3] = {false, false, false};
  bool any_periodic_ = false;
};

/// One-shot forms: build a KnnIndex over `points` and query it. With
/// `queries` unset the points query themselves (`exclude_self` as above).
struct KnnResult {
  std::size_t k = 0;
  std::vector<double> d2;           ///< queries x k, row-major
  std::vector<std::int64_t> index;  ///< queries x k; missing: size of points
};
KnnResult knn(const Points& points, const std::optional<Points>& queries, std::size_t k,
              const KnnConfig& config = {}, bool exclude_self = false, unsigned threads = 1);
Neighbours within(const Points& points, const std::optional<Points>& queries, double r,
                  const KnnConfig& config = {}, bool exclude_self = false, unsigned threads = 1);

}  // namespace broadphase
