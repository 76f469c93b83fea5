// The Python benchmark's moving workload (python/bench/bench.py) through the
// C++ tracker: N spheres of one radius uniform in the unit cube (radius
// 0.00565 at 10^6, the same density at other N), 20% of them moving a tenth
// of a radius a frame in a random direction, bouncing off the cube's faces;
// one `PairTracker::find_pairs` with `Changes::only(movers)` per frame.
//
//   moving_bench [N [FRAMES]] [--one-shot] [--verbose]
//
// Prints the median and mean CPU time of a call (one thread, frame 0 left
// out), the calls that took movers mode or rebuilt, and the own bytes per
// object. `--one-shot` calls `find_pairs` on the whole set instead;
// `--verbose` prints every call.
#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <numeric>
#include <random>
#include <vector>

namespace {

double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace broadphase;
  std::size_t n = 100000;
  int frames = 100;
  bool one_shot = false, verbose = false;
  int positional = 0;
  for (int a = 1; a < argc; ++a) {
    if (std::strcmp(argv[a], "--one-shot") == 0) {
      one_shot = true;
    } else if (std::strcmp(argv[a], "--verbose") == 0) {
      verbose = true;
    } else if (positional == 0 && std::atol(argv[a]) > 0) {
      n = static_cast<std::size_t>(std::atol(argv[a]));
      ++positional;
    } else if (positional == 1 && std::atoi(argv[a]) > 1) {
      frames = std::atoi(argv[a]);
      ++positional;
    } else {
      std::fprintf(stderr, "usage: moving_bench [N [FRAMES]] [--one-shot] [--verbose]\n");
      return 2;
    }
  }
  const double r = 0.00565 * std::cbrt(1e6 / static_cast<double>(n));
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::normal_distribution<double> normal;
  std::vector<double> xyz(3 * n);
  for (double& v : xyz) v = uniform(rng);
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<std::uint32_t> movers(order.begin(),
                                    order.begin() + static_cast<std::ptrdiff_t>(n / 5));
  std::sort(movers.begin(), movers.end());
  std::vector<double> v(3 * movers.size());
  for (std::size_t m = 0; m < movers.size(); ++m) {
    const double a = normal(rng), b = normal(rng), c = normal(rng);
    const double len = std::sqrt(a * a + b * b + c * c);
    v[3 * m] = 0.1 * r * a / len;
    v[3 * m + 1] = 0.1 * r * b / len;
    v[3 * m + 2] = 0.1 * r * c / len;
  }
  const Objects objects = Objects::spheres(xyz.data(), &r, n, 0);
  PairTracker tracker;
  std::vector<IndexPair> out;
  std::vector<double> calls;
  int in_movers_mode = 0, rebuilt = 0;
  for (int f = 0; f < frames; ++f) {
    for (std::size_t m = 0; m < movers.size(); ++m)
      for (int a = 0; a < 3; ++a) {
        double& x = xyz[3 * movers[m] + static_cast<std::size_t>(a)];
        double& dx = v[3 * m + static_cast<std::size_t>(a)];
        if (x + dx < 0 || x + dx > 1)
          dx = -dx;
        else
          x += dx;
      }
    out.clear();
    const double t0 = cpu_ms();
    const ArrayCallStats s = one_shot ? find_pairs(objects, out)
                                      : tracker.find_pairs(objects, out, Changes::only(movers));
    const double ms = cpu_ms() - t0;
    if (f > 0) calls.push_back(ms);
    in_movers_mode += s.movers ? 1 : 0;
    rebuilt += s.rebuilt ? 1 : 0;
    if (verbose)
      std::printf("%d %zu pairs %.2f ms renewed %llu%s%s%s\n", f, out.size(), ms,
                  static_cast<unsigned long long>(s.renewed), s.movers ? " movers" : "",
                  s.rebuilt ? " rebuilt" : "", s.compacted ? " compacted" : "");
  }
  std::vector<double> sorted = calls;
  std::sort(sorted.begin(), sorted.end());
  const double mean =
      std::accumulate(calls.begin(), calls.end(), 0.0) / static_cast<double>(calls.size());
  std::printf(
      "%s n %zu frames %d: pairs %zu, median call %.2f ms, mean %.2f ms (cpu, one thread), "
      "movers mode %d calls, rebuilt %d, own %.1f B/object\n",
      one_shot ? "one-shot" : "tracker", n, frames, out.size(), sorted[sorted.size() / 2], mean,
      in_movers_mode, rebuilt,
      static_cast<double>(tracker.memory_bytes()) / static_cast<double>(n));
}
