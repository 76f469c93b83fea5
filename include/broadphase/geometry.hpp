/// \file geometry.hpp
/// The shared vocabulary: 3-vectors of double, the two shapes a broad phase
/// bounds (spheres and axis-aligned boxes), conservative bounding boxes, and
/// the exact overlap predicates of the scene contract.
///
/// Exactness: the predicates are evaluated in double exactly as written in
/// docs/scene-format.md, left to right, with no fused multiply-add. The library
/// target compiles with `-ffp-contract=off` and passes that flag on to its
/// users, because these functions are inline and so are compiled in the
/// user's translation units too.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace broadphase {

/// A point or vector in world space, in double precision.
struct Vec3 {
  double x = 0, y = 0, z = 0;

  constexpr double operator[](int axis) const { return axis == 0 ? x : (axis == 1 ? y : z); }
  constexpr double& operator[](int axis) { return axis == 0 ? x : (axis == 1 ? y : z); }
  friend constexpr bool operator==(const Vec3&, const Vec3&) = default;
  friend constexpr Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
  friend constexpr Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
  friend constexpr Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
};

/// An axis-aligned box [lo, hi] in double. Empty when any lo > hi.
struct Aabb {
  Vec3 lo, hi;

  /// True when the closed boxes share at least one point.
  constexpr bool overlaps(const Aabb& o) const {
    return lo.x <= o.hi.x && o.lo.x <= hi.x && lo.y <= o.hi.y && o.lo.y <= hi.y && lo.z <= o.hi.z &&
           o.lo.z <= hi.z;
  }
  /// True when `o` lies inside this closed box.
  constexpr bool contains(const Aabb& o) const {
    return lo.x <= o.lo.x && o.hi.x <= hi.x && lo.y <= o.lo.y && o.hi.y <= hi.y && lo.z <= o.lo.z &&
           o.hi.z <= hi.z;
  }
  constexpr Aabb merged(const Aabb& o) const {
    return {{std::min(lo.x, o.lo.x), std::min(lo.y, o.lo.y), std::min(lo.z, o.lo.z)},
            {std::max(hi.x, o.hi.x), std::max(hi.y, o.hi.y), std::max(hi.z, o.hi.z)}};
  }
  friend constexpr bool operator==(const Aabb&, const Aabb&) = default;
};

/// An axis-aligned box in float, used by structures that store bounds
/// compactly. Built only by rounding a double box outwards, so it always
/// contains the double box it came from.
struct AabbF {
  float lo[3];
  float hi[3];

  bool overlaps(const AabbF& o) const {
    return lo[0] <= o.hi[0] && o.lo[0] <= hi[0] && lo[1] <= o.hi[1] && o.lo[1] <= hi[1] &&
           lo[2] <= o.hi[2] && o.lo[2] <= hi[2];
  }
  /// The same as `overlaps`, evaluated without short-circuit (no branch).
  bool overlaps_flat(const AabbF& o) const {
    return (lo[0] <= o.hi[0]) & (o.lo[0] <= hi[0]) & (lo[1] <= o.hi[1]) & (o.lo[1] <= hi[1]) &
           (lo[2] <= o.hi[2]) & (o.lo[2] <= hi[2]);
  }
  /// True when `o` lies inside this box (faces may touch).
  bool contains(const AabbF& o) const {
    return lo[0] <= o.lo[0] && lo[1] <= o.lo[1] && lo[2] <= o.lo[2] && o.hi[0] <= hi[0] &&
           o.hi[1] <= hi[1] && o.hi[2] <= hi[2];
  }
};

/// The two kinds of object bounds the contract knows.
enum class ShapeKind : std::uint8_t { sphere, box };

/// A sphere (centre, radius) or an axis-aligned box (centre, half-extents).
/// For a sphere all three `half` components equal the radius, so code that
/// only needs a box around the shape can read `half` for both kinds.
struct Shape {
  Vec3 center;
  Vec3 half;
  ShapeKind kind = ShapeKind::sphere;

  static constexpr Shape sphere(Vec3 c, double r) { return {c, {r, r, r}, ShapeKind::sphere}; }
  static constexpr Shape box(Vec3 c, Vec3 h) { return {c, h, ShapeKind::box}; }
  constexpr double radius() const { return half.x; }
  constexpr bool is_sphere() const { return kind == ShapeKind::sphere; }
  /// Largest half-extent: the radius of a sphere, the widest half side of a box.
  constexpr double max_half() const { return std::max(half.x, std::max(half.y, half.z)); }
  friend constexpr bool operator==(const Shape&, const Shape&) = default;
};

/// True when every number of the shape is finite and no extent is negative.
inline bool is_valid(const Shape& s) {
  const Vec3& c = s.center;
  const Vec3& h = s.half;
  return std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z) && std::isfinite(h.x) &&
         std::isfinite(h.y) && std::isfinite(h.z) && h.x >= 0 && h.y >= 0 && h.z >= 0 &&
         (s.kind == ShapeKind::box || (h.x == h.y && h.y == h.z));
}

/// Sphere–sphere overlap, exactly as docs/scene-format.md writes it.
inline bool spheres_overlap(const Vec3& ci, double ri, const Vec3& cj, double rj) {
  const double dx = ci.x - cj.x;
  const double dy = ci.y - cj.y;
  const double dz = ci.z - cj.z;
  const double d2 = dx * dx + dy * dy + dz * dz;
  const double s = ri + rj;
  return d2 <= s * s;
}

/// Box–box overlap, exactly as docs/scene-format.md writes it.
inline bool boxes_overlap(const Vec3& ci, const Vec3& hi, const Vec3& cj, const Vec3& hj) {
  return std::fabs(ci.x - cj.x) <= hi.x + hj.x && std::fabs(ci.y - cj.y) <= hi.y + hj.y &&
         std::fabs(ci.z - cj.z) <= hi.z + hj.z;
}

/// Sphere–box overlap, exactly as docs/scene-format.md writes it.
inline bool sphere_box_overlap(const Vec3& cs, double r, const Vec3& cb, const Vec3& hb) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double e = std::fabs(cs[a] - cb[a]) - hb[a];
    d2 += (e > 0 ? e * e : 0);
  }
  return d2 <= r * r;
}

/// The exact narrow phase: true when the two objects overlap (touching
/// counts). Symmetric in its arguments, so the order of a pair never matters.
inline bool overlaps(const Shape& a, const Shape& b) {
  if (a.kind == ShapeKind::sphere) {
    if (b.kind == ShapeKind::sphere) return spheres_overlap(a.center, a.half.x, b.center, b.half.x);
    return sphere_box_overlap(a.center, a.half.x, b.center, b.half);
  }
  if (b.kind == ShapeKind::sphere) return sphere_box_overlap(b.center, b.half.x, a.center, a.half);
  return boxes_overlap(a.center, a.half, b.center, b.half);
}

/// An object's collision filter (docs/scene-format.md, "Filters"): its
/// group bits and the groups it may pair with. The defaults pair everything.
struct Filter {
  std::uint32_t group = 1;
  std::uint32_t mask = 0xffffffffu;
  friend constexpr bool operator==(const Filter&, const Filter&) = default;
};

/// The contract's filter rule: two objects may form a pair only when each
/// one's group shares a bit with the other's mask (Bullet's group/mask,
/// Box2D's category/mask). Symmetric.
constexpr bool filters_pass(Filter a, Filter b) {
  return (a.group & b.mask) != 0 && (b.group & a.mask) != 0;
}

/// Relative slack added around every conservative box. The predicates round
/// at most a few ulps (2^-52 relative) of |centre| + extent away from exact
/// arithmetic; 2^-40 of that covers them with a wide margin, so whenever
/// `overlaps(a, b)` holds, `bounds(a).overlaps(bounds(b))` holds too.
inline constexpr double kBoundsSlack = 0x1p-40;

/// Absolute slack added around every conservative box. Squares below the
/// smallest normal double lose absolute precision (down to 2^-1074), so the
/// sphere predicates can hold for objects up to about 2^-537 apart whatever
/// their radii (d² and s² both round to zero, and 0 <= 0); 2^-520 covers
/// that, and is lost in the relative slack of any object not within 1e-140
/// of the origin.
inline constexpr double kBoundsFloor = 0x1p-520;

/// Half-extents at or above these make the contract's arithmetic overflow
/// to infinity, where `inf <= inf` counts as an overlap: a sphere of radius
/// ≥ 2^511 can overlap a partner of radius ≥ 2^511 at any distance (their
/// (ri + rj)² is +inf), and a box half side ≥ 2^1022 can overlap another as
/// large on that axis at any distance (hi + hj is +inf).
inline constexpr double kHugeRadius = 0x1p511;
inline constexpr double kHugeHalf = 0x1p1022;

/// A conservative double box around the shape: whenever `overlaps(a, b)`
/// is true, `bounds(a)` and `bounds(b)` overlap. Never tighter than the
/// exact box; at most a relative 2^-40 and an absolute 2^-520 larger (see
/// kBoundsFloor), except that shapes so large that the predicate overflows
/// (see kHugeRadius) get infinite extents.
inline Aabb bounds(const Shape& s) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const bool huge_sphere = s.kind == ShapeKind::sphere && s.half.x >= kHugeRadius;
  Aabb b;
  for (int a = 0; a < 3; ++a) {
    const double c = s.center[a];
    const double h = s.half[a];
    if (huge_sphere || h >= kHugeHalf) {
      b.lo[a] = -kInf;
      b.hi[a] = kInf;
      continue;
    }
    const double m = (std::fabs(c) + h) * kBoundsSlack + kBoundsFloor;
    b.lo[a] = c - h - m;
    b.hi[a] = c + h + m;
  }
  return b;
}

/// The largest float not above `x` (−∞ below the float range). Without a
/// branch on the rounding direction, which is a coin toss per coordinate.
inline float round_down(double x) {
  constexpr double kMax = std::numeric_limits<float>::max();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  if (x < -kMax) return -kInf;
  if (x > kMax) return x == static_cast<double>(kInf) ? kInf : static_cast<float>(kMax);
  const float f = static_cast<float>(x);
  // One step of the bit pattern towards −∞ (from either zero to −denorm).
  const std::uint32_t bits = f == 0 ? 0x80000000u : std::bit_cast<std::uint32_t>(f);
  const float below = std::bit_cast<float>(bits + (f > 0 ? 0xFFFFFFFFu : 1u));
  return static_cast<double>(f) > x ? below : f;
}
/// The smallest float not below `x` (+∞ above the float range).
inline float round_up(double x) {
  constexpr double kMax = std::numeric_limits<float>::max();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  if (x > kMax) return kInf;
  if (x < -kMax) return x == -static_cast<double>(kInf) ? -kInf : -static_cast<float>(kMax);
  const float f = static_cast<float>(x);
  const std::uint32_t bits = f == 0 ? 0u : std::bit_cast<std::uint32_t>(f);
  const float above = std::bit_cast<float>(bits + (f < 0 ? 0xFFFFFFFFu : 1u));
  return static_cast<double>(f) < x ? above : f;
}
/// `bounds(s)` rounded outwards to float: as conservative as `bounds`.
inline AabbF bounds_f(const Shape& s) {
  const Aabb b = bounds(s);
  return {{round_down(b.lo.x), round_down(b.lo.y), round_down(b.lo.z)},
          {round_up(b.hi.x), round_up(b.hi.y), round_up(b.hi.z)}};
}

}  // namespace broadphase
