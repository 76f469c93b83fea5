// The octrees and the k-d tree on the study's even workload: one frame's
// update of the moving objects, and one all-pairs pass, each measured alone.
#include <benchmark/benchmark.h>

#include <broadphase/kdtree.hpp>
#include <broadphase/octree.hpp>
#include <broadphase/octree_linear.hpp>
#include <broadphase/octree_loose.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cstdint>
#include <vector>

namespace {

using namespace broadphase;

template <class S>
struct Loaded {
  Scene scene;
  S structure;
  std::vector<Handle> handles;

  explicit Loaded(std::size_t n) : scene(generate(Distribution::even, n, 1)), structure(Config{}) {
    for (std::size_t i = 0; i < scene.size(); ++i)
      handles.push_back(structure.insert(scene.objects[i], i));
  }
};

template <class S>
void BM_AllPairs(benchmark::State& state) {
  Loaded<S> l(static_cast<std::size_t>(state.range(0)));
  std::uint64_t pairs = 0;
  for (auto _ : state) l.structure.for_each_pair([&](Handle, Handle) { ++pairs; });
  benchmark::DoNotOptimize(pairs);
  state.SetItemsProcessed(state.iterations() * state.range(0));
}

template <class S>
void BM_MoveFrame(benchmark::State& state) {
  Loaded<S> l(static_cast<std::size_t>(state.range(0)));
  std::vector<std::uint32_t> moving;
  for (std::size_t i = 0; i < l.scene.size(); ++i)
    if (l.scene.is_moving(i)) moving.push_back(static_cast<std::uint32_t>(i));
  std::vector<Move> moves;
  for (auto _ : state) {
    state.PauseTiming();
    step(l.scene);
    moves.clear();
    for (std::uint32_t i : moving) moves.push_back({l.handles[i], l.scene.objects[i]});
    state.ResumeTiming();
    if constexpr (requires { l.structure.update(std::span<const Move>(moves)); })
      l.structure.update(std::span<const Move>(moves));
    else
      for (const Move& m : moves) l.structure.update(m.handle, m.shape);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(moving.size()));
}

BENCHMARK(BM_AllPairs<Octree>)->Arg(6400);
BENCHMARK(BM_AllPairs<LooseOctree>)->Arg(6400);
BENCHMARK(BM_AllPairs<LinearOctree>)->Arg(6400);
BENCHMARK(BM_AllPairs<KdTree>)->Arg(6400);
BENCHMARK(BM_MoveFrame<Octree>)->Arg(6400);
BENCHMARK(BM_MoveFrame<LooseOctree>)->Arg(6400);
BENCHMARK(BM_MoveFrame<LinearOctree>)->Arg(6400);
BENCHMARK(BM_MoveFrame<KdTree>)->Arg(6400);

}  // namespace
