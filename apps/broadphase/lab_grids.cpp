#include "lab.hpp"

namespace broadphase::app {

std::string lab_cell_size_sweep(const LabContext& /*ctx*/) {
  return "## Cell-size sweep\n\nNot run in this build.\n";
}

}  // namespace broadphase::app
