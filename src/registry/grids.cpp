#include <broadphase/grid_dense.hpp>
#include <broadphase/grid_hashed.hpp>
#include <broadphase/grid_hybrid.hpp>
#include <broadphase/grid_implicit.hpp>
#include <broadphase/grid_static.hpp>
#include <broadphase/hgrid.hpp>

#include "register.hpp"

namespace broadphase {

GridDenseOptions GridDenseOptions::from(const OptionText& text) {
  OptionReader r(text, "grid-dense");
  GridDenseOptions o;
  o.cell = r.number("cell", o.cell);
  r.finish();
  return o;
}

namespace {
// grid-hashed and grid-hybrid take the same keys.
template <class O>
O read_hashed(const OptionText& text, const char* name) {
  OptionReader r(text, name);
  O o;
  o.cell = r.number("cell", o.cell);
  o.buckets = detail::narrow<std::size_t>(r.integer("buckets", o.buckets));
  r.finish();
  return o;
}
}  // namespace

GridHashedOptions GridHashedOptions::from(const OptionText& text) {
  return read_hashed<GridHashedOptions>(text, "grid-hashed");
}

GridHybridOptions GridHybridOptions::from(const OptionText& text) {
  return read_hashed<GridHybridOptions>(text, "grid-hybrid");
}

GridStaticOptions GridStaticOptions::from(const OptionText& text) {
  OptionReader r(text, "grid-static");
  GridStaticOptions o;
  o.cell = r.number("cell", o.cell);
  const std::string policy = r.choice("policy", "auto", {"rebuild", "patch", "auto"});
  o.policy = policy == "rebuild" ? GridStaticPolicy::rebuild
             : policy == "patch" ? GridStaticPolicy::patch
                                 : GridStaticPolicy::automatic;
  o.cache_fixed = r.choice("fixed", "cache", {"cache", "plain"}) == "cache";
  r.finish();
  return o;
}

GridImplicitOptions GridImplicitOptions::from(const OptionText& text) {
  OptionReader r(text, "grid-implicit");
  GridImplicitOptions o;
  o.cell = r.number("cell", o.cell);
  r.finish();
  return o;
}

HGridOptions HGridOptions::from(const OptionText& text) {
  OptionReader(text, "hgrid").finish();
  return {};
}

}  // namespace broadphase

namespace broadphase::detail {

void register_grids(Registry& r) {
  add_structure<GridDense>(r, "grid-dense",
                           "uniform grid: dense cell array over the world, linked lists");
  add_structure<GridHashed>(r, "grid-hashed",
                            "uniform grid: cells hashed into a bucket table, unbounded world");
  add_structure<GridStatic>(
      r, "grid-static",
      "uniform grid: contiguous cells by counting sort, fixed pairs cached, rebuild/patch");
  add_structure<GridImplicit>(r, "grid-implicit",
                              "uniform grid as per-axis slab bit arrays, cells = AND of three");
  add_structure<HGrid>(r, "hgrid",
                       "hierarchical grid: power-of-two levels in one hash table, any size");
  add_structure<GridHybrid>(r, "grid-hybrid",
                            "coarse hashed grid whose cells hold x-sorted lists, swept");
}

}  // namespace broadphase::detail
