/// \file rays.hpp
/// The module's ray casts: rays read from the caller's arrays, cast into a
/// structure of the library (the closest hit of each ray, or every hit in
/// rows), the results as int64 buffers (t as the bit patterns of its
/// doubles, which the package views as float64 without a copy).
#pragma once

#include <pybind11/pybind11.h>

#include <broadphase/arrays/rays.hpp>
#include <broadphase/rays.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "output.hpp"

namespace broadphase_python {

namespace py = pybind11;
namespace bp = broadphase;

/// The structure a one-shot ray cast builds when none is named and the
/// rays are many (ray_cast_once): the k-d tree cast random rays into 10^5
/// spheres fastest among ours (46 000 a second on one thread, the grids
/// 12 000-31 000; docs/rays.md).
inline constexpr const char* kRayStructure = "kdtree";
/// The name that selects the lean path's RayCaster (arrays/rays.hpp).
inline constexpr const char* kLeanRays = "lean";

/// Reads origins (R, 3), directions (R, 3), tmax (scalar or (R,)) and the
/// rays' masks (None or (R,) uint32) into rays; each ray checked
/// (BadInput naming the argument and the row).
std::vector<bp::Ray> ray_arrays(const py::buffer& origins, const py::buffer& directions,
                                const py::object& tmax, const py::object& masks);

/// What a cast returns: (ids, t bits) for the closest hits, or (offsets,
/// ids, t bits) for all hits. `id_of` maps a hit's handle to the caller's id.
py::tuple cast(const bp::AnyBroadPhase& s, const std::vector<bp::Ray>& rays, bool all_hits,
               unsigned threads, const std::vector<std::uint32_t>* id_of);

/// As `cast`, through the lean path's RayCaster; `id_of` maps an object's
/// index to the caller's id (null: the index is the id).
py::tuple cast_lean(const bp::arrays::RayCaster& c, const std::vector<bp::Ray>& rays, bool all_hits,
                    unsigned threads, const std::vector<std::uint32_t>* id_of);

/// One-shot: builds `structure` over the objects (with their filters) and
/// casts the rays.
py::tuple ray_cast_once(const py::buffer& centers, const py::object& radii, const py::object& half,
                        const py::object& kinds, const py::object& groups, const py::object& masks,
                        const py::buffer& origins, const py::buffer& directions,
                        const py::object& tmax, const py::object& ray_masks, bool all_hits,
                        unsigned threads, const std::string& structure);

}  // namespace broadphase_python
