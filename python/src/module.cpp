/// \file module.cpp
/// The compiled half of the Python package `broadphase` (`broadphase._broadphase`).
///
/// Arrays come in through the buffer protocol (not pybind11/numpy.h), so the
/// module works with the numpy Debian ships and with later ones: a float64 or
/// float32 array is read in place through byte strides (C-contiguous,
/// Fortran-ordered, sliced, read-only: no copy); the Python layer converts
/// anything else first. Results go out as `IntArray`, a buffer the module
/// owns, which numpy wraps without a copy and keeps alive as the array's base,
/// so a returned array outlives the index that made it.
///
/// Every call into the library releases the GIL. Bad input raises ValueError
/// naming the argument and the index before the library reads anything.
///
/// This file holds the bindings; the code behind them is in input.cpp
/// (reading and checking the arrays), output.cpp (the int64 results),
/// one_shot.cpp (the one-shot calls) and index.cpp (`IndexCore`).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <broadphase/arrays/arrays.hpp>
#include <broadphase/registry.hpp>
#include <cstdint>
#include <exception>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "index.hpp"
#include "input.hpp"
#include "knn.hpp"
#include "neighbours.hpp"
#include "one_shot.hpp"
#include "output.hpp"
#include "rays.hpp"

namespace py = pybind11;
namespace bp = broadphase;

using broadphase_python::BadInput;
using broadphase_python::find_pairs_between;
using broadphase_python::find_pairs_once;
using broadphase_python::IndexCore;
using broadphase_python::IntArray;
using broadphase_python::PairChunks;

PYBIND11_MODULE(_broadphase, m) {
  m.doc() = "The compiled core of broadphase (use the `broadphase` package, which wraps it).";

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const BadInput& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const bp::InvalidObjects& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const bp::InvalidShape& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const bp::InvalidRay& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const bp::InvalidConfig& e) {  // UnknownStructure too
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  py::class_<IntArray>(m, "IntArray", py::buffer_protocol(),
                       "An int64 array owned by the module (numpy wraps it without a copy).")
      .def_buffer([](IntArray& a) -> py::buffer_info {
        a.data.trim();  // (done where arrays are filled; a guard for any other)
        if (a.cols == 0)
          return py::buffer_info(a.data.data(), sizeof(std::int64_t),
                                 py::format_descriptor<std::int64_t>::format(), 1,
                                 {static_cast<py::ssize_t>(a.rows)}, {sizeof(std::int64_t)});
        return py::buffer_info(a.data.data(), sizeof(std::int64_t),
                               py::format_descriptor<std::int64_t>::format(), 2,
                               {static_cast<py::ssize_t>(a.rows), static_cast<py::ssize_t>(a.cols)},
                               {static_cast<py::ssize_t>(a.cols * sizeof(std::int64_t)),
                                static_cast<py::ssize_t>(sizeof(std::int64_t))});
      });

  py::class_<PairChunks>(m, "PairChunks", "Chunks of a snapshot of an index's pairs.")
      .def("__iter__", [](PairChunks& c) -> PairChunks& { return c; })
      .def("__next__", &PairChunks::next)
      .def("__len__",
           [](const PairChunks& c) { return (c.pairs->size() - c.pos + c.chunk - 1) / c.chunk; });

  broadphase_python::bind_neighbours(m);

  m.def("find_pairs", &find_pairs_once, py::arg("centers"), py::arg("radii"),
        py::arg("half_extents"), py::arg("kinds"), py::arg("sorted"), py::arg("threads"),
        py::arg("groups") = py::none(), py::arg("masks") = py::none(),
        "Overlapping pairs of one set of objects (int64 (M, 2), i < j) that pass the filters.");
  m.def("find_periodic_pairs", &broadphase_python::find_periodic_pairs_once, py::arg("centers"),
        py::arg("radii"), py::arg("half_extents"), py::arg("kinds"), py::arg("box"),
        py::arg("periodic"), py::arg("sorted"), py::arg("groups") = py::none(),
        py::arg("masks") = py::none(),
        "Periodic pairs of one set in an orthorhombic cell: (pairs int64 (M, 2), shifts int64 "
        "(M, 3)).");
  m.def("ray_cast", &broadphase_python::ray_cast_once, py::arg("centers"), py::arg("radii"),
        py::arg("half"), py::arg("kinds"), py::arg("groups"), py::arg("masks"), py::arg("origins"),
        py::arg("directions"), py::arg("tmax"), py::arg("ray_masks"), py::arg("all_hits"),
        py::arg("threads"), py::arg("structure"));
  m.def("find_pairs_between", &find_pairs_between, py::arg("centers"), py::arg("radii"),
        py::arg("half_extents"), py::arg("kinds"), py::arg("other_centers"), py::arg("other_radii"),
        py::arg("other_half_extents"), py::arg("other_kinds"), py::arg("threads"),
        py::arg("groups") = py::none(), py::arg("masks") = py::none(),
        py::arg("other_groups") = py::none(), py::arg("other_masks") = py::none(),
        "Overlapping pairs (i in the first set, j in the second), sorted.");
  broadphase_python::register_knn(m);
  m.def(
      "scratch_bytes", [] { return bp::scratch_bytes() + broadphase_python::kept_output_bytes(); },
      "Bytes of freed working and output memory kept for the next call.");
  m.def(
      "set_scratch_limit",
      [](std::size_t bytes) {
        bp::set_scratch_limit(bytes);
        broadphase_python::set_output_keep_limit(bytes);
      },
      py::arg("bytes"), "The most bytes kept of each kind (0: keep none).");
  m.def(
      "scratch_limit", [] { return bp::scratch_limit(); }, "The most bytes kept of each kind.");
  m.def(
      "structures",
      [] {
        std::vector<std::pair<std::string, std::string>> out;
        const bp::Registry registry = bp::Registry::library();
        for (const bp::StructureInfo& e : registry.entries())
          out.emplace_back(e.name, e.description);
        return out;
      },
      "The library's structures: (name, description) pairs.");

  py::class_<IndexCore>(m, "IndexCore", "The compiled index behind broadphase.Index.")
      .def(py::init([](const py::buffer& centers, const py::object& radii, const py::object& half,
                       const py::object& kinds, const std::string& structure, unsigned threads,
                       double skin, std::size_t spare_bytes, const py::object& groups,
                       const py::object& masks) {
             return std::make_unique<IndexCore>(centers, radii, half, kinds, structure, threads,
                                                skin, spare_bytes, groups, masks);
           }),
           py::arg("centers"), py::arg("radii"), py::arg("half_extents"), py::arg("kinds"),
           py::arg("structure"), py::arg("threads"), py::arg("skin"), py::arg("spare_bytes"),
           py::arg("groups") = py::none(), py::arg("masks") = py::none())
      .def("size", &IndexCore::size)
      .def("borrowing", &IndexCore::borrowing)
      .def("structure", &IndexCore::structure)
      .def("ids", &IndexCore::ids)
      .def("update_all", [](IndexCore& c, const py::buffer& centers, const py::object& radii,
                            const py::object& half) { c.update_all(centers, radii, half); })
      .def("update_in_place", &IndexCore::update_in_place)
      .def("update_ids", &IndexCore::update_ids)
      .def("insert", &IndexCore::insert, py::arg("centers"), py::arg("radii"),
           py::arg("half_extents"), py::arg("kinds"), py::arg("groups") = py::none(),
           py::arg("masks") = py::none())
      .def("set_filters", &IndexCore::set_filters, py::arg("ids"), py::arg("groups"),
           py::arg("masks"))
      .def("remove", &IndexCore::remove)
      .def("pairs", &IndexCore::pairs)
      .def("count_pairs", &IndexCore::count_pairs)
      .def("iter_pairs", &IndexCore::iter_pairs)
      .def("query", &IndexCore::query)
      .def("query_box", &IndexCore::query_box)
      .def("ray_cast", &IndexCore::ray_cast)
      .def("memory_bytes", &IndexCore::memory_bytes)
      .def("validate", &IndexCore::validate);
}
