#include "register.hpp"

#include <broadphase/fast_grid.hpp>

namespace broadphase::detail {

void register_fast(Registry& r) {
  add_structure<FastGrid>(
      r, "fast-grid",
      "row grids by size with a fixed/moving split and cached fixed pairs; threads=N");
}

}  // namespace broadphase::detail
