#include <broadphase/detail/worker_pool.hpp>

namespace broadphase::detail {

// Polls `ready` until it holds (true) or kSpin has passed (false).
template <class F>
bool WorkerPool::spin_until(F ready) {
  const auto until = std::chrono::steady_clock::now() + kSpin;
  for (unsigned k = 1;; ++k) {
    if (ready()) return true;
    if (k % 64 == 0 && std::chrono::steady_clock::now() > until) return false;
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#else
    std::this_thread::yield();
#endif
  }
}

WorkerPool::WorkerPool(unsigned workers) {
  for (unsigned w = 0; w < workers; ++w) threads_.emplace_back([this] { loop(); });
}
WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(m_);
    stopping_.store(true, std::memory_order_relaxed);
    round_.fetch_add(1, std::memory_order_release);
  }
  wake_.notify_all();
  threads_.clear();  // joins
}

void WorkerPool::run(unsigned shares, const std::function<void(unsigned)>& job) {
  std::unique_lock busy(run_mutex_, std::try_to_lock);
  if (!busy.owns_lock() || shares <= 1) {
    for (unsigned k = 0; k < shares; ++k) job(k);
    return;
  }
  {
    // The job and its share count are published by opening the run; they
    // change only here, while no worker is in a run.
    std::lock_guard lock(m_);
    job_ = &job;
    shares_ = shares;
    next_.store(0, std::memory_order_relaxed);
    open_.store(true, std::memory_order_seq_cst);
    round_.fetch_add(1, std::memory_order_release);
  }
  wake_.notify_all();
  for (unsigned k; (k = next_.fetch_add(1, std::memory_order_relaxed)) < shares;) job(k);
  // Closing and entering are ordered (sequentially consistent): a worker
  // that enters after the close sees it and leaves without touching the
  // job; one that entered before is counted, and waited for.
  open_.store(false, std::memory_order_seq_cst);
  auto done = [&] { return inside_.load(std::memory_order_seq_cst) == 0; };
  if (!spin_until(done)) {
    std::unique_lock lock(m_);
    done_.wait(lock, done);
  }
}

void WorkerPool::loop() {
  std::uint64_t seen = 0;
  for (;;) {
    auto fresh = [&] { return round_.load(std::memory_order_acquire) != seen; };
    if (!spin_until(fresh)) {
      std::unique_lock lock(m_);
      wake_.wait(lock, fresh);
    }
    seen = round_.load(std::memory_order_acquire);
    if (stopping_.load(std::memory_order_relaxed)) return;
    inside_.fetch_add(1, std::memory_order_seq_cst);
    if (open_.load(std::memory_order_seq_cst)) {
      const unsigned shares = shares_;
      for (unsigned k; (k = next_.fetch_add(1, std::memory_order_relaxed)) < shares;) (*job_)(k);
    }
    if (inside_.fetch_sub(1, std::memory_order_seq_cst) == 1) {
      // The caller may be asleep: notify under the lock it checks under.
      std::lock_guard lock(m_);
      done_.notify_one();
    }
  }
}

}  // namespace broadphase::detail
