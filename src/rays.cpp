#include <broadphase/rays.hpp>

namespace broadphase {

void cast_rays(const AnyBroadPhase& s, std::span<const Ray> rays, std::span<RayHit> closest,
               unsigned threads) {
  cast_rays<AnyBroadPhase>(s, rays, closest, threads);
}

void cast_rays_all(const AnyBroadPhase& s, std::span<const Ray> rays, RayHitRows& out,
                   unsigned threads) {
  cast_rays_all<AnyBroadPhase>(s, rays, out, threads);
}

}  // namespace broadphase
