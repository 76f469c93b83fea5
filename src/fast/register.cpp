#include "../register.hpp"

namespace broadphase::detail {

void register_fast(Registry& /*r*/) {}

}  // namespace broadphase::detail
