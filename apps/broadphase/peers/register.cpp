#include "peers.hpp"

namespace broadphase::app {

void register_peers(Registry& /*r*/) {}

}  // namespace broadphase::app
