/// \file neighbours.hpp
/// Neighbour lists of points (atoms) in free space, orthorhombic and general
/// (triclinic) periodic cells: the pairs (i, j, S) within a cutoff, as ASE's
/// `neighbor_list`, MDAnalysis' `capped_distance` and scipy's
/// `cKDTree(boxsize=...)` find them, exact and with every image.
///
/// The cell is three vectors a, b, c (the rows of a 3x3 matrix, as ASE's
/// `atoms.cell` and MDAnalysis' `triclinic_vectors` give it), each axis
/// periodic or not. A shift S is three integers, 0 on the axes that are not
/// periodic; point j moved by S lies at x_j + S·cell.
///
/// The exact rule (docs/neighbours.md). In double, evaluated exactly as
/// written (left to right, no fused multiply-add):
///
///     o_k  = (S0*a_k + S1*b_k) + S2*c_k          for k = x, y, z
///     D_k  = (x_j,k + o_k) - x_i,k
///     d2   = (Dx*Dx + Dy*Dy) + Dz*Dz
///     s    = cutoff            (one cutoff)
///          = c_i + c_j         (per-point cutoffs, ASE's rule)
///     pair = d2 <= s*s         (CutoffRule::inclusive, the library's contract)
///            d2 <  s*s         (CutoffRule::strict, ASE's `<` at the boundary)
///
/// where x are the positions as given (a float is widened exactly): a point
/// outside the cell is not moved first, its wrapping is part of S. Each pair
/// is evaluated once, in its canonical orientation: i < j with the shift on
/// j; for a point with its own image (i == j, S != 0, cells smaller than the
/// cutoff) the one of S and -S whose first non-zero component (S0, then S1,
/// then S2) is positive, as ASE's half lists keep it. A full list adds the
/// mirror (j, i, -S) of each, with the vector -D and the same distance.
/// (i, i, 0) is a pair only with `self_interaction`.
///
/// How: bins over the fractional coordinates of the cell (a cell list), each
/// at least the largest reach wide across its planes, so that a half stencil
/// of the neighbouring bins (and every image where the cutoff exceeds the
/// cell) holds every candidate; culling is conservative with a margin for
/// the rounding of fractional coordinates, and the rule above decides.
/// Complexity O(n + pairs) for points of bounded density.
///
/// Thread-safety: the functions are reentrant; the input must not change
/// during a call. A call runs on NeighbourOptions::threads threads (one by
/// default); the list does not depend on how many.
#pragma once

#include <array>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/geometry.hpp>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <stdexcept>
#include <utility>
#include <vector>

namespace broadphase {

/// A cell: rows are the cell vectors a, b, c; each axis periodic or not.
/// The vectors of the periodic axes must be linearly independent; those of
/// the axes that are not periodic are not used (zero is fine).
struct NeighbourCell {
  std::array<Vec3, 3> vectors{};
  std::array<bool, 3> periodic{false, false, false};

  /// No periodic axis.
  static NeighbourCell free_space() { return {}; }
  /// The box [0, L_x] x [0, L_y] x [0, L_z], periodic on `axes`.
  static NeighbourCell orthorhombic(Vec3 lengths, std::array<bool, 3> axes = {true, true, true}) {
    return {{Vec3{lengths.x, 0, 0}, Vec3{0, lengths.y, 0}, Vec3{0, 0, lengths.z}}, axes};
  }
};

/// The allocator of NeighbourList's arrays: a resize leaves the new elements
/// uninitialised, because the engine then writes every one of them once,
/// from several threads (a zeroing resize touched every page of the arrays
/// on one thread first: at 10^6 points, 226 MB for 'ijS').
template <class T>
struct UninitialisedAllocator : std::allocator<T> {
  using value_type = T;
  UninitialisedAllocator() noexcept = default;
  template <class U>
  UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}
  template <class U>
  struct rebind {
    using other = UninitialisedAllocator<U>;
  };
  template <class U, class... A>
  void construct(U* p, A&&... a) {
    if constexpr (sizeof...(A) == 0)
      ::new (static_cast<void*>(p)) U;
    else
      ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
};

/// An array of a NeighbourList: a std::vector (with the allocator above).
template <class T>
using NeighbourVector = std::vector<T, UninitialisedAllocator<T>>;

namespace neighbours_detail {
/// A pair as MovingNeighbourList keeps it, and as the engine hands it its
/// candidates: the second point and the shift.
struct Candidate {
  std::uint32_t j;
  std::int32_t s[3];
};
}  // namespace neighbours_detail

/// `<=` (the library's contract) or `<` (ASE) at the cutoff.
enum class CutoffRule : std::uint8_t { inclusive, strict };

/// What to compute and how to list it.
struct NeighbourOptions {
  CutoffRule rule = CutoffRule::inclusive;
  /// Both (i, j, S) and (j, i, -S) (ASE's `neighbor_list`); false: each pair
  /// once in its canonical orientation (a half list).
  bool full = false;
  /// (i, i, 0) for every point whose own cutoff admits it (ASE's
  /// `self_interaction`).
  bool self_interaction = false;
  bool shifts = true;      ///< fill NeighbourList::shifts
  bool distances = false;  ///< fill NeighbourList::distances
  bool vectors = false;    ///< fill NeighbourList::vectors
  bool offsets = false;    ///< fill NeighbourList::offsets (CSR by `first`)
  /// Threads a call runs on: 0 takes every core. The list is the same for
  /// any count.
  unsigned threads = 1;
};

/// The pairs, sorted by first, then second, then shift (S0, S1, S2).
struct NeighbourList {
  NeighbourVector<std::int64_t> first, second;
  NeighbourVector<std::int64_t> shifts;  ///< 3 per pair: S0, S1, S2
  NeighbourVector<double> distances;     ///< sqrt(d2)
  NeighbourVector<double> vectors;       ///< 3 per pair: D (from first to second's image)
  /// CSR: the pairs of first == i are [offsets[i], offsets[i + 1]);
  /// size n + 1 (the queries' count for neighbour_list_between).
  NeighbourVector<std::int64_t> offsets;
  std::size_t size() const { return first.size(); }
};

/// Points read in place (float64 or float32, any stride).
struct NeighbourPoints {
  arrays::Column x, y, z;
  std::size_t count = 0;
  /// `n` rows of three packed values (x, y, z).
  template <class T>
  static NeighbourPoints rows(const T* xyz, std::size_t n) {
    return {arrays::Column::of(xyz, 3), arrays::Column::of(xyz + 1, 3),
            arrays::Column::of(xyz + 2, 3), n};
  }
};

/// Input the functions refuse (a message naming what and where).
class InvalidNeighbourInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// The pairs within one `cutoff` (finite, >= 0). Throws
/// InvalidNeighbourInput for a position or cutoff that is not finite, a
/// negative cutoff, periodic vectors that are not finite or are linearly
/// dependent, a point more than 2^28 cells away, a cutoff that reaches more
/// than 2^20 cells, more than 2^32 - 1 points.
NeighbourList neighbour_list(const NeighbourPoints& points, const NeighbourCell& cell,
                             double cutoff, const NeighbourOptions& options = {});

/// The pairs with per-point cutoffs `cutoffs` (one per point, finite, >= 0):
/// i, j neighbours when |D| <= c_i + c_j (`<` when strict).
NeighbourList neighbour_list(const NeighbourPoints& points, const NeighbourCell& cell,
                             arrays::Column cutoffs, const NeighbourOptions& options = {});

/// The pairs (q, p, S) between two sets: point p of `points` moved by S
/// within `cutoff` of query q, the shift on p (D = (x_p + o) - x_q). Every
/// image within the cutoff is reported. `full` and `self_interaction` do not
/// apply; `offsets` is by query.
NeighbourList neighbour_list_between(const NeighbourPoints& queries, const NeighbourPoints& points,
                                     const NeighbourCell& cell, double cutoff,
                                     const NeighbourOptions& options = {});

/// The exact rule's pieces, shared by the engine and the tests' brute force.
namespace neighbour_rule {

/// S·cell, per component (S0*a_k + S1*b_k) + S2*c_k.
inline Vec3 image_offset(const NeighbourCell& cell, std::int64_t s0, std::int64_t s1,
                         std::int64_t s2) {
  const double f0 = static_cast<double>(s0), f1 = static_cast<double>(s1),
               f2 = static_cast<double>(s2);
  const Vec3& a = cell.vectors[0];
  const Vec3& b = cell.vectors[1];
  const Vec3& c = cell.vectors[2];
  return {(f0 * a.x + f1 * b.x) + f2 * c.x, (f0 * a.y + f1 * b.y) + f2 * c.y,
          (f0 * a.z + f1 * b.z) + f2 * c.z};
}

/// D = (x_j + o) - x_i, per component.
inline Vec3 pair_vector(Vec3 xi, Vec3 xj, Vec3 o) {
  return {(xj.x + o.x) - xi.x, (xj.y + o.y) - xi.y, (xj.z + o.z) - xi.z};
}

/// (Dx*Dx + Dy*Dy) + Dz*Dz.
inline double squared_length(Vec3 d) { return d.x * d.x + d.y * d.y + d.z * d.z; }

/// d2 against the reach s (one cutoff, or c_i + c_j).
inline bool within(double d2, double s, CutoffRule rule) {
  const double s2 = s * s;
  return rule == CutoffRule::strict ? d2 < s2 : d2 <= s2;
}

/// True when a self-image shift is the kept one of S and -S: its first
/// non-zero component is positive.
inline bool kept_self_shift(std::int64_t s0, std::int64_t s1, std::int64_t s2) {
  return s0 > 0 || (s0 == 0 && (s1 > 0 || (s1 == 0 && s2 > 0)));
}

}  // namespace neighbour_rule

}  // namespace broadphase
