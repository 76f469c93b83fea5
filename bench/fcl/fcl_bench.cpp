// broadphase::FclCollisionManager against FCL's own managers, side by side in
// one process (fcl_measure.hpp: the world, what is timed, the checks).
//
//   fcl_bench [--sizes 1000,10000,100000] [--frames 10] [--seed 1]
//             [--structure grid-verlet] [--skip-sap-above N] [--skip-hash-above N]
//             [--ours-only 1]  (no FCL manager: for profiling ours alone)
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "fcl_measure.hpp"

namespace {

using broadphase::detail::median;

std::vector<std::size_t> parse_sizes(const std::string& text) {
  std::vector<std::size_t> sizes;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v == 0 || v > 10000000)
      throw std::invalid_argument("--sizes: '" + item + "' is not a count in [1, 10^7]");
    sizes.push_back(static_cast<std::size_t>(v));
  }
  return sizes;
}

int positive(const char* flag, const char* text) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (*text == '\0' || *end != '\0' || v < 1 || v > 100000)
    throw std::invalid_argument(std::string(flag) + ": '" + text + "' is not in [1, 100000]");
  return static_cast<int>(v);
}

void print(const broadphase::engines::FclSizeRun& r) {
  std::printf("n=%zu world %.1f: %zu movers, %zu pairs per frame (all managers agree)\n", r.n,
              r.world, r.movers, r.pairs);
  const double ours = median(r.managers.front().total_ms);
  std::printf("%-34s %11s %10s %11s %12s %12s %12s\n", "manager", "register ms", "update ms",
              "collide ms", "callback ms", "upd+col ms", "vs ours");
  for (const auto& c : r.managers)
    std::printf("%-34s %11.2f %10.3f %11.3f %12.3f %12.3f %11.2fx\n", c.name.c_str(), c.register_ms,
                median(c.update_ms), median(c.collide_ms), median(c.callback_ms),
                median(c.total_ms), median(c.total_ms) / ours);
  // What no broad phase behind FCL's callback saves: the callback's own
  // time on the pairs, in the fastest order any manager handed them out.
  double floor = median(r.managers.front().callback_ms);
  for (const auto& c : r.managers) floor = std::min(floor, median(c.callback_ms));
  const auto& tree = r.managers.size() > 1 ? r.managers[1] : r.managers.front();
  if (r.managers.size() < 2) {
    std::printf("the callback alone: %.3f ms\n\n", floor);
    return;
  }
  std::printf(
      "the callback alone: %.3f ms at the least; %s's update + collide over it: %.2fx, "
      "the most any manager could be faster (one whose update and pair pass took no "
      "time)\n",
      floor, tree.name.c_str(), median(tree.total_ms) / floor);
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::vector<std::size_t> sizes{1000, 10000, 100000};
    broadphase::engines::FclPlan plan;
    std::size_t skip_sap_above = 10000000, skip_hash_above = 10000000;
    bool ours_only = false;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (i + 1 >= argc) throw std::invalid_argument(a + ": missing value (or unknown option)");
      const char* v = argv[++i];
      if (a == "--sizes")
        sizes = parse_sizes(v);
      else if (a == "--frames")
        plan.frames = positive("--frames", v);
      else if (a == "--seed")
        plan.seed = static_cast<std::uint64_t>(positive("--seed", v));
      else if (a == "--structure")
        plan.structure = v;
      else if (a == "--skip-sap-above")
        skip_sap_above = static_cast<std::size_t>(positive("--skip-sap-above", v));
      else if (a == "--ours-only")
        ours_only = positive("--ours-only", v) != 0;
      else if (a == "--skip-hash-above")
        skip_hash_above = static_cast<std::size_t>(positive("--skip-hash-above", v));
      else
        throw std::invalid_argument("unknown option '" + a + "'");
    }
    std::printf(
        "fcl_bench: %d frames after %d warm-up frames, medians of thread CPU time; seed %llu\n\n",
        plan.frames, plan.warm, static_cast<unsigned long long>(plan.seed));
    for (std::size_t n : sizes) {
      plan.n = n;
      plan.tree = !ours_only;
      plan.sap = !ours_only && n <= skip_sap_above;
      plan.hash = !ours_only && n <= skip_hash_above;
      print(broadphase::engines::measure_fcl(plan));
    }
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "fcl_bench: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fcl_bench: %s\n", e.what());
    return 2;
  }
  return 0;
}
