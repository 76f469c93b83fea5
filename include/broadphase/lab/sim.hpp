/// \file lab/sim.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/sim.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning "<broadphase/lab/sim.hpp> is deprecated: include <broadphase/scenes/sim.hpp>"
#endif
#include <broadphase/scenes/sim.hpp>
