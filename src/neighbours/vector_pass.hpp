/// \file vector_pass.hpp
/// The neighbour search's candidate passes with AVX-512 (vector_pass.cpp),
/// which neighbours.cpp's self search calls in place of its scalar loop
/// where the processor has them (vector_search, frame.hpp): private to the
/// library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine.hpp"

// The passes exist for GCC and Clang on x86-64; elsewhere only the scalar
// loop does.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define BROADPHASE_NEIGHBOURS_AVX512 1
#else
#define BROADPHASE_NEIGHBOURS_AVX512 0
#endif

namespace broadphase::neighbours_detail {

/// A point's reaches for a vector pass: with one cutoff (`one`), its reach
/// and inner reach squared; otherwise the point's own cutoff `cp`, each
/// pair's reach being (cp + c_q) + margin and its inner reach
/// max(0, (cp + c_q) - margin).
struct VectorReaches {
  bool one;
  double reach2, inner2;
  double cp, margin;
};

#if BROADPHASE_NEIGHBOURS_AVX512
/// The picks (run << 32 | slot) of the candidates within reach of the
/// point at (px, py, pz) that the scalar loop would pick (in a half list,
/// an index at least `ip`), in its order; writes up to 8 entries past them.
/// Only where vector_search_available().
std::size_t pick_avx512(const Binned& b, const std::vector<Run>& runs, double px, double py,
                        double pz, const VectorReaches& v, std::uint32_t ip, bool full,
                        std::uint64_t* pick);

/// Where every point lies in the cell: the records of the pairs inside the
/// inner reach that the point keeps, at `keys` (returned: how many), and
/// the other candidates the scalar loop would pick, at `pick` (`picked`:
/// how many); up to 8 entries past each. Only where
/// vector_search_available().
std::size_t records_avx512(const Binned& b, const std::vector<Run>& runs, double px, double py,
                           double pz, const VectorReaches& v, std::uint32_t ip, bool full,
                           PackedFound* keys, std::uint64_t* pick, std::size_t& picked);
#endif

}  // namespace broadphase::neighbours_detail
