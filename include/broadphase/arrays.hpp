/// \file arrays.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/arrays/arrays.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning "<broadphase/arrays.hpp> is deprecated: include <broadphase/arrays/arrays.hpp>"
#endif
#include <broadphase/arrays/arrays.hpp>
