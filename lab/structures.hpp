// The structures the lab measures and the CLI runs: every library structure
// plus the peer adapters that were built (lab/peers/). The lab's own, so
// that its code and the CLI's reach the same table without the lab
// including the CLI.
#pragma once

#include <broadphase/registry.hpp>

namespace broadphase::app {

/// Every library structure plus the peer adapters that were built.
const Registry& registry();

}  // namespace broadphase::app
