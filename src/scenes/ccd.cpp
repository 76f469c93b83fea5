#include <broadphase/scenes/ccd.hpp>
#include <cmath>

namespace broadphase {

std::optional<double> time_of_impact(const Vec3& d, const Vec3& w, double s, double t_max) {
  const double b = d.x * w.x + d.y * w.y + d.z * w.z;  // half the linear coefficient
  const double c = (d.x * d.x + d.y * d.y + d.z * d.z) - s * s;
  if (c <= 0) {
    // Already touching: a contact now if they approach, none if they part
    // (the response made them part; reporting it again would loop).
    if (b < 0 && t_max >= 0) return 0.0;
    return std::nullopt;
  }
  if (b >= 0) return std::nullopt;  // apart and not approaching
  const double a = w.x * w.x + w.y * w.y + w.z * w.z;
  const double disc = b * b - a * c;
  if (disc < 0) return std::nullopt;  // the closest approach stays outside s
  // The smaller root (−b − √disc) / a, rewritten as c / (−b + √disc): −b > 0,
  // so the denominator adds two positive numbers and never cancels.
  const double t = c / (-b + std::sqrt(disc));
  if (!(t <= t_max)) return std::nullopt;
  return t;
}

Shape swept_shape(const Shape& s, const Vec3& v, double duration) {
  Shape end = s;
  end.center = s.center + v * duration;
  const Aabb box = bounds(s).merged(bounds(end));
  const Vec3 center = (box.lo + box.hi) * 0.5;
  Vec3 half = (box.hi - box.lo) * 0.5;
  // The centre and half-widths round by an ulp or two; the bounds already
  // carry a 2^-40 relative slack, so giving back 2^-50 of it keeps the box
  // around both end shapes.
  for (int a = 0; a < 3; ++a) half[a] += (std::fabs(center[a]) + half[a]) * 0x1p-50;
  return Shape::box(center, half);
}

double bounding_radius(const Shape& s) {
  if (s.is_sphere()) return s.radius();
  return std::sqrt(s.half.x * s.half.x + s.half.y * s.half.y + s.half.z * s.half.z);
}

}  // namespace broadphase
