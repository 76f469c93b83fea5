// What the second core can give on this machine, whatever the structure:
// one pass over the same data done by one thread, then split in halves
// over two that start together and wait for each other (as the passes of
// grid-verlet's worker pool do), for a pass bound by arithmetic, by streaming
// memory and by scattered writes. The ratio of the times between the
// /1 and /2 variants is the ceiling for a pass of that kind here
// (docs/performance.md).
//
//   broadphase_bench --benchmark_filter=TwoCores --benchmark_repetitions=5
//                    --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <random>
#include <thread>
#include <vector>

namespace {

/// Runs job(0, 2) on the caller and job(1, 2) on a helper that polls for
/// work, and returns when both are done; or job(0, 1) alone.
class Halves {
 public:
  explicit Halves(int threads) : threads_(threads) {
    if (threads_ == 2)
      helper_ = std::jthread([this](std::stop_token st) {
        std::uint64_t seen = 0;
        while (!st.stop_requested()) {
          const std::uint64_t r = round_.load(std::memory_order_acquire);
          if (r == seen) continue;
          seen = r;
          (*job_)(1, 2);
          done_.store(r, std::memory_order_release);
        }
      });
  }
  void run(const std::function<void(int, int)>& job) {
    if (threads_ == 1) return job(0, 1);
    job_ = &job;
    const std::uint64_t r = round_.load(std::memory_order_relaxed) + 1;
    round_.store(r, std::memory_order_release);
    job(0, 2);
    while (done_.load(std::memory_order_acquire) != r) {
    }
  }

 private:
  int threads_;
  const std::function<void(int, int)>* job_ = nullptr;
  std::atomic<std::uint64_t> round_{0}, done_{0};
  std::jthread helper_;
};

// Records of a mover's size (its state and shape copy are 80 and 64 bytes).
struct Record {
  double v[16];
};

std::pair<std::size_t, std::size_t> half(std::size_t n, int k, int t) {
  return {n * static_cast<std::size_t>(k) / static_cast<std::size_t>(t),
          n * static_cast<std::size_t>(k + 1) / static_cast<std::size_t>(t)};
}

// Arithmetic only: dependent chains of multiply-adds.
void BM_TwoCoresArithmetic(benchmark::State& state) {
  Halves halves(static_cast<int>(state.range(0)));
  const std::size_t total = std::size_t{1} << 18;
  std::vector<double> out(2);
  const std::function<void(int, int)> job = [&](int k, int t) {
    const auto [lo, hi] = half(total, k, t);
    double x = 1;
    for (std::size_t i = lo; i < hi; ++i) x = x * 1.0000001 + 1e-9;
    out[static_cast<std::size_t>(k)] = x;
  };
  for (auto _ : state) halves.run(job);
  benchmark::DoNotOptimize(out.data());
}
BENCHMARK(BM_TwoCoresArithmetic)->Arg(1)->Arg(2)->UseRealTime();

// Each half reads and rewrites its records front to back (as a pass over
// the movers by ranges does). Args: KiB of records, threads.
void BM_TwoCoresStream(benchmark::State& state) {
  std::vector<Record> records(static_cast<std::size_t>(state.range(0)) * 1024 / sizeof(Record));
  Halves halves(static_cast<int>(state.range(1)));
  const std::function<void(int, int)> job = [&](int k, int t) {
    const auto [lo, hi] = half(records.size(), k, t);
    for (std::size_t i = lo; i < hi; ++i) {
      Record& r = records[i];
      for (int a = 0; a < 15; ++a) r.v[a] = r.v[a + 1] * 0.5 + 1.0;
    }
  };
  for (auto _ : state) {
    halves.run(job);
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(state.iterations() *
                          static_cast<std::int64_t>(records.size() * sizeof(Record)));
}
// 2.5, 5 and 64 MiB: within two second-level caches, over them, and beyond
// the third level.
BENCHMARK(BM_TwoCoresStream)->ArgsProduct({{2560, 5120, 65536}, {1, 2}})->UseRealTime();

// Each half takes its half of a list of writes to records at random (as
// moves in the caller's order, split in chunks, write the movers they
// name): each core writes lines the other wrote last.
void BM_TwoCoresScatter(benchmark::State& state) {
  std::vector<Record> records(static_cast<std::size_t>(state.range(0)) * 1024 / sizeof(Record));
  std::vector<std::uint32_t> targets(records.size());
  std::mt19937 rng(1);
  for (std::uint32_t& t : targets) t = static_cast<std::uint32_t>(rng() % records.size());
  Halves halves(static_cast<int>(state.range(1)));
  const std::function<void(int, int)> job = [&](int k, int t) {
    const auto [lo, hi] = half(targets.size(), k, t);
    for (std::size_t j = lo; j < hi; ++j) {
      Record& r = records[targets[j]];
      for (int a = 0; a < 6; ++a) r.v[a] = r.v[a + 1] * 0.5 + 1.0;
    }
  };
  for (auto _ : state) {
    halves.run(job);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(targets.size()));
}
BENCHMARK(BM_TwoCoresScatter)->ArgsProduct({{2560, 65536}, {1, 2}})->UseRealTime();

}  // namespace
