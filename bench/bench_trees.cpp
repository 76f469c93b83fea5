// One coherent frame (update of the movers, then all pairs) of the sweeps
// and the AABB tree, and the pair table behind sap, each in isolation.
#include <benchmark/benchmark.h>

#include <broadphase/detail/pair_table.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <string>
#include <vector>

namespace {

using namespace broadphase;

void frame(benchmark::State& state, const std::string& spec, Distribution dist) {
  Scene scene = generate(dist, static_cast<std::size_t>(state.range(0)), 1);
  Config c;
  c.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  auto bp = make_structure(spec, c);
  std::vector<Handle> h;
  for (std::size_t i = 0; i < scene.size(); ++i)
    h.push_back(
        bp->insert(scene.objects[i], i, scene.is_moving(i) ? Motion::dynamic : Motion::fixed));
  std::vector<Move> moves;
  std::vector<HandlePair> pairs;
  for (auto _ : state) {
    state.PauseTiming();
    step(scene);
    moves.clear();
    for (std::size_t i = 0; i < scene.size(); ++i)
      if (scene.is_moving(i)) moves.push_back({h[i], scene.objects[i]});
    pairs.clear();
    state.ResumeTiming();
    bp->update(moves);
    bp->find_pairs(pairs);
    benchmark::DoNotOptimize(pairs.data());
  }
}

void BM_EvenFrame_Sap(benchmark::State& s) { frame(s, "sap", Distribution::even); }
void BM_EvenFrame_SortSweep(benchmark::State& s) { frame(s, "sort-sweep", Distribution::even); }
void BM_EvenFrame_AabbTree(benchmark::State& s) { frame(s, "aabb-tree", Distribution::even); }
void BM_EvenFrame_AabbTreeFront(benchmark::State& s) {
  frame(s, "aabb-tree:front=deferred", Distribution::even);
}
void BM_ExplosionFrame_Sap(benchmark::State& s) { frame(s, "sap", Distribution::explosion); }
void BM_ExplosionFrame_SortSweep(benchmark::State& s) {
  frame(s, "sort-sweep", Distribution::explosion);
}
void BM_ExplosionFrame_AabbTree(benchmark::State& s) {
  frame(s, "aabb-tree", Distribution::explosion);
}
BENCHMARK(BM_EvenFrame_Sap)->Arg(1600)->Arg(6400);
BENCHMARK(BM_EvenFrame_SortSweep)->Arg(1600)->Arg(6400);
BENCHMARK(BM_EvenFrame_AabbTree)->Arg(1600)->Arg(6400);
BENCHMARK(BM_EvenFrame_AabbTreeFront)->Arg(1600)->Arg(6400);
BENCHMARK(BM_ExplosionFrame_Sap)->Arg(4000);
BENCHMARK(BM_ExplosionFrame_SortSweep)->Arg(4000);
BENCHMARK(BM_ExplosionFrame_AabbTree)->Arg(4000);

void BM_PairTableChurn(benchmark::State& state) {
  detail::PairTable t;
  Rng rng(1);
  for (auto _ : state) {
    const auto a = static_cast<std::uint32_t>(rng.below(4096));
    const auto b = static_cast<std::uint32_t>(rng.below(4096));
    if (!t.insert(a, b)) t.erase(a, b);
  }
  benchmark::DoNotOptimize(t.size());
}
BENCHMARK(BM_PairTableChurn);

}  // namespace
