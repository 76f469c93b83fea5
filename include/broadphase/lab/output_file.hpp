/// \file lab/output_file.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/scenes/output_file.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/lab/output_file.hpp> is deprecated: include <broadphase/scenes/output_file.hpp>"
#endif
#include <broadphase/scenes/output_file.hpp>
