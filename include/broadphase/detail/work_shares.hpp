/// \file work_shares.hpp
/// How grid-verlet (grid_verlet.hpp) cuts a pass over its entries into
/// shares and chunks and runs them on its WorkerPool: the thread count and
/// grain of the structure's options, and the one rule every pass splits by
/// (contiguous ranges of about equal size), so that the parts (the level
/// grids, the Verlet lists) split their passes alike.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>

namespace broadphase::detail {

class WorkerPool;

/// Part k of [0, n) cut into `parts` contiguous ranges of about equal size.
struct Slice {
  std::size_t begin, end;
};
inline Slice slice(std::size_t n, unsigned k, unsigned parts) {
  return {n * k / parts, n * (k + 1) / parts};
}

/// The threads of a structure and how its passes are split over them.
/// Const members may run concurrently (a busy pool runs a second caller's
/// shares on that caller).
class WorkShares {
 public:
  /// Work split over threads comes in this many chunks per thread, taken by
  /// whichever thread is free (renewals and list lengths are uneven).
  static constexpr unsigned kChunksPerShare = 8;
  /// The most threads: a chunk's mark (in grid-verlet's bulk update) holds
  /// its chunk in 10 bits, which more than 128 threads would overflow.
  static constexpr unsigned kMaxThreads = 64;

  /// `threads` >= 1 (a pool of threads - 1 workers when more than one);
  /// `grain` >= 1: entries per share at least.
  WorkShares(unsigned threads, std::size_t grain);
  ~WorkShares();
  WorkShares(const WorkShares&) = delete;
  WorkShares& operator=(const WorkShares&) = delete;

  /// The threads passes use.
  unsigned threads() const { return threads_; }
  /// Shares for a pass over that many entries: one per thread, but at
  /// least `grain` entries each.
  unsigned shares_for(std::size_t entries) const {
    const std::size_t by_grain = entries / grain_;
    return static_cast<unsigned>(by_grain < 1 ? 1 : (by_grain < threads_ ? by_grain : threads_));
  }
  /// Chunks for a pass over that many entries: several per share, taken by
  /// whichever thread is free, so that a thread slowed down (by the host,
  /// on a virtual machine) leaves its part to the others.
  unsigned chunks_for(std::size_t entries) const {
    const unsigned t = shares_for(entries);
    return t <= 1 ? 1 : t * kChunksPerShare;
  }
  /// Runs job(k) once for every k in [0, shares), each taken by whichever
  /// of the caller and the pool's workers is free; without workers, in
  /// order on the caller. The work of a share depends on k alone, so
  /// results merged in share order do not depend on the thread count.
  void run(unsigned shares, const std::function<void(unsigned)>& job) const;

 private:
  unsigned threads_;
  std::size_t grain_;
  std::unique_ptr<WorkerPool> pool_;
};

}  // namespace broadphase::detail
