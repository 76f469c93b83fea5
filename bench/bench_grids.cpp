// One frame of the study's scenes (move the 20% that move, update, find all
// pairs) for each grid, measured in CPU time so that a busy machine blurs
// the comparison less. Run with a filter, e.g.
//   broadphase_bench --benchmark_filter='Frame.*even' --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include <broadphase/registry.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <memory>
#include <string>

namespace {

using namespace broadphase;

void run_frames(benchmark::State& state, const std::string& algo, Distribution d, std::size_t n) {
  Scene scene = generate(d, n, 1);
  Config config;
  config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  config.expected_objects = n;
  auto bp = make_structure(algo, config);
  Replay replay(*bp, std::move(scene));
  replay.next();
  std::uint64_t tests = 0, pairs = 0;
  for (auto _ : state) {
    const FrameResult r = replay.next();
    tests += r.tests;
    pairs += r.digest.pairs;
  }
  const double frames = static_cast<double>(state.iterations());
  state.counters["tests"] = static_cast<double>(tests) / frames;
  state.counters["pairs"] = static_cast<double>(pairs) / frames;
  state.counters["bytes_per_object"] =
      static_cast<double>(bp->memory_bytes()) / static_cast<double>(n);
}

void register_all() {
  const char* algos[] = {"grid-dense",
                         "grid-hashed",
                         "grid-static",
                         "grid-static:policy=rebuild",
                         "grid-static:policy=patch",
                         "grid-static:fixed=plain",
                         "grid-implicit",
                         "hgrid",
                         "grid-hybrid"};
  struct Workload {
    const char* name;
    Distribution dist;
    std::size_t n;
  };
  // The study's two scenes and two stress kinds where the grids differ most.
  const Workload workloads[] = {{"even", Distribution::even, 6400},
                                {"uneven", Distribution::uneven, 6400},
                                {"decades", Distribution::decades, 20000},
                                {"flat", Distribution::flat, 20000}};
  for (const char* a : algos)
    for (const Workload& w : workloads) {
      const std::string name = std::string("Frame/") + a + "/" + w.name + "/" + std::to_string(w.n);
      const std::string algo = a;
      const Workload work = w;
      benchmark::RegisterBenchmark(name.c_str(), [algo, work](benchmark::State& s) {
        try {
          run_frames(s, algo, work.dist, work.n);
        } catch (const std::exception& e) {
          s.SkipWithError(e.what());
        }
      })->Unit(benchmark::kMillisecond);
    }
}

const int kRegistered = (register_all(), 0);

}  // namespace
