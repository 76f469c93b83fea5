// Frame-interleaved comparison of two builds of the library (A: a past
// commit, B: the working tree) in one process: four replays of one scene
// (A and B, each with two structure specs) take turns in blocks of a few
// frames, in a rotating order, with a pause between blocks long enough for
// any worker pool to fall asleep. The host's drift, which moves whole runs
// by 10-30% on a shared virtual machine, then falls on all four alike. The
// pair hashes of the four must agree on every frame.
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "runner.hpp"

namespace {
using broadphase::detail::median;
}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr, "usage: ab SCENE FRAMES SPEC1 SPEC2 [BLOCK]\n");
    return 2;
  }
  const std::string scene = argv[1];
  const int frames = std::atoi(argv[2]);
  const std::string specs[2] = {argv[3], argv[4]};
  const int block = argc > 5 ? std::max(1, std::atoi(argv[5])) : 5;
  std::unique_ptr<Runner> runs[4] = {make_runner_A(scene, specs[0]), make_runner_A(scene, specs[1]),
                                     make_runner_B(scene, specs[0]),
                                     make_runner_B(scene, specs[1])};
  static const int kOrders[4][4] = {{0, 1, 2, 3}, {3, 2, 1, 0}, {2, 0, 3, 1}, {1, 3, 0, 2}};
  std::vector<double> ms[4];
  for (int f = 0; f < frames; f += block) {
    std::vector<std::uint64_t> hashes[4];
    for (int k = 0; k < 4; ++k) {
      const int i = kOrders[(f / block) % 4][k];
      for (int b = 0; b < block; ++b) {
        const double t = runs[i]->frame();
        hashes[i].push_back(runs[i]->hash());
        // The first frames (the inserts' warm-up) and the first of each
        // block (caches cold after the other replays) are not counted.
        if (f + b >= 2 && b > 0) ms[i].push_back(t);
        std::this_thread::sleep_for(std::chrono::microseconds(300));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(3));
    }
    for (int i = 1; i < 4; ++i)
      if (hashes[i] != hashes[0]) {
        std::fprintf(stderr, "pair hashes differ in frames %d-%d\n", f, f + block - 1);
        return 1;
      }
  }
  const char* names[4] = {"A", "A", "B", "B"};
  for (int i = 0; i < 4; ++i)
    std::printf("%s %-32s median %.3f ms (%zu frames)\n", names[i], specs[i % 2].c_str(),
                median(ms[i]), ms[i].size());
  const double a0 = median(ms[0]), a1 = median(ms[1]), b0 = median(ms[2]), b1 = median(ms[3]);
  std::printf("B/A: %s %.3f, %s %.3f;  %s over %s: A %.3f, B %.3f\n", specs[0].c_str(), b0 / a0,
              specs[1].c_str(), b1 / a1, specs[0].c_str(), specs[1].c_str(), a0 / a1, b0 / b1);
  return 0;
}
