#include "lab.hpp"

namespace broadphase::app {

std::string lab_performance(const LabContext& /*ctx*/) {
  return "## Performance\n\nNot run in this build.\n";
}

}  // namespace broadphase::app
