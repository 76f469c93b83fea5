/// \file in_order.hpp
/// The library's one in-order joiner. Pieces of work numbered 0, 1, ... are
/// made on several threads and their results joined in that order, so that
/// results never depend on the thread count. Two ways to join:
///
/// - `InOrder::finish`: whichever thread makes a piece joins, under a lock,
///   every made piece that is next in order (grid-verlet's passes on its
///   worker pool, worker_pool.hpp);
/// - `run_in_order`: threads started for one pass make fixed chunks, and
///   the calling thread joins each chunk in order as soon as it and every
///   chunk before it are made (the lean path, whose sink runs on the
///   caller's thread and may stop the pass).
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>
#include <vector>

namespace broadphase::detail {

/// The threads a call asked for: `requested`, or every core for 0 (the
/// library's `threads` options and arguments).
inline unsigned thread_count(unsigned requested) {
  if (requested != 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

/// Which of `pieces` pieces are made, and which is joined next.
class InOrder {
 public:
  explicit InOrder(std::size_t pieces) : made_(pieces, 0) {}

  /// Marks `piece` made and joins (`join(j)`, on this thread, under the
  /// lock) every made piece that is next in order. Each thread that
  /// finishes a piece joins what it can, so no made piece waits for more
  /// than the lock, and the last piece made leaves none unjoined.
  template <class F>
  void finish(std::size_t piece, F&& join) {
    std::lock_guard hold(m_);
    made_[piece] = 1;
    for (; next_ < made_.size() && made_[next_]; ++next_) join(next_);
  }

  /// Marks `piece` made, for a thread that joins in `wait`.
  void made(std::size_t piece) {
    {
      std::lock_guard hold(m_);
      made_[piece] = 1;
    }
    ready_.notify_all();
  }
  /// Whether `piece` is made.
  bool is_made(std::size_t piece) {
    std::lock_guard hold(m_);
    return made_[piece] != 0;
  }
  /// Waits until `piece` is made.
  void wait(std::size_t piece) {
    std::unique_lock hold(m_);
    ready_.wait(hold, [&] { return made_[piece] != 0; });
  }

 private:
  std::mutex m_;
  std::condition_variable ready_;
  std::vector<char> made_;
  std::size_t next_ = 0;
};

/// Items per chunk of `run_in_order`: fixed, so the chunks (and so the
/// order of everything derived from them) never depend on the thread count.
inline constexpr std::size_t kChunkItems = 4096;

/// A pass over [0, n) in chunks of kChunkItems on `threads` threads (the
/// calling thread included, which joins): `produce(begin, end, result)`
/// fills `result` (a default-constructed R, reused between chunks on one
/// thread) for items [begin, end); `deliver(result)` receives the chunks'
/// results in order on the calling thread and returns false to stop (the
/// chunks not yet started are then skipped). Returns false when stopped.
/// Threads are started for the pass and joined before it returns, however
/// it is left (a deliver that throws included).
template <class R, class Produce, class Deliver>
bool run_in_order(std::size_t n, unsigned threads, Produce&& produce, Deliver&& deliver) {
  const std::size_t chunks = (n + kChunkItems - 1) / kChunkItems;
  auto range = [&](std::size_t c, std::size_t& b, std::size_t& e) {
    b = c * kChunkItems;
    e = std::min(n, b + kChunkItems);
  };
  if (threads <= 1 || chunks <= 1) {
    R r;
    for (std::size_t c = 0; c < chunks; ++c) {
      std::size_t b, e;
      range(c, b, e);
      produce(b, e, r);
      if (!deliver(r)) return false;
    }
    return true;
  }
  std::vector<R> results(chunks);
  InOrder order(chunks);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  auto work_one = [&]() -> bool {
    const std::size_t c = next.fetch_add(1);
    if (c >= chunks) return false;
    if (!stop.load(std::memory_order_relaxed)) {
      std::size_t b, e;
      range(c, b, e);
      produce(b, e, results[c]);
    }
    order.made(c);
    return true;
  };
  std::vector<std::thread> workers;
  struct Joiner {
    std::vector<std::thread>& workers;
    std::atomic<bool>& stop;
    ~Joiner() {
      stop = true;
      for (auto& w : workers)
        if (w.joinable()) w.join();
    }
  } joiner{workers, stop};
  const unsigned extra = static_cast<unsigned>(std::min<std::size_t>(threads - 1, chunks - 1));
  for (unsigned t = 0; t < extra; ++t)
    workers.emplace_back([&] {
      while (work_one()) {
      }
    });
  bool ok = true;
  for (std::size_t c = 0; c < chunks; ++c) {
    // The calling thread produces while the chunk it must hand over next is
    // not ready, and waits only when nothing is left to take.
    while (!order.is_made(c))
      if (!work_one()) {
        order.wait(c);
        break;
      }
    if (ok && !deliver(results[c])) {
      ok = false;
      stop = true;
    }
    results[c] = R{};
  }
  return ok;
}

}  // namespace broadphase::detail
