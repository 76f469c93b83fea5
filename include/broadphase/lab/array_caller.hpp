/// \file lab/array_caller.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/array_caller.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/lab/array_caller.hpp> is deprecated: include <broadphase/scenes/array_caller.hpp>"
#endif
#include <broadphase/scenes/array_caller.hpp>
