/// \file lab/scene.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/scene.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/lab/scene.hpp> is deprecated: include <broadphase/scenes/scene.hpp>"
#endif
#include <broadphase/scenes/scene.hpp>
