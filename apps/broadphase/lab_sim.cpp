#include "lab.hpp"

namespace broadphase::app {

std::string lab_tunneling(const LabContext& /*ctx*/) {
  return "## Tunneling\n\nNot run in this build.\n";
}

}  // namespace broadphase::app
