// Peer libraries that cast rays but find no pairs (Intel Embree): they are
// not structures of the registry, so the lab's ray experiment takes them
// from here. Bullet's broad phases cast rays through their structure
// adapters (peers/bullet.cpp, `cast_ray`).
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/ray.hpp>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace broadphase::app {

/// A closest hit: the object's index in the world given, and t; id -1 and
/// t = +infinity when the ray hits nothing.
struct PeerHit {
  std::int64_t id = -1;
  double t = std::numeric_limits<double>::infinity();
};

/// The contract's closest hit of `r` among `shapes` (ids their positions)
/// by testing every object: the oracle of the ray experiment, and what a
/// peer falls back on for a ray its float walk cannot take.
inline PeerHit closest_by_testing_all(std::span<const Shape> shapes, const Ray& r) {
  PeerHit best;
  double tmax = r.tmax;
  for (std::uint32_t i = 0; i < shapes.size(); ++i) {
    double t;
    if (!ray_hit(r.origin, r.dir, tmax, shapes[i], t)) continue;
    if (best.id < 0 || t < best.t) best = {i, t};  // ascending ids: a tie keeps the first
    tmax = best.t;
  }
  return best;
}

/// True when a float ray can stand for `r` in a peer's float walk (Bullet,
/// Embree): every origin and direction component well inside float's range,
/// and no non-zero direction component that float would flush to zero.
inline bool float_ray(const Ray& r) {
  constexpr double kBig = std::numeric_limits<float>::max() / 4;
  constexpr double kSmall = std::numeric_limits<float>::min() * 4;
  for (int a = 0; a < 3; ++a) {
    if (!(std::fabs(r.origin[a]) < kBig) || !(std::fabs(r.dir[a]) < kBig)) return false;
    if (r.dir[a] != 0 && std::fabs(r.dir[a]) < kSmall) return false;
  }
  return true;
}

/// A world of objects, numbered 0..n-1 in the order given, that a ray peer
/// casts rays into. Not thread-safe.
class RayWorld {
 public:
  virtual ~RayWorld() = default;
  /// Moves objects `ids[k]` to `shapes[k]` and makes the world ready to
  /// cast again (the library's rebuild happens here, so that its cost is
  /// counted where the structures' bulk update is).
  virtual void move(std::span<const std::uint32_t> ids, std::span<const Shape> shapes) = 0;
  /// The closest hit of `r` (the ray's mask is not applied: every object
  /// is seen). Throws InvalidRay.
  virtual PeerHit closest_hit(const Ray& r) = 0;
};

/// One way a peer library casts rays.
struct RayPeer {
  std::string name;
  std::string description;
  /// True when its closest hits are the contract's bit for bit (smallest
  /// t by the exact double evaluation, then smallest id).
  bool exact = false;
  /// Builds the world of `objects` inside `world` (a hint for the
  /// precision margin); `moving`: objects will move between batches.
  std::function<std::unique_ptr<RayWorld>(std::span<const Shape> objects, const Aabb& world,
                                          bool moving)>
      make;
};

/// The ray peers this build has (none without Embree).
std::vector<RayPeer> ray_peers();

namespace peers {
/// Adds Embree's two ways (peers/embree.cpp); ray_peers() calls it when built.
void add_embree(std::vector<RayPeer>& peers);
}  // namespace peers

}  // namespace broadphase::app
