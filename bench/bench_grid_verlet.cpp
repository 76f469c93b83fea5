// grid-verlet's kernels in isolation: a frame of the study (bulk update plus
// all pairs), one query, one insert/remove, at one and two threads.
#include <benchmark/benchmark.h>

#include <broadphase/grid_verlet.hpp>
#include <broadphase/scenes/scene.hpp>
#include <string>
#include <vector>

namespace {

using namespace broadphase;

struct Loaded {
  Scene scene;
  GridVerlet grid;
  std::vector<Handle> handles;
  std::vector<std::size_t> moving;
  std::vector<Move> moves;

  Loaded(Distribution d, std::size_t n, const Config& c) : scene(generate(d, n, 1)), grid(c) {
    for (std::size_t i = 0; i < scene.size(); ++i) {
      handles.push_back(
          grid.insert(scene.objects[i], i, scene.is_moving(i) ? Motion::dynamic : Motion::fixed));
      if (scene.is_moving(i)) moving.push_back(i);
    }
    grid.settle();
  }
  void step_scene() {
    step(scene);
    moves.clear();
    for (std::size_t i : moving) moves.push_back({handles[i], scene.objects[i]});
  }
};

Config threads(int t) {
  Config c;
  c.options["threads"] = std::to_string(t);
  return c;
}

// Arguments: distribution, objects, threads.
void BM_GridVerletFrame(benchmark::State& state) {
  Loaded l(static_cast<Distribution>(state.range(0)), static_cast<std::size_t>(state.range(1)),
           threads(static_cast<int>(state.range(2))));
  std::vector<HandlePair> pairs;
  for (auto _ : state) {
    state.PauseTiming();
    l.step_scene();
    pairs.clear();
    state.ResumeTiming();
    l.grid.update(l.moves);
    l.grid.find_pairs(pairs);
  }
  state.counters["pairs"] = static_cast<double>(pairs.size());
}
BENCHMARK(BM_GridVerletFrame)
    ->Args({static_cast<int>(Distribution::even), 6400, 1})
    ->Args({static_cast<int>(Distribution::uneven), 6400, 1})
    ->Args({static_cast<int>(Distribution::scaled_even), 102400, 1})
    ->Args({static_cast<int>(Distribution::scaled_even), 102400, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Argument: the row cell size over the level's reach (option `cell`).
void BM_GridVerletQuery(benchmark::State& state) {
  Config c;
  c.options["cell"] = std::to_string(state.range(0));
  Loaded l(Distribution::uneven, 6400, c);
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    l.grid.query(l.scene.objects[(i++ * 7919) % l.scene.size()], [&hits](Handle) { ++hits; });
  }
  benchmark::DoNotOptimize(hits);
}
BENCHMARK(BM_GridVerletQuery)->Arg(1)->Arg(2)->Arg(4)->Arg(8);

void BM_GridVerletInsertRemove(benchmark::State& state) {
  Loaded l(Distribution::uneven, 6400, {});
  std::size_t i = 0;
  for (auto _ : state) {
    const Handle h = l.grid.insert(l.scene.objects[(i++ * 7919) % l.scene.size()], 0);
    l.grid.remove(h);
  }
}
BENCHMARK(BM_GridVerletInsertRemove);

}  // namespace
