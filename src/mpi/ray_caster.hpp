// Domain's ray caster (rays.cpp), here so that every file that builds or
// destroys a Domain sees it whole.
#pragma once

#include <broadphase/mpi.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace broadphase::mpi {

// This rank's objects in a structure of Options::ray_algo, kept between
// ray calls with what each was given last (by global id), so that a call
// inserts the objects that arrived, removes those that left and moves
// those whose shape changed, as one process's replay keeps its structure.
struct Domain::RayCaster {
  struct Entry {
    Handle handle;
    Shape shape;
    std::uint32_t group = 0;
    std::uint64_t call = 0;  ///< the last call that passed it
  };
  std::unique_ptr<AnyBroadPhase> structure;
  std::unordered_map<std::uint32_t, Entry> by_id;
  std::vector<std::uint32_t> id_of_slot;
  std::uint64_t calls = 0;
  std::uint32_t id(Handle h) const { return id_of_slot[h.index]; }
};

}  // namespace broadphase::mpi
