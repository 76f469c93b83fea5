/// \file engine.hpp
/// The neighbour-list engine's binned points, candidate runs and found
/// records (neighbours.cpp), which its AVX-512 passes (vector_pass.cpp)
/// read and write too: private to the library.
#pragma once

#include <array>
#include <broadphase/neighbours.hpp>
#include <cstdint>
#include <vector>

namespace broadphase::neighbours_detail {

/// The points sorted by bin: wrapped positions and cutoff (prefilter), the
/// position as given, wrap counts and id (the exact rule).
struct Binned {
  std::vector<std::int64_t> start;  // bins + 1
  // Wrapped positions and cutoffs (cutoffs only for per-point ones), a
  // column each: the vector search reads eight candidates at a time.
  NeighbourVector<double> wx, wy, wz, wc;
  NeighbourVector<Vec3> x;
  NeighbourVector<std::array<std::int32_t, 3>> n;
  NeighbourVector<std::uint32_t> id;
};

/// A neighbour as found for the point whose group it is in: its index and
/// the shift on it, in one of two layouts that order alike (by index, then
/// shift). Packed: 8 bytes, one integer key, for shifts in [-127, 127] on
/// every axis (whenever the points lie within 100 cells of the cell and the
/// cutoff spans fewer than 100 cells: at 10^6 points, halving the records
/// took a fifth off the list, and the groups sort by comparing one
/// integer). Wide: 16 bytes, any shift.
struct PackedFound {
  std::uint64_t key;
  static constexpr std::int64_t kLimit = 127;
  static PackedFound make(std::uint32_t j, const std::int64_t s[3]) {
    return {std::uint64_t{j} << 32 | static_cast<std::uint64_t>(s[0] + 128) << 16 |
            static_cast<std::uint64_t>(s[1] + 128) << 8 | static_cast<std::uint64_t>(s[2] + 128)};
  }
  std::uint32_t j() const { return static_cast<std::uint32_t>(key >> 32); }
  std::int64_t s(int a) const {
    return static_cast<std::int64_t>((key >> (16 - 8 * a)) & 0xff) - 128;
  }
  bool operator<(const PackedFound& o) const { return key < o.key; }
};

struct WideFound {
  std::uint32_t j_;
  std::int32_t s_[3];
  static WideFound make(std::uint32_t j, const std::int64_t s[3]) {
    return {j,
            {static_cast<std::int32_t>(s[0]), static_cast<std::int32_t>(s[1]),
             static_cast<std::int32_t>(s[2])}};
  }
  std::uint32_t j() const { return j_; }
  std::int64_t s(int a) const { return s_[a]; }
  bool operator<(const WideFound& o) const {
    if (j_ != o.j_) return j_ < o.j_;
    if (s_[0] != o.s_[0]) return s_[0] < o.s_[0];
    if (s_[1] != o.s_[1]) return s_[1] < o.s_[1];
    return s_[2] < o.s_[2];
  }
};

/// The candidates of a home bin's neighbourhood as runs of bins that are
/// consecutive on the last axis and seen under one wrap shift: slots
/// [lo, hi), moved by `off` = image_offset(sb).
struct Run {
  std::uint32_t lo, hi;
  std::array<std::int32_t, 3> sb;
  Vec3 off;
};

}  // namespace broadphase::neighbours_detail
