/// \file neighbours.cpp
/// Neighbour lists for Python (one-shot, and the moving list with a skin):
/// arrays in through the buffer protocol (read in
/// place, float64 or float32), the library's lists out as owned buffers that
/// numpy wraps without a copy, the GIL released while the list is found, and
/// InvalidNeighbourInput raised as ValueError.
#include "neighbours.hpp"

#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <broadphase/moving_neighbours.hpp>
#include <broadphase/neighbours.hpp>
#include <cstdint>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "input.hpp"

namespace broadphase_python {
namespace {

namespace py = pybind11;
namespace bp = broadphase;

/// An int64 or float64 array the module owns: a vector moved out of a
/// NeighbourList, its shape (rows, cols; cols 0 for 1-D).
struct NeighbourArray {
  bp::NeighbourVector<std::int64_t> ints;
  bp::NeighbourVector<double> reals;
  bool real = false;
  std::size_t rows = 0, cols = 0;
};

NeighbourArray ints(bp::NeighbourVector<std::int64_t>&& v, std::size_t cols) {
  NeighbourArray a;
  a.rows = cols ? v.size() / cols : v.size();
  a.cols = cols;
  a.ints = std::move(v);
  return a;
}

NeighbourArray reals(bp::NeighbourVector<double>&& v, std::size_t cols) {
  NeighbourArray a;
  a.real = true;
  a.rows = cols ? v.size() / cols : v.size();
  a.cols = cols;
  a.reals = std::move(v);
  return a;
}

template <class T>
py::buffer_info info_of(T* data, const NeighbourArray& a) {
  if (a.cols == 0)
    return py::buffer_info(data, sizeof(T), py::format_descriptor<T>::format(), 1,
                           {static_cast<py::ssize_t>(a.rows)}, {sizeof(T)});
  return py::buffer_info(
      data, sizeof(T), py::format_descriptor<T>::format(), 2,
      {static_cast<py::ssize_t>(a.rows), static_cast<py::ssize_t>(a.cols)},
      {static_cast<py::ssize_t>(a.cols * sizeof(T)), static_cast<py::ssize_t>(sizeof(T))});
}

bp::NeighbourCell cell_of(const std::vector<std::vector<double>>& cell,
                          const std::vector<bool>& pbc) {
  if (cell.size() != 3) throw BadInput("cell: expected 3 rows, got " + std::to_string(cell.size()));
  if (pbc.size() != 3) throw BadInput("pbc: expected 3 values, got " + std::to_string(pbc.size()));
  bp::NeighbourCell c;
  for (int r = 0; r < 3; ++r) {
    if (cell[static_cast<std::size_t>(r)].size() != 3)
      throw BadInput("cell: row " + std::to_string(r) + " has " +
                     std::to_string(cell[static_cast<std::size_t>(r)].size()) + " values, not 3");
    for (int k = 0; k < 3; ++k)
      c.vectors[static_cast<std::size_t>(r)][k] =
          cell[static_cast<std::size_t>(r)][static_cast<std::size_t>(k)];
    c.periodic[static_cast<std::size_t>(r)] = pbc[static_cast<std::size_t>(r)];
  }
  return c;
}

bp::NeighbourPoints points_of(const RealArray& a) {
  return {a.column(0), a.column(1), a.column(2), a.rows};
}

/// The list as a dict of the quantities asked for: i, j, S, d, D, offsets.
py::dict to_dict(bp::NeighbourList&& l, const bp::NeighbourOptions& o) {
  py::dict d;
  d["i"] = ints(std::move(l.first), 0);
  d["j"] = ints(std::move(l.second), 0);
  if (o.shifts) d["S"] = ints(std::move(l.shifts), 3);
  if (o.distances) d["d"] = reals(std::move(l.distances), 0);
  if (o.vectors) d["D"] = reals(std::move(l.vectors), 3);
  if (o.offsets) d["offsets"] = ints(std::move(l.offsets), 0);
  return d;
}

bp::NeighbourOptions options_of(bool strict, bool shifts, bool distances, bool vectors,
                                bool offsets, unsigned threads) {
  bp::NeighbourOptions o;
  o.threads = threads;
  o.rule = strict ? bp::CutoffRule::strict : bp::CutoffRule::inclusive;
  o.shifts = shifts;
  o.distances = distances;
  o.vectors = vectors;
  o.offsets = offsets;
  return o;
}

py::dict neighbour_list(const py::buffer& positions, const std::vector<std::vector<double>>& cell,
                        const std::vector<bool>& pbc, double cutoff, const py::object& cutoffs,
                        bool full, bool self_interaction, bool strict, bool shifts, bool distances,
                        bool vectors, bool offsets, unsigned threads) {
  const RealArray pos = real_array(positions, "positions", 3, false, SIZE_MAX);
  std::optional<RealArray> cuts;
  if (!cutoffs.is_none())
    cuts = real_array(cutoffs.cast<py::buffer>(), "cutoff", 0, false, pos.rows);
  const bp::NeighbourCell c = cell_of(cell, pbc);
  bp::NeighbourOptions o = options_of(strict, shifts, distances, vectors, offsets, threads);
  o.full = full;
  o.self_interaction = self_interaction;
  bp::NeighbourList l;
  {
    py::gil_scoped_release release;
    l = cuts ? bp::neighbour_list(points_of(pos), c, cuts->column(0), o)
             : bp::neighbour_list(points_of(pos), c, cutoff, o);
  }
  return to_dict(std::move(l), o);
}

py::dict neighbour_list_between(const py::buffer& queries, const py::buffer& points,
                                const std::vector<std::vector<double>>& cell,
                                const std::vector<bool>& pbc, double cutoff, bool strict,
                                bool shifts, bool distances, bool vectors, bool offsets,
                                unsigned threads) {
  const RealArray q = real_array(queries, "queries", 3, false, SIZE_MAX);
  const RealArray p = real_array(points, "points", 3, false, SIZE_MAX);
  const bp::NeighbourCell c = cell_of(cell, pbc);
  const bp::NeighbourOptions o = options_of(strict, shifts, distances, vectors, offsets, threads);
  bp::NeighbourList l;
  {
    py::gil_scoped_release release;
    l = bp::neighbour_list_between(points_of(q), points_of(p), c, cutoff, o);
  }
  return to_dict(std::move(l), o);
}

/// A moving neighbour list (moving_neighbours.hpp) for Python: update
/// releases the GIL; a call that overlaps another on the same list raises
/// RuntimeError instead of racing (the list changes in update).
class MovingList {
 public:
  MovingList(const std::vector<std::vector<double>>& cell, const std::vector<bool>& pbc,
             double cutoff, const py::object& cutoffs, double skin, bool full,
             bool self_interaction, bool strict, bool shifts, bool distances, bool vectors,
             bool offsets, unsigned threads) {
    const bp::NeighbourCell c = cell_of(cell, pbc);
    bp::NeighbourOptions o = options_of(strict, shifts, distances, vectors, offsets, threads);
    o.full = full;
    o.self_interaction = self_interaction;
    options_ = o;
    if (cutoffs.is_none()) {
      list_ = std::make_unique<bp::MovingNeighbourList>(c, cutoff, skin, o);
    } else {
      const RealArray cuts = real_array(cutoffs.cast<py::buffer>(), "cutoff", 0, false, SIZE_MAX);
      list_ = std::make_unique<bp::MovingNeighbourList>(c, cuts.column(0), cuts.rows, skin, o);
    }
  }

  py::dict update(const py::buffer& positions) {
    const RealArray pos = real_array(positions, "positions", 3, false, SIZE_MAX);
    Exclusive use(busy_);
    bp::NeighbourList l;
    {
      py::gil_scoped_release release;
      l = list_->update(points_of(pos));
    }
    return to_dict(std::move(l), options_);
  }

  double skin() const { return list_->skin(); }
  std::size_t rebuilds() const { return list_->rebuilds(); }
  std::size_t candidates() const { return list_->candidates(); }
  std::size_t memory_bytes() const { return list_->memory_bytes(); }

 private:
  struct Exclusive {
    std::atomic<bool>& flag;
    explicit Exclusive(std::atomic<bool>& f) : flag(f) {
      if (flag.exchange(true))
        throw std::runtime_error("NeighbourList.update: the list is in use by another thread");
    }
    ~Exclusive() { flag.store(false); }
    Exclusive(const Exclusive&) = delete;
    Exclusive& operator=(const Exclusive&) = delete;
  };
  std::unique_ptr<bp::MovingNeighbourList> list_;
  bp::NeighbourOptions options_;
  std::atomic<bool> busy_{false};
};

}  // namespace

void bind_neighbours(py::module_& m) {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const bp::InvalidNeighbourInput& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  py::class_<NeighbourArray>(m, "NeighbourArray", py::buffer_protocol(),
                             "An int64 or float64 array of a neighbour list (numpy wraps it).")
      .def_buffer([](NeighbourArray& a) -> py::buffer_info {
        return a.real ? info_of(a.reals.data(), a) : info_of(a.ints.data(), a);
      });
  m.def("neighbour_list", &neighbour_list, py::arg("positions"), py::arg("cell"), py::arg("pbc"),
        py::arg("cutoff"), py::arg("cutoffs"), py::arg("full"), py::arg("self_interaction"),
        py::arg("strict"), py::arg("shifts"), py::arg("distances"), py::arg("vectors"),
        py::arg("offsets"), py::arg("threads"),
        "Pairs (i, j, S) within the cutoff (neighbours.hpp): a dict of int64/float64 buffers.");
  m.def("neighbour_list_between", &neighbour_list_between, py::arg("queries"), py::arg("points"),
        py::arg("cell"), py::arg("pbc"), py::arg("cutoff"), py::arg("strict"), py::arg("shifts"),
        py::arg("distances"), py::arg("vectors"), py::arg("offsets"), py::arg("threads"),
        "Pairs (q, p, S): points moved by S within the cutoff of queries.");
  py::class_<MovingList>(
      m, "MovingNeighbourList",
      "A neighbour list with a skin, reused over frames (moving_neighbours.hpp).")
      .def(
          py::init<const std::vector<std::vector<double>>&, const std::vector<bool>&, double,
                   const py::object&, double, bool, bool, bool, bool, bool, bool, bool, unsigned>(),
          py::arg("cell"), py::arg("pbc"), py::arg("cutoff"), py::arg("cutoffs"), py::arg("skin"),
          py::arg("full"), py::arg("self_interaction"), py::arg("strict"), py::arg("shifts"),
          py::arg("distances"), py::arg("vectors"), py::arg("offsets"), py::arg("threads"))
      .def("update", &MovingList::update, py::arg("positions"),
           "The list of these positions: a dict of int64/float64 buffers, as neighbour_list.")
      .def("skin", &MovingList::skin)
      .def("rebuilds", &MovingList::rebuilds)
      .def("candidates", &MovingList::candidates)
      .def("memory_bytes", &MovingList::memory_bytes);
}

}  // namespace broadphase_python
