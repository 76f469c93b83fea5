/// \file hgrid_paper.hpp
/// Deprecated forwarding header, kept so that existing code builds: include
/// <broadphase/study/hgrid_paper.hpp> instead. Define BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
/// to silence the warning.
#pragma once
#ifndef BROADPHASE_NO_DEPRECATED_HEADER_WARNINGS
#pragma GCC warning \
    "<broadphase/hgrid_paper.hpp> is deprecated: include <broadphase/study/hgrid_paper.hpp>"
#endif
#include <broadphase/study/hgrid_paper.hpp>
