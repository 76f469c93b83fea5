// Each family of structures registers itself from its own folder, so that
// adding a structure touches only that family's files.
#pragma once

#include <broadphase/registry.hpp>
#include <memory>

namespace broadphase::detail {

void register_study(Registry& r);  // src/study: naive, octree-paper, hgrid-paper
void register_grids(Registry& r);  // src/grids: the uniform and hierarchical grids
void register_trees(Registry& r);  // src/trees: octrees, k-d tree, sweeps, AABB tree
void register_fast(Registry& r);   // src/fast: the performance-tuned structures

/// Registers a structure type whose constructor takes a Config.
template <class S>
void add_structure(Registry& r, std::string name, std::string description) {
  r.add({std::move(name), std::move(description), false,
         [](const Config& c) -> std::unique_ptr<AnyBroadPhase> {
           return std::make_unique<Erased<S>>(c);
         }});
}

}  // namespace broadphase::detail
