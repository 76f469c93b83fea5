// The rule that gives each pair one rank (mpi.hpp), applied to a
// pair of a rank's local objects: shared by Domain::find_pairs and
// PairTracker.
#pragma once

#include <algorithm>
#include <broadphase/mpi.hpp>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace broadphase::mpi::detail {

// The error for filter columns that do not fit `count` objects (both empty
// or both `count` long), or "" when they fit.
inline std::string filter_columns_error(int rank, std::span<const std::uint32_t> groups,
                                        std::span<const std::uint32_t> masks, std::size_t count) {
  if ((groups.empty() && masks.empty()) || (groups.size() == count && masks.size() == count))
    return {};
  return "rank " + std::to_string(rank) + ": " + std::to_string(groups.size()) + " groups and " +
         std::to_string(masks.size()) + " masks for " + std::to_string(count) +
         " objects (both empty, or one of each per object)";
}

// Object i's filter from optional columns (checked above).
inline Filter filter_at(std::span<const std::uint32_t> groups, std::span<const std::uint32_t> masks,
                        std::size_t i) {
  return groups.empty() ? Filter{} : Filter{groups[i], masks[i]};
}

// Appends pair (i, j) of `local` (ids apart in `ids`) to `out` when rank
// `rank`'s subdomain holds max(lo_i, lo_j); `inside` says so without a
// look (one of the two lies in the subdomain, Partition::alone). Returns
// false, with `error` set, when the two ids are the same.
//
// The collision filters are applied before this, inside the local search
// (the lean path's columns, or the structure's set_filter): every record
// carries its object's filter to every rank that holds a copy, so the rank
// that owns max(lo_i, lo_j) tests both objects' own bits, and a pair they
// rule out is reported by no rank (the others drop it here whatever it is).
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
