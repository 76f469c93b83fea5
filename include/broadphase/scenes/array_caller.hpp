/// \file array_caller.hpp
/// A scene held the way a caller of the lean path (arrays.hpp) holds its
/// objects: columns of doubles it owns (struct of arrays), moved in place
/// by the scene's motion. Shared by `broadphase run --arrays`, the lab's
/// performance experiment and the lean path's benchmark, so that all three
/// measure the same caller.
#pragma once

#include <array>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace broadphase {

/// The caller's arrays of one scene. Spheres only: x, y, z and a radius
/// column (32 bytes per object). With boxes: x, y, z, three half-extent
/// columns (a sphere's radius is its half_x) and a kind byte (57 bytes per
/// object). With filters (version 3), a group and a mask column too (8
/// bytes more per object). The velocities are the caller's too, but the
/// lean path never reads them, so `bytes()` leaves them out.
class ArrayCaller {
 public:
  explicit ArrayCaller(const Scene& scene);

  /// A view of the arrays as they are now (valid while this lives).
  Objects objects() const;
  /// The indices of the objects that move (a frame changes only these).
  const std::vector<std::uint32_t>& movers() const { return movers_; }
  /// Moves every mover by one frame, exactly as `step(Scene&)` does
  /// (wrapping on the periodic axes of a periodic scene).
  /// Returns the first mover whose centre is no longer finite (its motion
  /// overflowed a double), or SIZE_MAX.
  std::size_t step();
  /// Bytes of the columns the lean path reads (centres, sizes, kinds,
  /// filters).
  std::size_t bytes() const;
  std::size_t size() const { return x_.size(); }

 private:
  double world_ = 0;
  bool boxes_ = false;
  std::array<bool, 3> periodic_{false, false, false};
  std::vector<double> x_, y_, z_, hx_, hy_, hz_, vx_, vy_, vz_;
  std::vector<std::uint8_t> kind_;
  std::vector<std::uint32_t> groups_, masks_;  // empty without filters
  std::vector<std::uint32_t> movers_;
};

}  // namespace broadphase
