#include "lab.hpp"

namespace broadphase::app {

std::string lab_tree_experiments(const LabContext& /*ctx*/) {
  return "## Trees, sweeps and caches\n\nNot run in this build.\n";
}

}  // namespace broadphase::app
