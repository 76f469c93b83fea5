/// \file worker_pool.hpp
/// Threads kept by a structure for its whole life (their results are joined
/// in order by in_order.hpp's InOrder): the engine under a structure's parallel passes
/// (grid-verlet's bulk update and find_pairs). Results never depend on the
/// thread count: work is cut into pieces by index, and pieces' results are
/// joined in index order.
#pragma once

#include <atomic>
#include <broadphase/detail/in_order.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace broadphase::detail {

/// Worker threads kept for the structure's lifetime: run(shares, job) runs
/// job(k) once for every k in [0, shares), each share taken by whichever of
/// the caller and the workers is free, and returns when all are done. One
/// run at a time; a caller that finds the pool busy (another thread's const
/// call) runs every share itself.
///
/// A frame makes about a dozen runs a fraction of a millisecond apart, and
/// waking a sleeping thread costs about 70 µs here (a round trip through a
/// condition variable). So a worker that finished a job, and a caller that
/// waits for the workers, first poll for a while (kSpin) and only then
/// sleep: runs within a frame find the workers awake, and an idle structure
/// costs nothing once its workers have gone to sleep. The first run after
/// a pause does not wait for them either: the caller takes shares until
/// none is left and then closes the run, so a worker still waking up finds
/// it closed (or joins in time to take shares) instead of holding it up.
class WorkerPool {
 public:
  /// Starts `workers` threads, which sleep until the first run.
  explicit WorkerPool(unsigned workers);
  /// Stops and joins the workers.
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Runs job(k) once for every k in [0, shares) and returns when all are
  /// done. Thread-safe: a second concurrent caller runs its shares alone.
  void run(unsigned shares, const std::function<void(unsigned)>& job);
  /// The threads a run can use: the workers and the caller.
  unsigned capacity() const { return static_cast<unsigned>(threads_.size()) + 1; }

 private:
  static constexpr std::chrono::microseconds kSpin{500};

  /// Polls `ready` until it holds (true) or kSpin has passed (false).
  template <class F>
  static bool spin_until(F ready);
  void loop();

  std::mutex run_mutex_;
  std::mutex m_;
  std::condition_variable wake_, done_;
  const std::function<void(unsigned)>* job_ = nullptr;
  unsigned shares_ = 0;
  std::atomic<unsigned> next_{0};    // the next share to take
  std::atomic<unsigned> inside_{0};  // workers in the run
  std::atomic<bool> open_{false};    // shares may still be taken
  std::atomic<std::uint64_t> round_{0};
  std::atomic<bool> stopping_{false};
  std::vector<std::jthread> threads_;
};

}  // namespace broadphase::detail
