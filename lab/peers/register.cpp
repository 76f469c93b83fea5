#include "peer_common.hpp"
#include "peers.hpp"
#include "ray_peers.hpp"

namespace broadphase::app {

void register_peers([[maybe_unused]] Registry& r) {
#ifdef BROADPHASE_HAVE_BULLET
  peers::register_bullet(r);
#endif
#ifdef BROADPHASE_HAVE_FCL
  peers::register_fcl(r);
#endif
#ifdef BROADPHASE_HAVE_ODE
  peers::register_ode(r);
#endif
#ifdef BROADPHASE_HAVE_CGAL
  peers::register_cgal(r);
#endif
}

std::vector<RayPeer> ray_peers() {
  std::vector<RayPeer> peers;
#ifdef BROADPHASE_HAVE_EMBREE
  peers::add_embree(peers);
#endif
  return peers;
}

}  // namespace broadphase::app
