/// \file frame.hpp
/// The frame of a neighbour cell (neighbours.cpp), and the other pieces the
/// one-shot lists share with the moving list (moving.cpp): private to the
/// library.
#pragma once

#include <algorithm>
#include <array>
#include <broadphase/detail/in_order.hpp>
#include <broadphase/neighbours.hpp>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace broadphase::neighbours_detail {

/// The frame the bins are laid in: the periodic cell vectors, completed by
/// unit vectors orthogonal to them on the axes that are not periodic.
/// Fractional coordinate k of x is dot(x, col_k); a displacement of length r
/// moves it by at most r * |col_k| (`spread[k]`).
struct Frame {
  std::array<Vec3, 3> col{};
  std::array<double, 3> spread{};
};

/// `v` with 17 significant digits, for messages.
std::string number(double v);

/// The frame of `cell`; throws InvalidNeighbourInput for vectors that are
/// not finite, zero or linearly dependent on the periodic axes.
Frame make_frame(const NeighbourCell& cell);

/// Throws InvalidNeighbourInput naming `name` unless `v` is finite and >= 0
/// (a cutoff or a skin).
void check_cutoff(double v, const std::string& name);

/// neighbour_list's pairs with `options` (rule, full, self_interaction,
/// threads; the quantities are not made) as point i's candidates
/// [offsets[i], offsets[i + 1]) of the result: one `cutoff`, or per-point
/// `cutoffs` when not null. Throws as neighbour_list does.
NeighbourVector<Candidate> candidate_list(const NeighbourPoints& points, const NeighbourCell& cell,
                                          double cutoff, const arrays::Column* cutoffs,
                                          const NeighbourOptions& options,
                                          NeighbourVector<std::int64_t>& offsets);

/// Whether this processor can run the self search's AVX-512 kernel.
bool vector_search_available();
/// Whether the self search uses it: available and allowed.
bool vector_search();
/// Allows (the default) or forbids it, for every later call in the process:
/// the tests compare the two searches. Not to be called while a list is
/// being made.
void allow_vector_search(bool allow);

/// Reserves room for `count` elements of a large array that is written
/// once, asking the kernel for huge pages on the part the new buffer spans
/// (Linux; a hint, ignored elsewhere or when they are off).
template <class T, class A>
void reserve_large(std::vector<T, A>& v, std::size_t count) {
  v.reserve(count);
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHuge = std::uintptr_t{1} << 21;
  const auto begin = reinterpret_cast<std::uintptr_t>(v.data());
  const std::uintptr_t lo = (begin + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t hi = (begin + count * sizeof(T)) & ~(kHuge - 1);
  if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
#endif
}

/// Sizes `v` to `count` elements (capacity on huge pages when it has to
/// grow): the engine's arrays of a value or a few a point, written once.
template <class T, class A>
void resize_large(std::vector<T, A>& v, std::size_t count) {
  if (v.capacity() < count) {
    std::vector<T, A>().swap(v);
    reserve_large(v, count);
  }
  v.resize(count);
}

/// How many parts (threads) a call of `items` points or queries takes:
/// `threads` (0: every core), at most one a 16 384 items (a thread costs
/// tens of microseconds to start).
inline unsigned parts_for(std::size_t items, unsigned threads) {
  const unsigned want = broadphase::detail::thread_count(threads);
  const std::size_t most = std::max<std::size_t>(1, items / 16384);
  return static_cast<unsigned>(std::min<std::size_t>({want, most, 256}));
}

/// Runs job(p) for every part p in [0, parts), part 0 on the calling thread
/// and each other on a thread of its own; rethrows the first part's error.
template <class Job>
void run_parts(unsigned parts, Job&& job) {
  if (parts <= 1) {
    job(0u);
    return;
  }
  std::vector<std::exception_ptr> errors(parts);
  const auto guarded = [&](unsigned p) {
    try {
      job(p);
    } catch (...) {
      errors[p] = std::current_exception();
    }
  };
  {
    std::vector<std::jthread> pool;
    pool.reserve(parts - 1);
    for (unsigned p = 1; p < parts; ++p) pool.emplace_back(guarded, p);
    guarded(0u);
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace broadphase::neighbours_detail
