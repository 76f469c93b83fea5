/// \file neighbours.hpp
/// The Python bindings of the neighbour lists (include/broadphase/neighbours.hpp):
/// `_broadphase.neighbour_list` and `_broadphase.neighbour_list_between`.
#pragma once

#include <pybind11/pybind11.h>

namespace broadphase_python {

/// Adds the neighbour-list functions and their output array type to `m`.
void bind_neighbours(pybind11::module_& m);

}  // namespace broadphase_python
