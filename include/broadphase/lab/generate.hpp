/// \file lab/generate.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/generate.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/lab/generate.hpp> is deprecated: include <broadphase/scenes/generate.hpp>"
#endif
#include <broadphase/scenes/generate.hpp>
