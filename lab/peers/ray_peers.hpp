// Peer libraries that cast rays but find no pairs (Intel Embree): they are
// not structures of the registry, so the lab's ray experiment takes them
// from here. Bullet's broad phases cast rays through their structure
// adapters (peers/bullet.cpp, `cast_ray`).
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/ray.hpp>
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
