#include "structures.hpp"

#include "peers/peers.hpp"

namespace broadphase::app {

const Registry& registry() {
  static const Registry r = [] {
    Registry reg = Registry::library();
    register_peers(reg);
    return reg;
  }();
  return r;
}

}  // namespace broadphase::app
