// Microbenchmarks of the study's structures: the octree's node choice and
// descent, the hashed grid's placement and cell probes, and one query per
// structure on the study's 6400-object uneven scene.
#include <benchmark/benchmark.h>

#include <broadphase/naive.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/study/hgrid_paper.hpp>
#include <broadphase/study/octree_paper.hpp>
#include <vector>

namespace {

using namespace broadphase;

const Scene& uneven_6400() {
  static const Scene s = generate(Distribution::uneven, 6400, 1);
  return s;
}

// Inserts every object of `s`, with its index as user data.
template <class S>
std::vector<Handle> insert_all(S& bp, const Scene& s) {
  std::vector<Handle> hs;
  for (std::size_t i = 0; i < s.size(); ++i) hs.push_back(bp.insert(s.objects[i], i));
  return hs;
}

// 1024 points drawn uniformly in the cube [lo, hi)^3.
std::vector<Shape> points_in(double lo, double hi) {
  Rng rng(3);
  std::vector<Shape> points;
  for (int i = 0; i < 1024; ++i)
    points.push_back(
        Shape::sphere({rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi)}, 0));
  return points;
}

// One query per iteration, cycling through `points`.
template <class S>
void query_points(benchmark::State& state, const S& bp, const std::vector<Shape>& points) {
  std::size_t i = 0, hits = 0;
  for (auto _ : state) bp.query(points[i++ & 1023], [&](Handle) { ++hits; });
  benchmark::DoNotOptimize(hits);
}

// Removes an object and inserts it back, per iteration, so that the
// structure keeps its population.
template <class S>
void remove_insert(benchmark::State& state, S& bp, const Scene& s) {
  std::vector<Handle> hs = insert_all(bp, s);
  std::size_t i = 0;
  for (auto _ : state) {
    const std::size_t k = i++ % s.size();
    bp.remove(hs[k]);
    hs[k] = bp.insert(s.objects[k], k);
  }
}

// The O(1) node choice from the corners' finest cells.
void BM_OctreeNodeOf(benchmark::State& state) {
  const Scene& s = uneven_6400();
  const OctreePaper t{Config{}};
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(t.node_of(s.objects[i++ % s.size()]));
}
BENCHMARK(BM_OctreeNodeOf);

// Points in the world: the descent from the root to one finest cell,
// testing the objects of every node on the way.
void BM_OctreeNodeDescent(benchmark::State& state) {
  const Scene& s = uneven_6400();
  OctreePaper t{Config{}};
  insert_all(t, s);
  query_points(state, t, points_in(0, 1000));
}
BENCHMARK(BM_OctreeNodeDescent);

// Removal as the study measured it: find the node, search its list. Every
// object goes back in, so the lists keep their lengths.
void BM_OctreeRemoveInsert(benchmark::State& state) {
  const Scene& s = uneven_6400();
  OctreePaper t{Config{}};
  remove_insert(state, t, s);
}
BENCHMARK(BM_OctreeRemoveInsert);

// Level choice and cell coordinates of one object.
void BM_HGridPlacement(benchmark::State& state) {
  const Scene& s = uneven_6400();
  const HGridPaper g{Config{}};
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(g.level_of(s.objects[i++ % s.size()]));
}
BENCHMARK(BM_HGridPlacement);

// Points in the world: one cell per non-empty level hashed, its bucket
// walked and its objects tested (a coarse cell holds hundreds).
void BM_HGridPointQuery(benchmark::State& state) {
  const Scene& s = uneven_6400();
  HGridPaper g{Config{}};
  insert_all(g, s);
  query_points(state, g, points_in(0, 1000));
}
BENCHMARK(BM_HGridPointQuery);

// Points outside the world, in empty cells: only the hashing and the walk
// past other cells' entries in the bucket, once per non-empty level.
void BM_HGridCellHashing(benchmark::State& state) {
  const Scene& s = uneven_6400();
  HGridPaper g{Config{}};
  insert_all(g, s);
  query_points(state, g, points_in(3000, 9000));
}
BENCHMARK(BM_HGridCellHashing);

// Removal through the remembered bucket, and the insertion back.
void BM_HGridRemoveInsert(benchmark::State& state) {
  const Scene& s = uneven_6400();
  HGridPaper g{Config{}};
  remove_insert(state, g, s);
}
BENCHMARK(BM_HGridRemoveInsert);

// One query with each object's own shape in turn, on the 6400 uneven scene.
template <class S>
void BM_QueryUneven6400(benchmark::State& state) {
  const Scene& s = uneven_6400();
  S bp{Config{}};
  insert_all(bp, s);
  std::size_t i = 0, hits = 0, tests = 0;
  for (auto _ : state) tests += bp.query(s.objects[i++ % s.size()], [&](Handle) { ++hits; }).tests;
  state.counters["tests/query"] =
      benchmark::Counter(static_cast<double>(tests), benchmark::Counter::kAvgIterations);
  benchmark::DoNotOptimize(hits);
}
BENCHMARK(BM_QueryUneven6400<Naive>)->Name("BM_QueryUneven6400/naive");
BENCHMARK(BM_QueryUneven6400<OctreePaper>)->Name("BM_QueryUneven6400/octree-paper");
BENCHMARK(BM_QueryUneven6400<HGridPaper>)->Name("BM_QueryUneven6400/hgrid-paper");

}  // namespace
