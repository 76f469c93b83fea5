/// \file pair_cache.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/detail/pair_table.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning "<broadphase/pair_cache.hpp> is deprecated: include <broadphase/detail/pair_table.hpp>"
#endif
#include <broadphase/detail/pair_table.hpp>
