/// \file ray.hpp
/// Rays and their exact hit test (docs/scene-format.md, "Rays"), and the
/// conservative culling every structure's ray walk uses.
///
/// Exactness: `ray_hit` evaluates the contract's ray–sphere and ray–box
/// tests in double exactly as written, with no fused multiply-add, like the
/// overlap predicates in geometry.hpp. A structure's walk must never skip an
/// object for which `ray_hit` reports a hit: it culls with
/// `detail::RayCull`, which is conservative with respect to that evaluation
/// (not to real arithmetic), for the reasons given there.
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace broadphase {

/// A ray: the points origin + t·dir for 0 <= t <= tmax. `dir` need not be
/// of unit length and may be zero (the ray is then its origin alone);
/// `tmax` may be +infinity. The ray sees only objects whose group shares a
/// bit with `mask` (Filter).
struct Ray {
  Vec3 origin;
  Vec3 dir;
  double tmax = std::numeric_limits<double>::infinity();
  std::uint32_t mask = 0xffffffffu;
};

/// One hit: the object and the ray's parameter t at which it is hit.
struct RayHit {
  Handle handle;
  double t = 0;
};

/// Why a ray is refused, or an empty string when it is valid: a NaN or
/// infinite origin or direction component, a direction other than 0 whose
/// squared length is infinite or below the smallest normal double, a NaN
/// or negative tmax (-0 counts as 0).
inline std::string ray_problem(const Ray& r) {
  const Vec3& o = r.origin;
  const Vec3& d = r.dir;
  if (!(std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.z)))
    return "origin is not finite";
  if (!(std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z)))
    return "direction is not finite";
  if (d.x != 0 || d.y != 0 || d.z != 0) {
    const double a = d.x * d.x + d.y * d.y + d.z * d.z;
    if (!std::isfinite(a)) return "direction's squared length overflows";
    if (a < std::numeric_limits<double>::min())
      return "direction's squared length is below the smallest normal double";
  }
  if (std::isnan(r.tmax)) return "tmax is NaN";
  if (r.tmax < 0) return "tmax is negative";
  return {};
}

/// True when the ray may be cast (ray_problem is empty).
inline bool is_valid(const Ray& r) { return ray_problem(r).empty(); }

/// Thrown when a ray is NaN, infinite or has a negative tmax.
class InvalidRay : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Throws InvalidRay unless `is_valid(r)`.
inline void require_valid(const Ray& r) {
  const std::string why = ray_problem(r);
  if (!why.empty()) throw InvalidRay("broadphase: invalid ray: " + why);
}

namespace detail {

/// Throws InvalidRay naming the first invalid ray of `rays`.
inline void require_valid_rays(std::span<const Ray> rays) {
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const std::string why = ray_problem(rays[i]);
    if (!why.empty()) throw InvalidRay("broadphase: invalid ray " + std::to_string(i) + ": " + why);
  }
}

/// A batch of casts' checks: std::invalid_argument unless there is one
/// result per ray (`what` names the call), then require_valid_rays.
inline void require_valid_batch(std::span<const Ray> rays, std::size_t results, const char* what) {
  if (results != rays.size())
    throw std::invalid_argument(std::string("broadphase: ") + what + ": one result per ray");
  require_valid_rays(rays);
}

}  // namespace detail

/// The contract's ray–sphere test: true, with `t`, when the ray (o, d,
/// tmax) hits the sphere (c, r). Exactly as docs/scene-format.md writes it.
inline bool ray_hits_sphere(const Vec3& o, const Vec3& d, double tmax, const Vec3& c, double r,
                            double& t) {
  const double mx = o.x - c.x;
  const double my = o.y - c.y;
  const double mz = o.z - c.z;
  const double c2 = (mx * mx + my * my + mz * mz) - r * r;
  if (c2 <= 0) {
    t = 0;
    return true;
  }
  const double b = mx * d.x + my * d.y + mz * d.z;
  if (!(b < 0)) return false;
  const double a = d.x * d.x + d.y * d.y + d.z * d.z;
  const double f = b / a;
  const double qx = mx - f * d.x;
  const double qy = my - f * d.y;
  const double qz = mz - f * d.z;
  const double h2 = r * r - (qx * qx + qy * qy + qz * qz);
  if (!(h2 >= 0)) return false;
  double s = -f - std::sqrt(h2 / a);
  if (s < 0) s = 0;
  if (!(s <= tmax)) return false;
  t = s;
  return true;
}

namespace detail {

/// The slab loop of the contract's ray–box test, given each axis's box
/// faces relative to the ray's origin (`lo[a]`, `hi[a]`): true, with the
/// entry parameter `t`, when the ray (direction d, up to tmax) meets the box.
/// Both the exact test and the culling (RayCull) run it, so the culling
/// over a larger box is never stricter.
inline bool slab_enter(const double (&lo)[3], const double (&hi)[3], const Vec3& d, double tmax,
                       double& t) {
  double tn = 0;
  double tf = tmax;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (lo[a] > 0 || hi[a] < 0) return false;
      continue;
    }
    double t1 = lo[a] / d[a];
    double t2 = hi[a] / d[a];
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > tn) tn = t1;
    if (t2 < tf) tf = t2;
  }
  if (!(tn <= tf)) return false;
  t = tn;
  return true;
}

}  // namespace detail

/// The contract's ray–box test: true, with `t`, when the ray (o, d, tmax)
/// hits the box (c, h). Exactly as docs/scene-format.md writes it.
inline bool ray_hits_box(const Vec3& o, const Vec3& d, double tmax, const Vec3& c, const Vec3& h,
                         double& t) {
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = (c[a] - h[a]) - o[a];
    hi[a] = (c[a] + h[a]) - o[a];
  }
  return detail::slab_enter(lo, hi, d, tmax, t);
}

/// The exact hit test of the contract for either kind of shape, up to
/// `tmax` (the ray's own or a shorter one). The ray's mask is not applied
/// here: see ray_sees.
inline bool ray_hit(const Vec3& o, const Vec3& d, double tmax, const Shape& s, double& t) {
  return s.kind == ShapeKind::sphere ? ray_hits_sphere(o, d, tmax, s.center, s.half.x, t)
                                     : ray_hits_box(o, d, tmax, s.center, s.half, t);
}
inline bool ray_hit(const Ray& r, const Shape& s, double& t) {
  return ray_hit(r.origin, r.dir, r.tmax, s, t);
}

/// True when a ray with `mask` sees an object of `f`'s group.
constexpr bool ray_sees(std::uint32_t mask, Filter f) { return (f.group & mask) != 0; }

/// True when hit `a` comes before hit `b` by the contract's closest-hit
/// rule: the smaller t, then the smaller object (slot index).
constexpr bool closer(const RayHit& a, const RayHit& b) {
  return a.t < b.t || (a.t == b.t && a.handle.index < b.handle.index);
}

/// The visitor of a closest-hit cast: keeps the closer of each hit and the
/// best so far (`closer`), and clips the ray to the best t.
struct ClosestHit {
  RayHit best{Handle{}, std::numeric_limits<double>::infinity()};
  double operator()(Handle h, double t) {
    if (best.handle.is_null() || closer({h, t}, best)) best = {h, t};
    return best.t;
  }
};

/// Ray visitors take `(Handle h, double t)` for each hit and return the
/// ray's new tmax (a visitor returning void goes on):
///   - kRayGoOn (+infinity, or any value not below the current tmax) to go on;
///   - a smaller value to clip the cast (Box2D's clip): hits beyond it are no
///     longer reported; hits at exactly the new value still are, so that
///     ties can be broken by id;
///   - kStopRay (any negative value) to end the cast (an any-hit query).
/// The order of the hits is unspecified; each hit is reported once.
inline constexpr double kRayGoOn = std::numeric_limits<double>::infinity();
inline constexpr double kStopRay = -1;

/// Calls a ray visitor and returns the ray's tmax after it: `tmax` when the
/// visitor returns void or a value not below it, else its value (negative:
/// stop).
template <class V>
inline double visit_hit(V& v, Handle h, double t, double tmax) {
  if constexpr (std::is_void_v<std::invoke_result_t<V&, Handle, double>>) {
    v(h, t);
    return tmax;
  } else {
    const double r = static_cast<double>(v(h, t));
    return r < tmax ? r : tmax;  // NaN: goes on
  }
}

namespace detail {

/// Conservative ray–box culling for the structures' walks.
///
/// `enter(box, tmax, t)` is true, with the parameter `t` where the ray
/// enters `box` grown by a margin, unless no object whose `bounds()` lies in
/// `box` can be hit by `ray_hit` at a parameter <= tmax; and the `t` it
/// gives is never greater than such a hit's t. So a walk may skip a box it
/// refuses and stop once every box left is entered beyond the closest hit.
///
/// Why the margin: for a box object `ray_hit` is the same slab test, and a
/// slab test over a larger box is never stricter (rounding is monotone), so
/// no margin is needed. For a sphere the evaluation measures the distance
/// from the centre to the ray's line through q = m - f·d, whose rounding
/// error is a few ulps of |m| = |origin - centre| and not of the radius: a
/// sphere far from the origin can be "hit" by a line that misses it by
/// several ulps of that distance. And near a tangent, t = -f - sqrt(h2/a)
/// carries the error of a square root of a rounded h2, about sqrt(2^-52)
/// (1.5e-8) of |m| + r along the ray. The margin, 2^-20 (9.5e-7) of
/// (|origin| + |box|) on each side, covers both more than thirtyfold; it is
/// a micrometre on a kilometre, so it costs no culling worth measuring.
///
/// The reciprocal: `enter` runs the slab loop with the ray's reciprocal
/// direction (1/d per axis, computed once per ray) instead of a division
/// per face: six divisions were two thirds of a box test and a k-d tree's
/// ray visits about two hundred boxes (measured, uniform spheres 10^5).
/// It stays conservative: each face parameter (lo - o)·(1/d) differs from
/// (lo - o)/d by at most two roundings, 2^-52 of |lo - o|/|d| <= (|o| +
/// |box| + m)/|d|, while the margin moves each face by m/|d| >= 2^-20 (|o|
/// + |box|)/|d|: the product is the slab of the box grown by at least m
/// (1 - 2^-30), which keeps the thirtyfold reserve. An axis with d = 0
/// compares the grown faces with the origin as slab_enter does. The
/// reciprocal is used only where no product can overflow or lose its
/// relative precision: every non-zero |d| in [2^-256, 2^256], |o| and the
/// box's coordinates below 2^512 (a product stays below 2^770, and one
/// below the normal range is off by less than 2^-1074, far below the
/// floor's share m/|d| >= 2^-776); any other ray or box takes the division.
class RayCull {
 public:
  explicit RayCull(const Ray& r) : o_(r.origin), d_(r.dir) {
    o_mag_ = std::max(std::fabs(o_.x), std::max(std::fabs(o_.y), std::fabs(o_.z)));
    fast_ = o_mag_ <= kFastMag;
    for (int a = 0; a < 3; ++a) {
      const double ad = std::fabs(d_[a]);
      inv_[a] = 0;
      if (d_[a] == 0) continue;
      if (ad >= 0x1p-256 && ad <= 0x1p256)
        inv_[a] = 1 / d_[a];
      else
        fast_ = false;
    }
  }

  /// The margin added on each side of `box` (see the class comment).
  double margin(const Aabb& box) const { return margin_of(box_mag(box)); }

  /// See the class comment. `tmax` may be the ray's or a clipped one.
  bool enter(const Aabb& box, double tmax, double& t) const {
    const double mag = box_mag(box);
    return enter(box.lo.x, box.lo.y, box.lo.z, box.hi.x, box.hi.y, box.hi.z, mag, tmax, t);
  }
  bool enter(const AabbF& b, double tmax, double& t) const {
    const float mag = std::max(std::max(std::max(std::fabs(b.lo[0]), std::fabs(b.hi[0])),
                                        std::max(std::fabs(b.lo[1]), std::fabs(b.hi[1]))),
                               std::max(std::fabs(b.lo[2]), std::fabs(b.hi[2])));
    return enter(b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2], mag, tmax, t);
  }

  /// The culling of boxes that all lie inside one box (a tree's root box):
  /// see `within`.
  class Within {
   public:
    /// As RayCull::enter, for a box inside the one given to `within`.
    bool enter(const AabbF& b, double tmax, double& t) const {
      if (!fast_) return cull_->enter(b, tmax, t);
      double tn = 0;
      double tf = tmax;
      for (int a = 0; a < 3; ++a) {
        // The lo and hi faces' parameters; the smaller is the near one
        // (see enter2).
        const double p = (static_cast<double>(b.lo[a]) + lo_[a]) * inv_[a];
        const double q = (static_cast<double>(b.hi[a]) + hi_[a]) * inv_[a];
        tn = std::max(tn, q < p ? q : p);
        tf = std::min(tf, q < p ? p : q);
      }
      if (!(tn <= tf)) return false;
      t = tn;
      return true;
    }
    bool enter(const Aabb& b, double tmax, double& t) const { return cull_->enter(b, tmax, t); }
    /// `enter` of two boxes at once: bit 0 of the result for `a` (with
    /// `ta`), bit 1 for `b` (with `tb`); each bit and parameter is the one
    /// `enter` gives. With SSE2 the two boxes share each instruction (two
    /// doubles a register), in the same operations and order as `enter`:
    /// the parameters are bit for bit `enter`'s. Measured on a k-d tree's
    /// walk, where a node's two children and a leaf's items are tested in
    /// pairs: see docs/rays.md.
    unsigned enter2(const AabbF& a, const AabbF& b, double tmax, double& ta, double& tb) const {
#if defined(__SSE2__)
      if (fast_) {
        __m128d tn = _mm_setzero_pd();
        __m128d tf = _mm_set1_pd(tmax);
        for (int k = 0; k < 3; ++k) {
          const __m128d inv = _mm_set1_pd(inv_[k]);
          const __m128d lo = _mm_set_pd(b.lo[k], a.lo[k]);
          const __m128d hi = _mm_set_pd(b.hi[k], a.hi[k]);
          const __m128d p = _mm_mul_pd(_mm_add_pd(lo, _mm_set1_pd(lo_[k])), inv);
          const __m128d q = _mm_mul_pd(_mm_add_pd(hi, _mm_set1_pd(hi_[k])), inv);
          // min(x, y) is x < y ? x : y, max(x, y) x > y ? x : y. With no
          // NaN (the faces are finite or infinite, inv finite and not 0,
          // every rounding monotone) the smaller of the lo and hi faces'
          // parameters is `enter`'s near one, and these are its max and min.
          tn = _mm_max_pd(_mm_min_pd(p, q), tn);
          tf = _mm_min_pd(_mm_max_pd(p, q), tf);
        }
        ta = _mm_cvtsd_f64(tn);
        tb = _mm_cvtsd_f64(_mm_unpackhi_pd(tn, tn));
        return static_cast<unsigned>(_mm_movemask_pd(_mm_cmple_pd(tn, tf)));
      }
#endif
      const unsigned hit_a = enter(a, tmax, ta) ? 1u : 0u;
      return hit_a | (enter(b, tmax, tb) ? 2u : 0u);
    }

   private:
    friend class RayCull;
    const RayCull* cull_ = nullptr;
    bool fast_ = false;
    double inv_[3] = {};
    double lo_[3] = {}, hi_[3] = {};  // the grown faces relative to the origin
  };

  /// A culling for boxes inside `outer` only, as conservative as `enter`
  /// and about three times cheaper (measured on a k-d tree's walk, 100
  /// instructions a box down to 30): one margin, `outer`'s, which is at
  /// least each inner box's own (a larger margin is never stricter), and
  /// the faces relative to the origin and the near face of each axis fixed
  /// once per ray. The grown face (b + (-m - o))·(1/d) rounds three times
  /// where enter's rounds three times too, each by 2^-53 of |b| + |o| + m:
  /// the reserve of the class comment holds. It needs the reciprocal on
  /// every axis (no d = 0) and `outer` within the reciprocal's range;
  /// otherwise it defers to `enter`, as it does for double boxes.
  Within within(const AabbF& outer) const {
    Within w;
    w.cull_ = this;
    const Aabb o{{outer.lo[0], outer.lo[1], outer.lo[2]}, {outer.hi[0], outer.hi[1], outer.hi[2]}};
    const double mag = box_mag(o);
    w.fast_ = fast_ && mag <= kFastMag && inv_[0] != 0 && inv_[1] != 0 && inv_[2] != 0;
    if (!w.fast_) return w;
    const double m = margin_of(mag);
    for (int a = 0; a < 3; ++a) {
      w.inv_[a] = inv_[a];
      w.lo_[a] = -m - o_[a];
      w.hi_[a] = m - o_[a];
    }
    return w;
  }

  const Vec3& origin() const { return o_; }
  const Vec3& dir() const { return d_; }

  static constexpr double kMargin = 0x1p-20;

 private:
  static constexpr double kFastMag = 0x1p512;

  static double box_mag(const Aabb& box) {
    double m = 0;
    for (int a = 0; a < 3; ++a)
      m = std::max(m, std::max(std::fabs(box.lo[a]), std::fabs(box.hi[a])));
    return m;
  }
  double margin_of(double mag) const { return (o_mag_ + mag) * kMargin + kBoundsFloor; }

  bool enter(double lx, double ly, double lz, double hx, double hy, double hz, double mag,
             double tmax, double& t) const {
    const double m = margin_of(mag);
    const double lo[3] = {(lx - m) - o_.x, (ly - m) - o_.y, (lz - m) - o_.z};
    const double hi[3] = {(hx + m) - o_.x, (hy + m) - o_.y, (hz + m) - o_.z};
    if (!(fast_ && mag <= kFastMag)) return slab_enter(lo, hi, d_, tmax, t);
    double tn = 0;
    double tf = tmax;
    for (int a = 0; a < 3; ++a) {
      if (inv_[a] == 0) {
        if (lo[a] > 0 || hi[a] < 0) return false;
        continue;
      }
      // The near face first: no compare of the two products (their NaN,
      // from an infinite box, is ignored by the compares below, as in
      // slab_enter).
      const double t1 = (inv_[a] > 0 ? lo[a] : hi[a]) * inv_[a];
      const double t2 = (inv_[a] > 0 ? hi[a] : lo[a]) * inv_[a];
      if (t1 > tn) tn = t1;
      if (t2 < tf) tf = t2;
    }
    if (!(tn <= tf)) return false;
    t = tn;
    return true;
  }

  Vec3 o_, d_;
  double inv_[3];
  double o_mag_ = 0;
  bool fast_ = false;
};

}  // namespace detail

}  // namespace broadphase
