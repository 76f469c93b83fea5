/// \file distributed.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/mpi.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning "<broadphase/distributed.hpp> is deprecated: include <broadphase/mpi.hpp>"
#endif
#include <broadphase/mpi.hpp>
