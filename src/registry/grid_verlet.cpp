#include <broadphase/grid_verlet.hpp>

#include "register.hpp"

namespace broadphase {

GridVerletOptions GridVerletOptions::from(const OptionText& text) {
  OptionReader r(text, "grid-verlet");
  GridVerletOptions o;
  o.threads = detail::narrow<unsigned>(r.integer("threads", o.threads));
  o.cell = r.number("cell", o.cell);
  o.grain = detail::narrow<std::size_t>(r.integer("grain", o.grain));
  const std::string movers = r.choice("movers", "auto", {"auto", "lists", "dense"});
  o.movers = movers == "lists"   ? GridVerletMovers::lists
             : movers == "dense" ? GridVerletMovers::dense
                                 : GridVerletMovers::automatic;
  r.finish();
  return o;
}

}  // namespace broadphase

namespace broadphase::detail {

void register_fast(Registry& r) {
  add_structure<GridVerlet>(
      r, "grid-verlet",
      "the default: row grids by size, fixed pairs cached, and per mover a "
      "Verlet list (objects near a grown box, kept while it stays inside), or a "
      "dense grid when everything moves fast; threads=N, movers=auto|lists|dense");
  // Its name until the structure was taken apart; scripts and result files
  // still use it.
  r.add_alias("fast-grid", "grid-verlet");
}

}  // namespace broadphase::detail
