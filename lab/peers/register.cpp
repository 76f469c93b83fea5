#include "peer_common.hpp"
#include "peers.hpp"

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

}  // namespace broadphase::app
