#include "../register.hpp"

namespace broadphase::detail {

void register_grids(Registry& /*r*/) {}

}  // namespace broadphase::detail
