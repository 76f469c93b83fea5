/// \file lab/replay.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/replay.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/lab/replay.hpp> is deprecated: include <broadphase/scenes/replay.hpp>"
#endif
#include <broadphase/scenes/replay.hpp>
