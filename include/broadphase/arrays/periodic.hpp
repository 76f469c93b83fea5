/// \file periodic.hpp
/// The lean path in a periodic world: overlapping pairs over the caller's
/// arrays in an orthorhombic cell that wraps on some of its axes, natively
/// (its cells wrap; no image of any object is made).
///
/// The cell is `PeriodicCell` (broadphase/periodic.hpp): a length L_a per
/// axis and whether axis a is periodic (a slab: x and y; a tube: x; bulk:
/// all three); the lengths of the other axes are not read. A pair is a
/// triple (i, j, S), i < j, S with components in {-1, 0, 1} (0 on the axes
/// that are not periodic), reported exactly when `overlaps()` of
/// geometry.hpp holds for object i as it lies and object j with its centre
/// moved to c_j + S_a·L_a on each axis, computed in double: the contract's
/// periodic pairs (docs/scene-format.md, "Periodic worlds"). One i, j may
/// pair under several shifts (near half the cell); each is reported once.
///
/// On a periodic axis every centre must lie in [0, L_a] and every radius and
/// half-extent be below L_a / 2 (InvalidObjects names the first object
/// that breaks it). Filters, float columns, strides and kinds as in
/// arrays.hpp.
///
/// Order: the pairs of one call come in an order that depends only on the
/// objects (never on the thread count: these calls run on the calling
/// thread); a pair's shifts in increasing `Shift::code()`. The tracker's are
/// sorted by (i, j, code) on every call; the one-shot call's with
/// `ArrayOptions::sorted`.
#pragma once

#include <broadphase/arrays/arrays.hpp>
#include <broadphase/periodic.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace broadphase::arrays {

/// A periodic pair of the caller's objects: i as it lies overlaps j moved
/// by `shift`·L; i < j.
struct ShiftedPair {
  std::uint32_t i, j;
  Shift shift;
  friend constexpr bool operator==(const ShiftedPair&, const ShiftedPair&) = default;
};

/// Where periodic pairs go: chunks valid only during the call; return false
/// to stop early.
using ShiftedPairSink = std::function<bool(std::span<const ShiftedPair>)>;

/// Checks the cell (a periodic axis's length finite and positive) and, on
/// top of `check_objects`, every object against it: on a periodic axis a
/// centre in [0, L_a], a radius or half-extent below L_a / 2. Throws
/// InvalidObjects naming the first bad object, e.g. `objects[7]: x (1001)
/// is outside [0, L] = [0, 1000] on the periodic axis x`.
void check_periodic(const Objects& objects, const PeriodicCell& cell, const char* what = "objects");

/// Every periodic pair of one set, streamed to `sink`. A multi-level grid
/// whose cells wrap on the periodic axes, built for the call (about 70
/// bytes an object, released before it returns): each object sits once, in
/// the cell of its centre on the level whose cells are as wide as it, and
/// meets the objects of its own and the neighbouring cells on its level and
/// every coarser one, across the faces on the periodic axes.
ArrayCallStats find_pairs(const Objects& objects, const PeriodicCell& cell,
                          const ShiftedPairSink& sink, const ArrayOptions& options = {});
/// The same, appended to `out`.
ArrayCallStats find_pairs(const Objects& objects, const PeriodicCell& cell,
                          std::vector<ShiftedPair>& out, const ArrayOptions& options = {});

/// Periodic pairs of one set frame after frame, as MD codes keep neighbour
/// lists: the candidate pairs within a skin of each other (across the faces
/// too) are kept between calls, and each call tests only the candidates
/// with an object listed as changed (the others keep their last answer).
/// Objects that cross a face wrap (the caller moves them back into
/// [0, L_a]); a move is measured the short way round. Each object may
/// move by its allowance from where the candidates were found: half the
/// skin (`ArrayOptions::skin` times the median largest half-extent, by
/// default 0.25), or, for an object that moved before the last rebuild,
/// eight calls of its speed then (at most four times its size plus the
/// median size). When one moves farther, or grows, the candidates are
/// found again (a rebuild).
///
/// Growing and shrinking the count rebuilds. `Changes` as for PairTracker;
/// a call that lists its changes on the same count checks and reads only
/// the listed objects (besides the partners of their candidates).
class PeriodicPairTracker {
 public:
  /// Throws std::invalid_argument for a periodic axis whose length is not
  /// finite and positive, InvalidConfig for bad options.
  explicit PeriodicPairTracker(const PeriodicCell& cell, const ArrayOptions& options = {});
  ~PeriodicPairTracker();
  PeriodicPairTracker(PeriodicPairTracker&&) noexcept;
  PeriodicPairTracker& operator=(PeriodicPairTracker&&) noexcept;

  /// Every periodic pair of `objects` as they are now, sorted by (i, j,
  /// code). Throws InvalidObjects (the tracker is then as before the call).
  ArrayCallStats find_pairs(const Objects& objects, const ShiftedPairSink& sink,
                            const Changes& changes = Changes::everything());
  ArrayCallStats find_pairs(const Objects& objects, std::vector<ShiftedPair>& out,
                            const Changes& changes = Changes::everything());

  const PeriodicCell& cell() const;
  /// The skin of the last rebuild (absolute; 0 before the first call).
  double skin() const;
  /// Bytes kept between calls (the candidates, where they were found).
  std::size_t memory_bytes() const;
  /// Forgets everything; the next call rebuilds.
  void clear();
  /// Checks the invariants against `objects` (the last call's arrays): every
  /// object within its allowance of where it was when the candidates were
  /// found, the candidates sorted and unique, and every kept answer the
  /// exact test's; throws std::logic_error naming the first that fails.
  void validate(const Objects& objects) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace broadphase::arrays

namespace broadphase {
using arrays::check_periodic;
// Again here: a using-declaration names only the overloads declared before it.
using arrays::find_pairs;
using arrays::PeriodicPairTracker;
using arrays::ShiftedPair;
using arrays::ShiftedPairSink;
}  // namespace broadphase
