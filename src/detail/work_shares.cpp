#include <broadphase/detail/work_shares.hpp>
#include <broadphase/detail/worker_pool.hpp>

namespace broadphase::detail {

WorkShares::WorkShares(unsigned threads, std::size_t grain)
    : threads_(threads < 1 ? 1 : threads), grain_(grain < 1 ? 1 : grain) {
  if (threads_ > 1) pool_ = std::make_unique<WorkerPool>(threads_ - 1);
}

WorkShares::~WorkShares() = default;

void WorkShares::run(unsigned shares, const std::function<void(unsigned)>& job) const {
  if (shares <= 1 || !pool_) {
    for (unsigned k = 0; k < shares; ++k) job(k);
    return;
  }
  pool_->run(shares, job);
}

}  // namespace broadphase::detail
