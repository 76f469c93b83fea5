#include "../register.hpp"

namespace broadphase::detail {

void register_trees(Registry& /*r*/) {}

}  // namespace broadphase::detail
