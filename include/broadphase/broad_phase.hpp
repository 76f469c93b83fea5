/// \file broad_phase.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/structure.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning "<broadphase/broad_phase.hpp> is deprecated: include <broadphase/structure.hpp>"
#endif
#include <broadphase/structure.hpp>
