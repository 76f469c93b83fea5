/// \file thread_clock.hpp
/// The calling thread's CPU time, for the lab's and the benchmarks'
/// timings: the development hosts are 2-core machines shared with other
/// builds (load 10 to 20 and more), where a wall-clock interval mostly
/// charges whichever run was descheduled; one thread's CPU time is what
/// the work itself costs.
#pragma once

#include <ctime>

namespace broadphase::detail {

/// A clock in milliseconds of the calling thread's CPU time.
struct ThreadClock {
  using time_point = double;
  static double now() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
  }
};

/// Milliseconds of the calling thread's CPU time since `t0` (ThreadClock::now()).
inline double thread_ms_since(double t0) { return ThreadClock::now() - t0; }

}  // namespace broadphase::detail
