// Version 3 workloads: filters and rays added to a generated scene, each
// from a random stream of its own so that the objects of a seed stay the
// same with or without them.
#include <algorithm>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace broadphase {

namespace {

// Streams of their own, so that filters and rays never shift the objects.
constexpr std::uint64_t kFilterStream = 0x46494c5445525331ull;  // "FILTERS1"
constexpr std::uint64_t kRayStream = 0x5241595331303030ull;     // "RAYS1000"

constexpr double kPi = 3.141592653589793;

std::uint32_t bit(int b) { return std::uint32_t{1} << b; }

}  // namespace

void add_filters(Scene& scene, FilterKind kind, int layers, std::uint64_t seed) {
  if (kind == FilterKind::layers && (layers < 1 || layers > 32))
    throw std::invalid_argument("the layer count must be 1 to 32, got " + std::to_string(layers));
  Rng rng(splitmix64(seed ^ kFilterStream));
  scene.filters.resize(scene.size());
  for (Filter& f : scene.filters) {
    if (kind == FilterKind::layers) {
      // Each layer pairs with itself and its neighbours: with K >= 4, most
      // pairs of layers ignore each other.
      const int l = static_cast<int>(rng.below(static_cast<std::uint64_t>(layers)));
      f.group = bit(l);
      f.mask = bit(l) | bit((l + 1) % layers) | bit((l + layers - 1) % layers);
    } else {
      // Eight groups, each bit set with probability 1/4 in a group (an
      // empty group pairs with nothing) and 1/2 in a mask; now and then a
      // mask of everything or of nothing.
      f.group = static_cast<std::uint32_t>(rng.next() & rng.next() & 0xff);
      const std::uint64_t u = rng.below(32);
      f.mask = u == 0 ? 0u : u < 3 ? 0xffffffffu : static_cast<std::uint32_t>(rng.next() & 0xff);
    }
  }
}

RayKind parse_ray_kind(std::string_view name) {
  static constexpr RayKind kAll[] = {RayKind::mixed, RayKind::random, RayKind::lidar,
                                     RayKind::axis,  RayKind::inside, RayKind::zero};
  std::string valid;
  for (RayKind k : kAll) {
    if (to_string(k) == name) return k;
    valid += (valid.empty() ? "" : ", ") + std::string(to_string(k));
  }
  throw std::invalid_argument("unknown ray kind '" + std::string(name) + "'; valid: " + valid);
}

std::string_view to_string(RayKind k) {
  switch (k) {
    case RayKind::mixed:
      return "mixed";
    case RayKind::random:
      return "random";
    case RayKind::lidar:
      return "lidar";
    case RayKind::axis:
      return "axis";
    case RayKind::inside:
      return "inside";
    case RayKind::zero:
      return "zero";
  }
  return "?";
}

namespace {

class RayMaker {
 public:
  RayMaker(const Scene& scene, Rng& rng) : scene_(scene), rng_(rng), L_(scene.world) {}

  // A point uniform in the world grown by `spill` of its side on each side.
  Vec3 point(double spill) {
    return {rng_.uniform(-spill * L_, (1 + spill) * L_),
            rng_.uniform(-spill * L_, (1 + spill) * L_),
            rng_.uniform(-spill * L_, (1 + spill) * L_)};
  }

  // Mostly no limit, some 0, the rest up to one and a half worlds along d.
  double tmax(const Vec3& d) {
    const double u = rng_.uniform();
    if (u < 0.55) return std::numeric_limits<double>::infinity();
    if (u < 0.65) return 0;
    const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    return rng_.uniform(0, 1.5 * L_) / (len > 0 ? len : 1);
  }

  Ray random() {
    Ray r;
    r.origin = point(0.2);
    // Not of unit length: 0.01 to 100.
    r.dir = rng_.direction() * std::pow(10.0, rng_.uniform(-2, 2));
    if (rng_.below(8) == 0) r.dir[static_cast<int>(rng_.below(3))] = 0;  // a zero component
    r.tmax = tmax(r.dir);
    return r;
  }

  // Ray `i` of `count` in a fan from `origin`: eight rings of elevation
  // from -15 to +15 degrees, evenly spaced azimuths on each.
  Ray lidar(const Vec3& origin, std::size_t i, std::size_t count) {
    const std::size_t rings = std::min<std::size_t>(8, count);
    const std::size_t per_ring = (count + rings - 1) / rings;
    const double ring = static_cast<double>(i / per_ring);
    const double elevation =
        rings > 1 ? (-15 + 30 * ring / static_cast<double>(rings - 1)) * kPi / 180 : 0;
    const double azimuth =
        2 * kPi * static_cast<double>(i % per_ring) / static_cast<double>(per_ring);
    Ray r;
    r.origin = origin;
    r.dir = {std::cos(elevation) * std::cos(azimuth), std::sin(elevation),
             std::cos(elevation) * std::sin(azimuth)};
    // A sensor's range, or none.
    r.tmax = rng_.below(2) ? std::numeric_limits<double>::infinity() : L_ / 2;
    return r;
  }

  // On the lattice of cells of side L/8 .. L/64: along an axis on a cell
  // face or edge, or along a diagonal through cell corners; or, a third of
  // the time when it picks a box, along the face or edge of that box.
  Ray axis() {
    if (scene_.size() > 0 && rng_.below(3) == 0) {
      const Shape& s = scene_.objects[rng_.below(scene_.size())];
      if (s.kind == ShapeKind::box) return graze(s);
    }
    const double cells = static_cast<double>(8 << rng_.below(4));
    const double side = L_ / cells;
    auto on_lattice = [&] {
      return side * static_cast<double>(rng_.below(static_cast<std::uint64_t>(cells) + 1));
    };
    Ray r;
    r.origin = {on_lattice(), on_lattice(), on_lattice()};
    const double speed = std::ldexp(1.0, static_cast<int>(rng_.below(5)) - 2);  // 1/4 .. 4
    if (rng_.below(3) == 0) {
      for (int a = 0; a < 3; ++a) r.dir[a] = rng_.below(2) ? speed : -speed;
    } else {
      const int a = static_cast<int>(rng_.below(3));
      r.dir[a] = rng_.below(2) ? speed : -speed;
      // From anywhere along its axis, inside the world or before it.
      r.origin[a] = r.dir[a] > 0 ? rng_.uniform(-0.1 * L_, L_) : rng_.uniform(0, 1.1 * L_);
    }
    r.tmax = tmax(r.dir);
    return r;
  }

  // Along axis a, on a face of box `s` (its plane c_b ± h_b computed as
  // the hit test computes it) or on an edge, from before the box.
  Ray graze(const Shape& s) {
    const int a = static_cast<int>(rng_.below(3));
    const int b = (a + 1 + static_cast<int>(rng_.below(2))) % 3;
    const int c = 3 - a - b;
    Ray r;
    r.origin[b] = rng_.below(2) ? s.center[b] + s.half[b] : s.center[b] - s.half[b];
    r.origin[c] =
        rng_.below(2) ? s.center[c] + s.half[c] * rng_.uniform(-1, 1) : s.center[c] - s.half[c];
    r.origin[a] = s.center[a] - s.half[a] - rng_.uniform(0, L_ / 4);
    r.dir[a] = 1;
    r.tmax = tmax(r.dir);
    return r;
  }

  // From inside an object (or on a box's face), in a random direction.
  Ray inside() {
    if (scene_.size() == 0) return random();
    const Shape& s = scene_.objects[rng_.below(scene_.size())];
    Ray r;
    if (s.kind == ShapeKind::sphere) {
      r.origin = s.center + rng_.direction() * (s.half.x * rng_.uniform());
    } else {
      for (int a = 0; a < 3; ++a) r.origin[a] = s.center[a] + s.half[a] * rng_.uniform(-1, 1);
      if (rng_.below(4) == 0) {
        const int a = static_cast<int>(rng_.below(3));
        r.origin[a] = s.center[a] + s.half[a];  // on a face
      }
    }
    r.dir = rng_.direction();
    r.tmax = tmax(r.dir);
    return r;
  }

  // Direction 0: the ray is its origin, at an object's centre or anywhere.
  Ray zero() {
    Ray r;
    r.origin = scene_.size() > 0 && rng_.below(2) ? scene_.objects[rng_.below(scene_.size())].center
                                                  : point(0);
    r.tmax = rng_.below(2) ? std::numeric_limits<double>::infinity() : 0;
    return r;
  }

 private:
  const Scene& scene_;
  Rng& rng_;
  double L_;
};

}  // namespace

void add_rays(Scene& scene, std::size_t n, RayKind kind, std::uint64_t seed) {
  Rng rng(splitmix64(seed ^ kRayStream));
  RayMaker make(scene, rng);
  // The kind of each ray first, so that a mixed set knows its fan's size.
  std::vector<RayKind> kinds(n, kind);
  if (kind == RayKind::mixed)
    for (RayKind& k : kinds) {
      const double u = rng.uniform();
      k = u < 0.35   ? RayKind::random
          : u < 0.6  ? RayKind::lidar
          : u < 0.8  ? RayKind::axis
          : u < 0.95 ? RayKind::inside
                     : RayKind::zero;
    }
  std::size_t fan = 0;
  for (RayKind k : kinds) fan += k == RayKind::lidar;
  const double L = scene.world;
  const Vec3 sensor{rng.uniform(L / 3, 2 * L / 3), rng.uniform(L / 3, 2 * L / 3),
                    rng.uniform(L / 3, 2 * L / 3)};
  const bool filtered = scene.has_filters();
  std::size_t fan_index = 0;
  scene.rays.reserve(scene.rays.size() + n);
  for (RayKind k : kinds) {
    Ray r;
    switch (k) {
      case RayKind::lidar:
        r = make.lidar(sensor, fan_index++, fan);
        break;
      case RayKind::axis:
        r = make.axis();
        break;
      case RayKind::inside:
        r = make.inside();
        break;
      case RayKind::zero:
        r = make.zero();
        break;
      default:
        r = make.random();
    }
    // A quarter see only the groups of one object, or a few random groups.
    if (filtered && rng.below(4) == 0)
      r.mask = rng.below(2) ? scene.filters[rng.below(scene.size())].group | 1u
                            : static_cast<std::uint32_t>(rng.next() & 0xff);
    scene.rays.push_back(r);
  }
}

}  // namespace broadphase
