// Microbenchmarks of the hot kernels, each measured in isolation.
#include <benchmark/benchmark.h>

#include <broadphase/geometry.hpp>
#include <broadphase/naive.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <vector>

namespace {

using namespace broadphase;

// 1024 objects, alternately spheres and boxes, for the mixed predicates.
std::vector<Shape> mixed_shapes() {
  const Scene s = generate(Distribution::even, 1024, 1);
  std::vector<Shape> out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Shape& o = s.objects[i];
    out.push_back(i % 2 ? Shape::box(o.center, {o.half.x, o.half.x * 0.5, o.half.x * 2}) : o);
  }
  return out;
}

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

void BM_MixedPredicate(benchmark::State& state) {
  const std::vector<Shape> shapes = mixed_shapes();
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    hits += overlaps(shapes[i & 1023], shapes[(i * 7 + 3) & 1023]);
    ++i;
  }
  benchmark::DoNotOptimize(hits);
}
BENCHMARK(BM_MixedPredicate);

void BM_BoxBoxPredicate(benchmark::State& state) {
  const std::vector<Shape> shapes = mixed_shapes();
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    const Shape& a = shapes[(i & 511) * 2 + 1];
    const Shape& b = shapes[((i * 7 + 3) & 511) * 2 + 1];
    hits += boxes_overlap(a.center, a.half, b.center, b.half);
    ++i;
  }
  benchmark::DoNotOptimize(hits);
}
BENCHMARK(BM_BoxBoxPredicate);

void BM_ConservativeBounds(benchmark::State& state) {
  const Scene s = generate(Distribution::even, 1024, 1);
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(bounds(s.objects[i++ & 1023]));
}
BENCHMARK(BM_ConservativeBounds);

void BM_ConservativeFloatBounds(benchmark::State& state) {
  const Scene s = generate(Distribution::even, 1024, 1);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(bounds_f(s.objects[i++ & 1023]));
  }
}
BENCHMARK(BM_ConservativeFloatBounds);

// Rounding one double outwards to float, the step bounds_f takes six times.
void BM_RoundOutwards(benchmark::State& state) {
  std::vector<double> xs(1024);
  Rng rng(3);
  for (double& x : xs) x = rng.uniform(-1e4, 1e4);
  std::size_t i = 0;
  for (auto _ : state) {
    const double x = xs[i++ & 1023];
    benchmark::DoNotOptimize(round_down(x));
    benchmark::DoNotOptimize(round_up(x));
  }
}
BENCHMARK(BM_RoundOutwards);

void BM_FloatBoxOverlap(benchmark::State& state) {
  const Scene s = generate(Distribution::even, 1024, 1);
  std::vector<AabbF> boxes;
  for (const Shape& o : s.objects) boxes.push_back(bounds_f(o));
  std::size_t i = 0, hits = 0;
  for (auto _ : state) {
    hits += boxes[i & 1023].overlaps(boxes[(i * 7 + 3) & 1023]);
    ++i;
  }
  benchmark::DoNotOptimize(hits);
}
BENCHMARK(BM_FloatBoxOverlap);

void BM_Splitmix64(benchmark::State& state) {
  std::uint64_t x = 1;
  for (auto _ : state) {
    x = splitmix64(x);
    benchmark::DoNotOptimize(x);
  }
}
BENCHMARK(BM_Splitmix64);

// The contract's pair hash accumulated as a frame digest, per pair.
void BM_PairHashDigest(benchmark::State& state) {
  FrameDigest d;
  std::uint32_t i = 0;
  for (auto _ : state) {
    d.add(i * 2654435761u, i + 17);
    ++i;
  }
  benchmark::DoNotOptimize(d);
}
BENCHMARK(BM_PairHashDigest);

// One engine frame (move the moving 20%, bulk update, all pairs, digest)
// of the naive structure on the study's even placement.
void BM_ReplayFrameNaive(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  Erased<Naive> bp;
  Replay replay(bp, generate(Distribution::even, n, 7));
  std::uint64_t pairs = 0;
  for (auto _ : state) pairs += replay.next().digest.pairs;
  benchmark::DoNotOptimize(pairs);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(n));
}
BENCHMARK(BM_ReplayFrameNaive)->Arg(100)->Arg(400)->Arg(1600)->Unit(benchmark::kMicrosecond);

}  // namespace
