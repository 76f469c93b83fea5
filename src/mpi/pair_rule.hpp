// The rule that gives each pair one rank (mpi.hpp), applied to a
// pair of a rank's local objects: shared by Domain::find_pairs and
// PairTracker.
#pragma once

#include <algorithm>
#include <broadphase/mpi.hpp>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace broadphase::mpi::detail {

// Appends pair (i, j) of `local` (ids apart in `ids`) to `out` when rank
// `rank`'s subdomain holds max(lo_i, lo_j); `inside` says so without a
// look (one of the two lies in the subdomain, Partition::alone). Returns
// false, with `error` set, when the two ids are the same.
inline bool keep_pair(const Partition& partition, int rank, const GhostRecord* local,
                      const std::uint32_t* ids, std::size_t i, std::size_t j, bool inside,
                      std::vector<IdPair>& out, std::string& error) {
  if (!inside) {
    const Aabb bi = bounds(local[i].shape), bj = bounds(local[j].shape);
    const Vec3 at{std::max(bi.lo.x, bj.lo.x), std::max(bi.lo.y, bj.lo.y),
                  std::max(bi.lo.z, bj.lo.z)};
    if (!partition.holds(rank, at)) return true;
  }
  const std::uint32_t a = ids[i], b = ids[j];
  if (a == b) {
    error = "object id " + std::to_string(a) + " was passed on more than one rank or twice";
    return false;
  }
  out.push_back({std::min(a, b), std::max(a, b)});
  return true;
}

}  // namespace broadphase::mpi::detail
