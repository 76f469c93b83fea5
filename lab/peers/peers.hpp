// The peer libraries' broad phases, behind AnyBroadPhase, for comparison.
#pragma once

#include <broadphase/registry.hpp>

namespace broadphase::app {

/// Adds every peer adapter that was built (marked `peer` in the registry).
void register_peers(Registry& r);

}  // namespace broadphase::app
