// Bullet's step with its own broad phases and with ours, side by side in
// one process: btDbvtBroadphase, bt32BitAxisSweep3 and BulletBroadphase
// over the structures named, on the same worlds (tests/bullet/
// bullet_worlds.hpp), the runs of one scene interleaved step by step so
// that the machine's load falls on all alike (bullet_measure.hpp).
//
//   bullet_bench [--scene falling|pyramid|mixed|groups|ghost] [--bodies N]
//                [--steps S] [--structures 'spec;spec'] [--no-sweep]
//
// Specs are separated by ';' (a spec's options use commas). Default: 3 000
// falling boxes, 1 000 steps, our default structure.
#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/detail/median.hpp>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "bullet_measure.hpp"

namespace {

using broadphase::detail::median;
double sum(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  broadphase::engines::BulletPlan plan;
  plan.structures = {broadphase::BulletOptions{}.structure};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bullet_bench: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--scene") {
      plan.scene = next();
    } else if (a == "--bodies") {
      plan.bodies = std::atoi(next().c_str());
    } else if (a == "--steps") {
      plan.steps = std::atoi(next().c_str());
    } else if (a == "--structures") {
      plan.structures.clear();
      std::string list = next();
      for (std::size_t p = 0; p <= list.size();) {
        const std::size_t q = std::min(list.find(';', p), list.size());
        plan.structures.push_back(list.substr(p, q - p));
        p = q + 1;
      }
    } else if (a == "--no-sweep") {
      plan.sweep = false;
    } else {
      std::fprintf(stderr, "bullet_bench: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  std::vector<broadphase::engines::BulletRun> runs;
  try {
    runs = broadphase::engines::measure_bullet(plan);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bullet_bench: %s\n", e.what());
    return 2;
  }

  const int steps = plan.steps;
  std::printf(
      "scene %s, %d bodies, %d steps (thread CPU time: medians per step in ms, totals in s)\n",
      plan.scene.c_str(), plan.bodies, steps);
  std::printf("%-28s %10s %10s %10s %8s %10s %10s %10s\n", "broad phase", "step", "broad", "aabbs+",
              "share", "step tot", "broad tot", "pairs");
  const auto& ref = runs.front();
  for (const auto& r : runs) {
    std::printf("%-28s %10.3f %10.3f %10.3f %7.1f%% %10.2f %10.2f %10d\n", r.name.c_str(),
                median(r.step_ms), median(r.broad_ms), r.aabbs_ms / steps,
                100 * sum(r.broad_ms) / sum(r.step_ms), sum(r.step_ms) / 1000,
                sum(r.broad_ms) / 1000, r.pairs);
  }
  for (const auto& r : runs) {
    if (&r == &ref) continue;
    std::printf(
        "dbvt / %-21s broad phase %.2fx (median), %.2fx (total); step %.2fx (median), %.2fx "
        "(total)\n",
        r.name.c_str(), median(ref.broad_ms) / median(r.broad_ms),
        sum(ref.broad_ms) / sum(r.broad_ms), median(ref.step_ms) / median(r.step_ms),
        sum(ref.step_ms) / sum(r.step_ms));
  }
  return 0;
}
