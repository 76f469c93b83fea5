/// \file verlet_lists.hpp
/// The records of grid-verlet's moving objects (grid_verlet.hpp): each
/// mover's fat box and where its candidate lists are, and the entries of a
/// fixed-candidate list. The lists hold, like a Verlet neighbour list in
/// molecular dynamics, every object near a box grown by a margin, so that
/// while an object stays inside its box a frame tests its lists alone.
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <cstdint>

namespace broadphase::detail {

/// Per moving-grid entry (in the same order): its bounds now, the "fat"
/// box its lists cover (which is also its grid entry's box), where its
/// lists are, and its last displacement. Lists stay valid while the
/// bounds stay inside the fat box; then the box and lists are renewed.
struct VerletMover {
  AabbF cur;
  AabbF fat;
  std::uint32_t list_begin = 0, list_count = 0;  // fixed candidates, in list_pool_
  std::uint32_t near_begin = 0, near_count = 0;  // moving neighbours, in near_pool_
  std::uint32_t epoch = 0;                       // fixed-grid epoch of the lists; 0: renewal due
  std::uint32_t stamp = 0;                       // the rebuild that last renewed them
  float speed = 0;
  bool fast = false;    // too fast for a margin: probes the moving grid each frame
  bool guessed = true;  // the fat box was made before the speed was known
};

/// One fixed object in a candidate list: a copy of its sphere (so that a
/// frame reads lists front to back, never the fixed grid) and its handle.
/// A box has a NaN radius and is tested from the grid's shape copy.
struct VerletCandidate {
  double c[3];
  double r;
  Handle handle;
};
static_assert(sizeof(VerletCandidate) == 40, "candidates are packed for the list scans");

}  // namespace broadphase::detail
