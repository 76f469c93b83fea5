/// \file rays.hpp
/// Rays over the caller's arrays (the lean path, arrays.hpp): the closest
/// hit, every hit (through a visitor that may clip or stop the cast) or any
/// hit of a ray, and batches of rays on threads. Results are the caller's
/// indices.
///
/// Exact by the contract's ray test (ray.hpp, `ray_hit`): a ray hits object
/// i at t exactly when the contract's double evaluation says so, with the
/// same t, bit for bit; a ray with mask M sees only objects whose group
/// (Objects::groups, 1 without filters) shares a bit with M. The closest
/// hit is the smallest t, then the smallest index.
///
/// The index is the lean path's own multi-level grid (src/arrays/box_grid.hpp)
/// over the objects' float bounds; a ray marches each level's cells with the
/// library's conservative march (detail::RayGridMarch), and the objects too
/// wide for any level are tested on every ray (docs/arrays.md, "Rays").
///
/// Thread safety: a RayCaster's const calls may run concurrently; building
/// one needs it to itself. The objects' arrays must outlive the caster and
/// not change while it is used (build it again after they move).
#pragma once

#include <broadphase/arrays/arrays.hpp>
#include <broadphase/ray.hpp>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <vector>

namespace broadphase::arrays {

/// One hit: the caller's object `index`, hit at parameter `t`.
struct IndexHit {
  static constexpr std::uint32_t kNone = 0xffffffffu;
  std::uint32_t index = kNone;  ///< kNone: the ray hits nothing
  double t = std::numeric_limits<double>::infinity();
  bool hit() const { return index != kNone; }
  friend bool operator==(const IndexHit&, const IndexHit&) = default;
};

/// Every hit of every ray in compressed rows: ray r's hits are
/// `hits[offsets[r]]` to `hits[offsets[r + 1] - 1]`, sorted by t, then by
/// index (the closest hit first).
struct IndexHitRows {
  std::vector<std::size_t> offsets;
  std::vector<IndexHit> hits;
};

/// A ray visitor over indices: called once for each hit, in no particular
/// order, it returns the ray's new tmax as ray.hpp's visitors do: kRayGoOn
/// to go on, a smaller value to clip (hits at exactly it are still
/// reported), kStopRay to end the cast.
using IndexRayVisitor = std::function<double(std::uint32_t index, double t)>;

/// The lean path's index for rays over one set of objects.
class RayCaster {
 public:
  /// Empty: every ray misses.
  RayCaster();
  /// Builds over `objects` (see `build`).
  explicit RayCaster(const Objects& objects);
  ~RayCaster();
  RayCaster(RayCaster&&) noexcept;
  RayCaster& operator=(RayCaster&&) noexcept;

  /// Checks the objects (InvalidObjects, check_objects) and builds the grid
  /// over their bounds: O(n), about 66 bytes an object kept (10^5
  /// spheres). Keeps a view
  /// of `objects` (the caller's arrays, read again by every cast).
  void build(const Objects& objects);

  /// Casts `ray` and calls `visitor` for its hits; returns the number of
  /// exact ray tests made. Throws InvalidRay for an invalid ray.
  std::uint64_t cast(const Ray& ray, const IndexRayVisitor& visitor) const;
  /// The closest hit (smallest t, then smallest index), or none.
  IndexHit closest(const Ray& ray) const;
  /// True when the ray hits some object (stops at the first found).
  bool any(const Ray& ray) const;

  /// Batches: `out[r]` for `rays[r]`. Every ray is checked first (InvalidRay
  /// naming the first bad one) and `out` must be as long as `rays`
  /// (std::invalid_argument). `threads` share the rays in contiguous runs
  /// (1: the calling thread; 0: every core; at most ArrayOptions::kMaxThreads);
  /// the results do not depend on it.
  void closest(std::span<const Ray> rays, std::span<IndexHit> out, unsigned threads = 1) const;
  void any(std::span<const Ray> rays, std::span<std::uint8_t> out, unsigned threads = 1) const;
  /// Every hit of each ray, in rows (IndexHitRows), replacing `out`'s content.
  void all(std::span<const Ray> rays, IndexHitRows& out, unsigned threads = 1) const;

  /// The number of objects it was built over.
  std::size_t size() const;
  /// Bytes held (the grid and the objects' float bounds).
  std::size_t memory_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// One-shot: the closest hit of each ray into `objects` (a RayCaster built
/// for the call, `options.threads` sharing the rays; ArrayOptions::check).
void cast_rays(const Objects& objects, std::span<const Ray> rays, std::span<IndexHit> closest,
               const ArrayOptions& options = {});
/// One-shot: every hit of each ray, in rows.
void cast_rays_all(const Objects& objects, std::span<const Ray> rays, IndexHitRows& out,
                   const ArrayOptions& options = {});

}  // namespace broadphase::arrays
