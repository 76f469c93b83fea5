/// \file moving_neighbours.hpp
/// A neighbour list reused over the frames of a moving system, as molecular
/// dynamics codes keep a Verlet list with a skin: `update(points)` returns,
/// on every frame, exactly what `neighbour_list` (neighbours.hpp) returns for
/// those points (the same pairs, shifts, distances, vectors and order), but
/// finds the candidates again only when an atom has moved farther than the
/// skin allows; otherwise it re-evaluates the kept candidates with the exact
/// rule of neighbours.hpp.
///
/// The candidates are the pairs (i, j, S) within cutoff + skin (per-point
/// cutoffs: c_i + skin/2 each) of the positions of the last rebuild x_ref.
/// Each frame, every point gets the whole number of cells m_i that brings
/// it back next to its reference position (the cell vectors of the periodic
/// axes), and its displacement u_i = (x_i + m_i·cell) - x_ref,i. When every
/// |u_i| is at most skin/2 (less a rounding margin, see the source), a pair
/// (i, j, S') within the cutoff now is the candidate (i, j, S) with
/// S = S' - m_j + m_i, so the candidates hold every pair: atoms that cross a
/// periodic face, or are given outside the cell, get their shifts from m.
/// Else the list is rebuilt from the current points.
///
/// Cost: a frame without a rebuild is one pass over the points and one over
/// the candidates (about (1 + skin/cutoff)^3 times the pairs); a rebuild is
/// one `neighbour_list` call at cutoff + skin.
///
/// Memory: 32 bytes a candidate (16 kept, 16 of the evaluation's scratch;
/// a full list has twice the half list's candidates), 24 more with
/// distances or vectors; 64 bytes a point (reference and current positions,
/// wrap counts, the start of its candidates), 16 more with per-point
/// cutoffs. `memory_bytes()` tells. The returned lists are the caller's.
///
/// Thread-safety: `update` changes the object: one thread at a time. The
/// const members may run concurrently with each other. Inside, `update`
/// runs on the options' `threads` (one by default); the list does not
/// depend on how many.
#pragma once

#include <array>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/neighbours.hpp>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace broadphase {

/// A neighbour list with a skin over the frames of one system: the cell,
/// cutoffs and options fixed at construction, the points given to each
/// `update`.
class MovingNeighbourList {
 public:
  /// The skin a list takes unless told, as a fraction of the largest reach
  /// (the cutoff, or twice the largest per-point cutoff). Measured on
  /// thermal-like motion of 10^4 to 10^6 points at liquid density, 3 Å
  /// cutoff, 0.024 Å a frame (python/bench/neighbours.py --moving): skins
  /// of 0.1, 0.15, 0.2 and 0.3 of the cutoff took 1.3, 1.4, 1.3 and 1.0
  /// times the 0.3 skin's time a frame at 10^5 points (rebuilds every 2.4 to
  /// 6.7 frames: the fastest point of 10^5 moves three times the mean step),
  /// and the 0.3 skin was the fastest at 10^4 and 10^6 too
  /// (docs/neighbours.md, "Moving systems").
  static constexpr double kDefaultSkinFraction = 0.3;

  /// One cutoff (finite, >= 0) and a skin (finite, >= 0; negative: the
  /// default, kDefaultSkinFraction * cutoff). Throws InvalidNeighbourInput
  /// for a bad cutoff, skin or cell (as `neighbour_list`).
  MovingNeighbourList(const NeighbourCell& cell, double cutoff, double skin = -1,
                      const NeighbourOptions& options = {});

  /// Per-point cutoffs (`count` of them, copied; each finite, >= 0): every
  /// `update` must give `count` points. Skin as above, its default
  /// kDefaultSkinFraction * 2 * max(cutoffs).
  MovingNeighbourList(const NeighbourCell& cell, arrays::Column cutoffs, std::size_t count,
                      double skin = -1, const NeighbourOptions& options = {});

  /// The list of `points` now: exactly `neighbour_list(points, cell,
  /// cutoff(s), options)`. Rebuilds the candidates at the first call, when
  /// the number of points changes (one cutoff; per-point cutoffs refuse
  /// another count) or a point moved more than skin/2 since the last
  /// rebuild. Throws InvalidNeighbourInput as `neighbour_list` does (the
  /// list is then as before the call). O(n + candidates) without a
  /// rebuild.
  NeighbourList update(const NeighbourPoints& points);

  /// The skin in use (length).
  double skin() const { return skin_; }
  /// Rebuilds so far (the first update's build counts).
  std::size_t rebuilds() const { return rebuilds_; }
  /// Candidates kept now.
  std::size_t candidates() const { return second_.size(); }
  /// Bytes held (capacity of the working arrays).
  std::size_t memory_bytes() const;

 private:
  /// A point as the evaluation reads it: its position as given and its
  /// wrap count m relative to the reference (32 bytes, half a cache line).
  struct Point {
    double x, y, z;
    std::int16_t m[3];
    std::int16_t pad;
  };
  /// A candidate's other point and its shift at the reference positions.
  using Candidate = neighbours_detail::Candidate;
  static_assert(sizeof(Point) == 32 && sizeof(Candidate) == 16);

  void init_frame();
  bool read(const NeighbourPoints& points);
  void rebuild(const NeighbourPoints& points);
  NeighbourList evaluate();

  NeighbourCell cell_;
  NeighbourOptions options_;
  double cutoff_ = 0;
  bool per_point_ = false;
  std::vector<double> cutoffs_;        ///< per-point, or empty
  std::vector<double> build_cutoffs_;  ///< c_i + skin/2
  double skin_ = 0;
  double reach_ = 0;                ///< the largest pair reach with the skin
  std::array<Vec3, 27> offsets_{};  ///< image_offset of S in [-1, 1]^3
  std::array<Vec3, 3> inverse_{};   ///< dual columns of the cell (fractional coordinates)
  double spread_sum_ = 0;           ///< sum over periodic k of |col_k| * |v_k|_1
  double cell_sum_ = 0;             ///< sum over periodic k of |v_k|_1
  double reference_max_ = 0;        ///< largest |coordinate| at the rebuild
  bool built_ = false;
  bool wrapped_ = false;  ///< some m != 0 in this frame
  std::size_t rebuilds_ = 0;
  std::vector<Vec3> reference_;
  std::vector<Point> points_;
  NeighbourVector<std::int64_t> start_;  ///< n + 1: point i's candidates
  NeighbourVector<Candidate> second_;
  // Scratch of `evaluate`, kept between frames: every candidate is written
  // to it and the pairs kept by advancing past them (no branch on the
  // rule), then the output is written from it.
  std::vector<Candidate> found_;  ///< the pair's second point and shift now
  std::vector<Vec3> vectors_;     ///< its D, when distances or vectors are asked
};

}  // namespace broadphase
