/// \file one_shot.hpp
/// The module's one-shot calls: the pairs of one set of objects, or between
/// two sets, found once over the caller's arrays (no index kept).
#pragma once

#include <pybind11/pybind11.h>

#include <array>
#include <broadphase/arrays/arrays.hpp>

#include "output.hpp"

namespace broadphase_python {

namespace py = pybind11;
namespace bp = broadphase;

bp::ArrayOptions array_options(unsigned threads, bool sorted, double skin = 0);

/// One-shot: the overlapping pairs of one set as an int64 (M, 2) array.
IntArray find_pairs_once(const py::buffer& centers, const py::object& radii, const py::object& half,
                         const py::object& kinds, bool sorted, unsigned threads,
                         const py::object& groups, const py::object& masks);

/// One-shot bipartite: pairs (i in a, j in b), sorted by i then j.
IntArray find_pairs_between(const py::buffer& a_centers, const py::object& a_radii,
                            const py::object& a_half, const py::object& a_kinds,
                            const py::buffer& b_centers, const py::object& b_radii,
                            const py::object& b_half, const py::object& b_kinds, unsigned threads,
                            const py::object& a_groups, const py::object& a_masks,
                            const py::object& b_groups, const py::object& b_masks);

/// One-shot in a periodic cell (arrays/periodic.hpp): a tuple of the pairs,
/// int64 (M, 2) with i < j, and their shifts, int64 (M, 3) in {-1, 0, 1}.
py::tuple find_periodic_pairs_once(const py::buffer& centers, const py::object& radii,
                                   const py::object& half, const py::object& kinds,
                                   std::array<double, 3> box, std::array<bool, 3> periodic,
                                   bool sorted, const py::object& groups, const py::object& masks);

}  // namespace broadphase_python
