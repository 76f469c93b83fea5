// The ray tests' shared random source: scenes of the kinds that hurt walks
// (far from the origin, huge and tiny objects, objects on cell faces and
// corners, on hierarchical cells, strung along an axis) and rays of every
// kind the contract names. Used by test_rays.cpp (every structure) and
// test_arrays_rays.cpp (the lean path), each keeping its objects its own way.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/ray.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>

namespace broadphase::ray_testing {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The hits of a ray: (object index, bits of t).
using HitSet = std::set<std::pair<std::uint32_t, std::uint64_t>>;

// The kinds of scene the rays are cast into. `levels`: objects of sizes
// from 2^-3 to 2^6 centred on multiples of eight times their size (the
// faces and corners of hierarchical grids' cells and blocks), rays from
// such points along axes and diagonals. `line`: objects strung along x
// (sweep-and-prune then walks y or z, or x for rays across the line).
enum class Kind { spheres, boxes, mixed, far, huge_and_tiny, lattice, levels, line };

inline const char* kind_name(Kind k) {
  static const char* const kNames[] = {"spheres",       "boxes",   "mixed",  "far",
                                       "huge_and_tiny", "lattice", "levels", "line"};
  return kNames[static_cast<int>(k)];
}

inline double length(const Vec3& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }

inline std::string describe(const Ray& r, std::size_t objects) {
  char buf[400];
  std::snprintf(buf, sizeof buf, "ray o=(%a, %a, %a) d=(%a, %a, %a) tmax=%a mask=%x objects=%zu",
                r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmax, r.mask,
                objects);
  return buf;
}

class RandomRays {
 public:
  RandomRays(Kind kind, std::uint64_t seed) : kind_(kind), rng_(seed) {
    if (kind == Kind::far) base_ = 1e15;
  }

  double u(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  std::uint64_t bits() { return rng_(); }
  bool coin(double p = 0.5) { return u(0, 1) < p; }
  Kind kind() const { return kind_; }
  double base() const { return base_; }
  double scale() const { return scale_; }

  // A coordinate: uniform, or on a "round" value where cell faces of
  // power-of-two grids and octree midplanes fall.
  double coord() {
    if (kind_ == Kind::levels) {
      const double step = std::ldexp(8.0, static_cast<int>(bits() % 10) - 3);
      return base_ + step * std::floor(u(-0.1, 1.1) * scale_ / step);
    }
    if (kind_ == Kind::lattice || coin(0.2))
      return base_ + scale_ * static_cast<double>(bits() % 17) / 16.0;
    return base_ + u(-0.1, 1.1) * scale_;
  }

  // A new random object of the scene's kind.
  Shape shape() {
    Vec3 c{coord(), coord(), coord()};
    if (kind_ == Kind::line) c.y = c.z = base_ + scale_ * u(0.49, 0.51);
    if (kind_ == Kind::levels) {
      // The size of a level, the centre on a multiple of eight of them.
      const int level = static_cast<int>(bits() % 10) - 3;
      const double step = std::ldexp(8.0, level);
      for (int a = 0; a < 3; ++a) c[a] = base_ + step * std::floor(u(-0.1, 1.1) * scale_ / step);
      const double half = std::ldexp(coin() ? 0.5 : u(0.2, 0.5), level);
      if (coin()) return Shape::box(c, {half, half * u(0.5, 1), half});
      return Shape::sphere(c, half);
    }
    const bool box =
        kind_ == Kind::boxes || ((kind_ != Kind::spheres && kind_ != Kind::lattice) && coin());
    double size = scale_ * std::exp(u(std::log(1e-3), std::log(5e-2)));
    if (kind_ == Kind::lattice) size = scale_ / 32;
    if (kind_ == Kind::huge_and_tiny) {
      const double p = u(0, 1);
      if (p < 0.1)
        size = scale_ * u(0.5, 3);  // larger than many cells, or the world
      else if (p < 0.3)
        size = scale_ * 1e-9;
      else if (p < 0.35)
        size = 0;
    }
    if (box) return Shape::box(c, {size * u(0.2, 1), size * u(0.2, 1), size * u(0.2, 1)});
    return Shape::sphere(c, size);
  }

  // A group of one bit among four (or the default), a full mask.
  Filter filter() {
    if (coin(0.7)) return Filter{};
    return Filter{static_cast<std::uint32_t>(1u << (bits() % 4)), 0xffffffffu};
  }

  // A ray of one of the contract's kinds into `count` objects, object(i)
  // giving the shape of the i-th: starting inside an object (t = 0),
  // outside the world or never entering it, along a cell face (zero
  // components), all-zero or tiny direction, at an object or through its
  // corner, along diagonals (levels) or across the line, tmax 0, infinite
  // or finite, a mask, and a hit exactly at tmax.
  template <class ObjectAt>
  Ray ray(std::size_t count, ObjectAt&& object) {
    Ray r;
    const int kind = static_cast<int>(bits() % 11);
    r.origin = {coord(), coord(), coord()};
    if (kind == 0 && count > 0) r.origin = object(bits() % count).center;  // inside: t = 0
    if (kind == 1) r.origin = {base_ - scale_ * 2, coord(), coord()};      // outside the world
    for (int a = 0; a < 3; ++a) r.dir[a] = u(-1, 1);
    if (kind == 2 || kind == 3) {  // along a cell face: zero components
      r.dir = {0, 0, 0};
      r.dir[static_cast<int>(bits() % 3)] = coin() ? 1 : -1;
      if (kind == 3) r.dir[static_cast<int>(bits() % 3)] = coin() ? 0.5 : -0.5;
    }
    if (kind == 4) r.dir = {0, 0, 0};
    if (kind == 5 && count > 0) {  // at an object, through a corner
      const Shape s = object(bits() % count);
      r.dir = (coin() ? s.center : s.center + s.half) - r.origin;
    }
    if (kind == 6) r.dir = r.dir * 1e-150;  // tiny, still a valid length
    if (kind == 7) {                        // never entering the world
      r.origin = {base_ - scale_ * 3, base_ - scale_ * 3, base_ - scale_ * 3};
      if (coin()) r.dir = {-1, u(-1, 1), u(-1, 1)};
    }
    if (kind_ == Kind::levels && (kind == 8 || kind == 9)) {  // along a diagonal, through corners
      for (int a = 0; a < 3; ++a) r.dir[a] = static_cast<double>(bits() % 3) - 1;
      if (r.dir == Vec3{0, 0, 0}) r.dir = {1, 1, 1};
    }
    if (kind_ == Kind::line && (kind == 8 || kind == 9))
      r.origin.y = r.origin.z = base_ + scale_ * u(0.49, 0.51);
    const double p = u(0, 1);
    r.tmax = p < 0.4 ? kInf : p < 0.5 ? 0.0 : u(0, 2) * scale_ / std::max(1e-300, length(r.dir));
    if (!std::isfinite(r.tmax)) r.tmax = kInf;
    if (coin(0.25)) r.mask = static_cast<std::uint32_t>(bits() % 16);
    if (ray_problem(r) != "") r.dir = {1, 0, 0};
    if (kind == 10 && count > 0) {  // a hit exactly at tmax
      const Shape s = object(bits() % count);
      r.dir = s.center - r.origin;
      if (ray_problem(r) != "") r.dir = {1, 0, 0};
      double t;
      if (ray_hit(r.origin, r.dir, kInf, s, t)) r.tmax = t;
    }
    return r;
  }

 private:
  Kind kind_;
  std::mt19937_64 rng_;
  double base_ = 0;
  double scale_ = 1000;
};

}  // namespace broadphase::ray_testing
