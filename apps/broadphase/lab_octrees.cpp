#include "lab.hpp"

namespace broadphase::app {

std::string lab_octree_experiments(const LabContext& /*ctx*/) {
  return "## Octrees and the k-d tree\n\nNot run in this build.\n";
}

}  // namespace broadphase::app
