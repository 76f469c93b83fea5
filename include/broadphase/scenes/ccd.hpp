/// \file lab/ccd.hpp
/// Continuous collision detection for linearly moving spheres: the exact
/// time of first contact within a step, and the swept bounds a broad phase
/// is fed so that it never drops a pair that touches during the step.
///
/// Thread-safety: every function here is pure and may be called from any
/// thread.
#pragma once

#include <broadphase/geometry.hpp>
#include <optional>

namespace broadphase {

/// The first time t in [0, t_max] at which two spheres touch, when their
/// centres' difference is `d + w * t` and their radii sum to `s`; nullopt
/// when they do not touch in that interval or are not approaching.
///
/// Solves |d + w t|² = s² with the cancellation-free form of the quadratic
/// (t = c / (−b + √(b² − a c)), b the half linear coefficient), so a tiny
/// time of impact is not lost to rounding and a = 0 (no relative motion)
/// needs no special case. Spheres that already overlap (|d| ≤ s) give 0
/// when they approach (d·w < 0) and nullopt when they separate, so a
/// contact that was resolved is not reported again. O(1).
std::optional<double> time_of_impact(const Vec3& d, const Vec3& w, double s, double t_max);

/// The box covering a shape moving by `v * t` for t in [0, duration]: the
/// union of the conservative bounds of its start and end shapes, returned
/// as a box shape. Whenever the moving shape touches an object at some
/// time in the interval, the swept box overlaps that object exactly, so a
/// broad phase queried with it finds every candidate. O(1).
Shape swept_shape(const Shape& s, const Vec3& v, double duration);

/// The radius of the smallest sphere around the shape centred at its
/// centre: the radius of a sphere, the half-diagonal of a box. The
/// simulation treats a box as this sphere for response and time of impact.
double bounding_radius(const Shape& s);

}  // namespace broadphase
