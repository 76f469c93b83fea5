/// \file knn.hpp
/// The module's k nearest neighbours and radius queries (broadphase/knn.hpp):
/// `knn` fills the caller's (M, k) float64 and int64 arrays, `within`
/// returns CSR offsets, indices and the squared distances' bit patterns
/// (the package views them as float64 without a copy). GIL released.
#pragma once

#include <pybind11/pybind11.h>

namespace broadphase_python {

/// Adds `knn` and `within` to the module.
void register_knn(pybind11::module_& m);

}  // namespace broadphase_python
