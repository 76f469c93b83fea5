/// \file lab/scene.hpp
/// Scene files (docs/scene-format.md, versions 1 to 3: spheres, boxes,
/// filters, rays and periodic worlds), the replay motion, the pair and hit
/// hashes, and the workload generators.
#pragma once

#include <array>
#include <broadphase/geometry.hpp>
#include <broadphase/periodic.hpp>
#include <broadphase/ray.hpp>
#include <cstdint>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace broadphase {

/// A world cube [0, L]^3 with objects; object id = position in `objects`;
/// ray id = position in `rays`.
struct Scene {
  double world = 1000;
  /// The periodic axes (version 3, `world L periodic AXES`), x, y, z. On
  /// each, centres lie in [0, L], half-extents below L/2, |v| below L, and
  /// motion wraps.
  std::array<bool, 3> periodic{false, false, false};
  std::vector<Shape> objects;
  std::vector<Vec3> velocity;  ///< per object; (0,0,0) means static
  /// Per object, or empty when every object has the default Filter{}
  /// (group 1, mask 0xffffffff). When not empty, as long as `objects`.
  std::vector<Filter> filters;
  /// Cast every frame after the objects moved (version 3); each valid
  /// (`is_valid(Ray)`).
  std::vector<Ray> rays;

  std::size_t size() const { return objects.size(); }
  bool is_moving(std::size_t i) const {
    const Vec3& v = velocity[i];
    return v.x != 0 || v.y != 0 || v.z != 0;
  }
  /// Object `i`'s filter (the default when `filters` is empty).
  Filter filter(std::size_t i) const { return filters.empty() ? Filter{} : filters[i]; }
  /// True when any object is a box (the file must then be version 2 or 3).
  bool has_boxes() const;
  /// True when any object's filter is not the default (version 3).
  bool has_filters() const;
  /// True when the scene's frames print the version 3 lines with hits.
  bool has_rays() const { return !rays.empty(); }
  /// True when any axis is periodic (version 3).
  bool is_periodic() const { return periodic[0] || periodic[1] || periodic[2]; }
  /// The periodic cell of the world (PeriodicBroadPhase).
  PeriodicCell cell() const { return PeriodicCell::cube(world, periodic); }
  /// The version `write_scene` writes: 3 with filters, rays or periodic
  /// axes, else 2 with boxes, else 1.
  int version() const;
};

/// Thrown for a malformed scene; `what()` is "FILE:LINE: reason".
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parses a scene of version 1, 2 or 3. `name` is used in messages. Throws
/// SceneError naming the line (in a periodic world also for a centre
/// outside [0, L], a radius or half-extent not below L/2 or a velocity
/// component not below L in magnitude on a periodic axis). Beyond the letter of
/// the format, CRLF line ends, a UTF-8 byte order mark before the header
/// and a leading '+' on a number are accepted.
Scene parse_scene(std::istream& in, const std::string& name);
/// Reads a scene file. Throws SceneError (also when it cannot be opened).
Scene read_scene(const std::string& path);
/// Writes version 1 (spheres only), version 2 (when there are boxes) or
/// version 3 (when there are filters, rays or periodic axes, written in x,
/// y, z order; `Scene::version`), numbers as %.17g so that reading gives
/// back the same doubles.
void write_scene(std::ostream& out, const Scene& scene);
/// Writes a scene file. Throws std::runtime_error when it cannot be written.
void write_scene(const std::string& path, const Scene& scene);

/// Moves every object with a non-zero velocity by one frame, axis by axis,
/// reflecting off the walls of [0, L], or wrapping on a periodic axis
/// (step_axis_periodic), exactly as the contract says.
void step(Scene& scene);
/// The motion of one coordinate (exposed for tests and other steppers).
inline void step_axis(double& p, double& v, double world) {
  p += v;
  if (p < 0) {
    p = -p;
    v = -v;
  } else if (p > world) {
    p = 2 * world - p;
    v = -v;
  }
}

/// The motion of one coordinate on a periodic axis: wraps into [0, L).
inline void step_axis_periodic(double& p, double v, double world) {
  p += v;
  if (p < 0)
    p += world;
  else if (p >= world)
    p -= world;
}

/// splitmix64 as the contract defines it.
constexpr std::uint64_t splitmix64(std::uint64_t x) {
  std::uint64_t z = x + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// The contract's hash of one pair of object ids (any order).
constexpr std::uint64_t pair_hash(std::uint32_t i, std::uint32_t j) {
  if (i > j) std::swap(i, j);
  return splitmix64((std::uint64_t(i) << 32) | j);
}

/// The contract's hash of a periodic pair (i, j, S), i < j: the pair's
/// hash for S = 0, else splitmix64(splitmix64((i << 32) | j) ^ S.code()).
constexpr std::uint64_t pair_hash(std::uint32_t i, std::uint32_t j, Shift s) {
  const std::uint64_t h = splitmix64((std::uint64_t(i) << 32) | j);
  return s.is_zero() ? h : splitmix64(h ^ static_cast<std::uint64_t>(s.code()));
}

/// Pair count and order-independent hash of one frame.
struct FrameDigest {
  std::uint64_t pairs = 0;
  std::uint64_t hash = 0;
  void add(std::uint32_t i, std::uint32_t j) {
    ++pairs;
    hash += pair_hash(i, j);
  }
  /// A periodic pair (i, j, S) with i < j.
  void add(std::uint32_t i, std::uint32_t j, Shift s) {
    ++pairs;
    hash += pair_hash(i, j, s);
  }
  friend bool operator==(const FrameDigest&, const FrameDigest&) = default;
};

/// The contract's hash of one ray hit (version 3, "Frame lines"):
/// splitmix64(splitmix64((ray << 32) | id) + bits(t)).
std::uint64_t hit_hash(std::uint32_t ray, std::uint32_t id, double t);

/// Hit count and order-independent hashes of one frame's rays: every hit,
/// and each ray's closest hit (smallest t, then smallest id).
struct HitDigest {
  std::uint64_t hits = 0;
  std::uint64_t hash = 0;     ///< over every hit
  std::uint64_t closest = 0;  ///< over each ray's closest hit
  friend bool operator==(const HitDigest&, const HitDigest&) = default;
};

/// Gathers one ray's hits, in any order, and adds them to a HitDigest.
class RayHits {
 public:
  explicit RayHits(std::uint32_t ray) : ray_(ray) {}
  void add(std::uint32_t id, double t);
  /// Adds this ray's hits and its closest hit (if any) to `d`.
  void add_to(HitDigest& d) const;

 private:
  std::uint32_t ray_;
  std::uint64_t hits_ = 0, hash_ = 0;
  std::uint32_t best_id_ = 0;
  double best_t_ = 0;
};

/// 16 lowercase hex digits.
std::string hex16(std::uint64_t v);

/// One frame's line as `run` prints it (no newline): `frame pairs hash`,
/// and with rays `frame pairs hash hits hits_hash closest_hash`.
std::string frame_line(int frame, const FrameDigest& pairs, const HitDigest* hits);

/// The study's workloads (docs/scene-format.md, "The paper's workloads"), and
/// the stress kinds the performance work is measured on.
enum class Distribution {
  even,            ///< the study: centres uniform in the 1 km cube
  uneven,          ///< the study: 80% within the lowest tenth of the cube
  scaled_even,     ///< even at the study's density of 6400 objects per km³
  scaled_uneven,   ///< uneven at the study's density
  clusters,        ///< Gaussian clusters of 500 objects each (sigma L/40)
  decades,         ///< radii log-uniform over five decades, 0.001 to 100
  all_moving,      ///< even, but every object moves
  explosion,       ///< debris flying out of a small ball: incoherent motion
  flat,            ///< every centre within 1 unit of the ground (y in [0, 1])
  coincident,      ///< a quarter of the objects share one of N/100 centres
  outside,         ///< 10% of the centres outside the world, 1 in 5000 larger than it
  boxes,           ///< all boxes, thin, long or cubic, largest half side over two decades
  half_boxes,      ///< half boxes, half spheres, sizes as the stress kinds
  box_decades,     ///< sizes over four decades (0.01 to 100), a third of them boxes
  city,            ///< touching buildings on a ground box, spheres flying above them
  shapes_uneven,   ///< half spheres, half poles, slabs, boxes of three half-extents and cubes,
                   ///< under the study's uneven placement
  shapes_decades,  ///< the same, uneven, with sizes over four decades (0.01 to 100)
  shapes_flat,     ///< the same shapes, every centre within 1 unit of the ground
};

/// Every distribution, in enum order.
inline constexpr Distribution kAllDistributions[] = {
    Distribution::even,          Distribution::uneven,         Distribution::scaled_even,
    Distribution::scaled_uneven, Distribution::clusters,       Distribution::decades,
    Distribution::all_moving,    Distribution::explosion,      Distribution::flat,
    Distribution::coincident,    Distribution::outside,        Distribution::boxes,
    Distribution::half_boxes,    Distribution::box_decades,    Distribution::city,
    Distribution::shapes_uneven, Distribution::shapes_decades, Distribution::shapes_flat};

/// Parses a distribution name ("even", "scaled-even", "all-moving", ...).
/// Throws std::invalid_argument listing the valid names.
Distribution parse_distribution(std::string_view name);
std::string_view to_string(Distribution d);

/// A small, portable, seedable generator (splitmix64 stream), so a seed
/// gives the same scene on every platform and standard library.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    state_ += 0x9E3779B97F4A7C15ull;
    return splitmix64(state_ - 0x9E3779B97F4A7C15ull);
  }
  /// Uniform in [0, 1), 53 bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Uniform in [0, n).
  std::uint64_t below(std::uint64_t n) { return n == 0 ? 0 : next() % n; }
  /// A direction uniform on the unit sphere.
  Vec3 direction();

 private:
  std::uint64_t state_;
};

/// Generates a workload of N objects. The study's kinds: spheres with radius
/// uniform in [0.5, 50] (diameters L/1000 .. L/10 of the 1 km world), 20%
/// moving with a uniform direction and a speed uniform in [0.1, 2]; scaled
/// kinds keep the density of 6400 objects per km³: L = 1000 * cbrt(N / 6400).
/// The stress kinds keep L = 1000 and the study's speeds unless their
/// description says otherwise, with radii uniform in [0.5, 5] so that 20 000
/// objects are about as crowded as the study's 6400. The box worlds: `boxes`
/// has largest half sides log-uniform in [0.25, 25], each box cubic, long
/// (the other sides a tenth) or thin (one side a tenth); `half-boxes` sizes
/// as the stress kinds; `box-decades` sizes log-uniform in [0.01, 100];
/// `city` lots of side 8 each filled by a building of half height 1..40
/// standing on a ground box (neighbours and the ground touch exactly), and
/// 30% spheres (the movers) flying at heights 50 to L. The shaped worlds
/// (`shapes-uneven`, `shapes-decades`, `shapes-flat`) are half spheres and
/// half boxes, the boxes in quarters: poles (two half sides each 10 to 100
/// times thinner than the third, log-uniform), slabs (one half side 10 to
/// 100 times thinner than the other two, and 0 in one slab of twenty),
/// boxes of three independent half sides, and cubes. `shapes-uneven` and
/// `shapes-flat`: radii as the stress kinds, a box's largest half side
/// log-uniform in [0.5, 50] (a pole crosses up to a hundred cells of the
/// smallest objects); `shapes-decades`: both log-uniform in [0.01, 100].
/// 20% move at the study's speeds. Placement: the study's uneven (80%
/// within the lowest tenth), or y in [0, 1] (`shapes-flat`).
Scene generate(Distribution d, std::size_t n, std::uint64_t seed);

/// How `add_filters` gives the objects their filters (version 3).
enum class FilterKind {
  layers,  ///< object in one of K layers: group 1 << layer, a layer pairs with itself and
           ///< its two neighbours (layer ± 1 mod K), so most layers ignore each other
  random,  ///< groups and masks of random bits over 8 groups (some pair with nothing)
};

/// Gives every object of `scene` a filter drawn from `seed` (a stream of
/// its own: the objects stay as they are). `layers` (1 to 32) is used by
/// FilterKind::layers. Throws std::invalid_argument for a layer count out
/// of range.
void add_filters(Scene& scene, FilterKind kind, int layers, std::uint64_t seed);

/// Parses the AXES of `world L periodic AXES`: a non-empty set of distinct
/// letters among x, y, z, in any order. Throws std::invalid_argument saying
/// what is wrong (empty, a letter repeated, a letter not an axis).
std::array<bool, 3> parse_periodic_axes(std::string_view axes);
/// The AXES text of `axes` in x, y, z order ("" when none).
std::string periodic_axes_text(const std::array<bool, 3>& axes);

/// Makes `scene` periodic on `axes` (version 3): on each periodic axis,
/// centres are wrapped into [0, L), half-extents of L/2 or more become just
/// below L/2 (0.499 L), and velocity components of L or more in magnitude
/// are cut to L/2 with their sign, so that the contract's limits hold.
/// Objects on the other axes are left as they are.
void make_periodic(Scene& scene, const std::array<bool, 3>& axes);

/// The rays `add_rays` makes (version 3).
enum class RayKind {
  mixed,   ///< a share of each kind below
  random,  ///< random points (some outside the world), random directions and lengths
  lidar,   ///< a fan from one point: rings of elevation, evenly spaced azimuths
  axis,    ///< along an axis on cell faces and edges (multiples of L/8 .. L/64), and
           ///< diagonals through cell corners
  inside,  ///< starting inside or on an object (a hit at t = 0)
  zero,    ///< direction 0: the ray is its origin alone
};
/// Parses "mixed", "random", "lidar", "axis", "inside" or "zero"; throws
/// std::invalid_argument listing them.
RayKind parse_ray_kind(std::string_view name);
std::string_view to_string(RayKind k);

/// Appends `n` rays of `kind` to `scene`, drawn from `seed` (a stream of its
/// own). tmax is a mix of +infinity, 0 and finite values; where the scene
/// has filters, a quarter of the rays get a mask of one or a few groups.
void add_rays(Scene& scene, std::size_t n, RayKind kind, std::uint64_t seed);

}  // namespace broadphase
