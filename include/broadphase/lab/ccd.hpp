/// \file lab/ccd.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/ccd.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning "<broadphase/lab/ccd.hpp> is deprecated: include <broadphase/scenes/ccd.hpp>"
#endif
#include <broadphase/scenes/ccd.hpp>
