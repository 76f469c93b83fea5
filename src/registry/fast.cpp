#include <broadphase/fast_grid.hpp>

#include "register.hpp"

namespace broadphase {

FastGridOptions FastGridOptions::from(const Config& c) {
  OptionReader r(c, "fast-grid");
  FastGridOptions o;
  o.threads = detail::narrow<unsigned>(r.integer("threads", o.threads));
  o.cell = r.number("cell", o.cell);
  o.grain = detail::narrow<std::size_t>(r.integer("grain", o.grain));
  r.finish();
  return o;
}

}  // namespace broadphase

namespace broadphase::detail {

void register_fast(Registry& r) {
  add_structure<FastGrid>(
      r, "fast-grid",
      "row grids by size with a fixed/moving split and cached fixed pairs; threads=N");
}

}  // namespace broadphase::detail
