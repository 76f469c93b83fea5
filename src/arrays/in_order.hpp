// Runs a pass over [0, n) in fixed chunks on several threads and hands each
// chunk's result over in chunk order, as soon as it and every chunk before
// it are done, so that the result does not depend on the thread count.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>
#include <vector>

namespace broadphase::detail {

/// Items per chunk: fixed, so the chunks (and so the order of everything
/// derived from them) never depend on the thread count.
inline constexpr std::size_t kChunkItems = 4096;

/// `produce(begin, end, result)` fills `result` (a default-constructed R,
/// reused between chunks on one thread) for items [begin, end);
/// `deliver(result)` receives the chunks' results in order and returns
/// false to stop (the chunks not yet started are then skipped). Returns
/// false when stopped. `threads` includes the calling thread, which
/// delivers.
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
  std::vector<char> done(chunks, 0);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex m;
  std::condition_variable cv;
  auto work_one = [&]() -> bool {
    const std::size_t c = next.fetch_add(1);
    if (c >= chunks) return false;
    if (!stop.load(std::memory_order_relaxed)) {
      std::size_t b, e;
      range(c, b, e);
      produce(b, e, results[c]);
    }
    {
      std::lock_guard<std::mutex> lock(m);
      done[c] = 1;
    }
    cv.notify_all();
    return true;
  };
  std::vector<std::thread> workers;
  // Joins the workers however this function is left (a sink may throw).
  struct Joiner {
    std::vector<std::thread>& workers;
    std::atomic<bool>& stop;
    ~Joiner() {
      stop = true;
      for (auto& w : workers)
        if (w.joinable()) w.join();
    }
  } joiner{workers, stop};
  const unsigned extra = std::min<std::size_t>(threads - 1, chunks - 1);
  for (unsigned t = 0; t < extra; ++t)
    workers.emplace_back([&] {
      while (work_one()) {
      }
    });
  bool ok = true;
  for (std::size_t c = 0; c < chunks; ++c) {
    // The calling thread produces while the chunk it must hand over next is
    // not ready, and waits only when nothing is left to take.
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(m);
        if (done[c]) break;
      }
      if (!work_one()) {
        std::unique_lock<std::mutex> lock(m);
        cv.wait(lock, [&] { return done[c] != 0; });
        break;
      }
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
