#include <broadphase/naive.hpp>
#include <broadphase/study/hgrid_paper.hpp>
#include <broadphase/study/octree_paper.hpp>

#include "register.hpp"

namespace broadphase {

NaiveOptions NaiveOptions::from(const OptionText& text) {
  OptionReader(text, "naive").finish();
  return {};
}

OctreePaperOptions OctreePaperOptions::from(const OptionText& text) {
  OptionReader r(text, "octree-paper");
  OctreePaperOptions o;
  o.clamp_outside = r.choice("outside", "root", {"root", "clamp"}) == "clamp";
  r.finish();
  return o;
}

HGridPaperOptions HGridPaperOptions::from(const OptionText& text) {
  OptionReader r(text, "hgrid-paper");
  HGridPaperOptions o;
  o.levels = detail::narrow<int>(r.integer("levels", static_cast<std::uint64_t>(o.levels)));
  r.finish();
  return o;
}

}  // namespace broadphase

namespace broadphase::detail {

void register_study(Registry& r) {
  add_structure<Naive>(r, "naive",
                       "tests every pair, O(n^2): the study's base case and the oracle");
  add_structure<OctreePaper>(r, "octree-paper",
                             "the study's octree: fixed depth 4 over the world cube, objects at "
                             "the deepest node containing them");
  add_structure<HGridPaper>(
      r, "hgrid-paper",
      "the study's hierarchical hashed grid: levels of 2^k cells per axis in one hash table");
}

}  // namespace broadphase::detail
