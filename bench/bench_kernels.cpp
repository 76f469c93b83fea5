// Microbenchmarks of the hot kernels, each measured in isolation.
#include <benchmark/benchmark.h>
#include <broadphase/geometry.hpp>
#include <broadphase/scene.hpp>

#include <vector>

namespace {

using namespace broadphase;

void BM_SphereSpherePredicate(benchmark::State& state) {
  const Scene s = generate(Distribution::even, 1024, 1);
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    const Shape& a = s.objects[i & 1023];
    const Shape& b = s.objects[(i * 7 + 3) & 1023];
    hits += overlaps(a, b);
    ++i;
  }
  benchmark::DoNotOptimize(hits);
}
BENCHMARK(BM_SphereSpherePredicate);

void BM_ConservativeFloatBounds(benchmark::State& state) {
  const Scene s = generate(Distribution::even, 1024, 1);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(bounds_f(s.objects[i++ & 1023]));
  }
}
BENCHMARK(BM_ConservativeFloatBounds);

}  // namespace
