#include <broadphase/naive.hpp>

#include "../register.hpp"

namespace broadphase::detail {

void register_study(Registry& r) {
  add_structure<Naive>(r, "naive", "tests every pair, O(n^2): the study's base case and the oracle");
}

}  // namespace broadphase::detail
