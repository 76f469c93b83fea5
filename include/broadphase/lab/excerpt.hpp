/// \file lab/excerpt.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/excerpt.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/lab/excerpt.hpp> is deprecated: include <broadphase/scenes/excerpt.hpp>"
#endif
#include <broadphase/scenes/excerpt.hpp>
