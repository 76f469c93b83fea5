/// \file knn.cpp
/// `knn` and `within` for the package (knn.hpp): points and queries read in
/// place as float64 or float32 (N, 3), a periodic box as three lengths (0
/// for an axis that is not periodic), the library's InvalidPoints raised as
/// ValueError.
#include "knn.hpp"

#include <pybind11/stl.h>

#include <bit>
#include <broadphase/knn.hpp>
#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "input.hpp"
#include "output.hpp"

namespace broadphase_python {

namespace {

bp::Points knn_points_of(const RealArray& a) {
  return {a.rows, a.column(0), a.column(1), a.column(2)};
}

bp::KnnConfig config_of(const py::object& box) {
  bp::KnnConfig c;
  if (box.is_none()) return c;
  const std::vector<double> lengths = box.cast<std::vector<double>>();
  if (lengths.size() != 3) throw BadInput("box: expected three lengths (0: not periodic)");
  bp::PeriodicCell cell{{lengths[0], lengths[1], lengths[2]}, {false, false, false}};
  for (int a = 0; a < 3; ++a) {
    if (lengths[a] == 0) continue;
    if (!(lengths[a] > 0) || !std::isfinite(lengths[a]))
      throw BadInput("box[" + std::to_string(a) + "] is " + number_text(lengths[a]) +
                     " (a length must be finite and positive, or 0 for an axis that is not "
                     "periodic)");
    cell.periodic[static_cast<std::size_t>(a)] = true;
  }
  c.box = cell;
  return c;
}

template <class F>
auto translated(F&& f) {
  try {
    return f();
  } catch (const bp::InvalidPoints& e) {
    throw BadInput(e.what());
  }
}

IntArray column_of(const std::vector<std::int64_t>& v) {
  IntArray a;
  a.rows = v.size();
  a.data.assign(v.begin(), v.end());
  a.data.trim();
  return a;
}

}  // namespace

void register_knn(py::module_& m) {
  m.def(
      "knn",
      [](const py::buffer& points, const py::object& queries, std::size_t k, const py::object& box,
         bool exclude_self, unsigned threads, const py::buffer& d2_out,
         const py::buffer& index_out) {
        const RealArray p = real_array(points, "points", 3, false, SIZE_MAX);
        std::optional<RealArray> q;
        if (!queries.is_none())
          q = real_array(queries.cast<py::buffer>(), "queries", 3, false, SIZE_MAX);
        const bp::KnnConfig config = config_of(box);
        py::buffer_info d2 = d2_out.request(true);
        py::buffer_info index = index_out.request(true);
        const std::size_t rows = q ? q->rows : p.rows;
        if (d2.itemsize != 8 || index.itemsize != 8 ||
            static_cast<std::size_t>(d2.size) != rows * k ||
            static_cast<std::size_t>(index.size) != rows * k)
          throw BadInput("knn: the output arrays must be contiguous (M, k) float64 and int64");
        py::gil_scoped_release release;
        translated([&] {
          const bp::KnnIndex index_(knn_points_of(p), config);
          std::span<double> d(static_cast<double*>(d2.ptr), rows * k);
          std::span<std::int64_t> i(static_cast<std::int64_t*>(index.ptr), rows * k);
          if (q)
            index_.knn(knn_points_of(*q), k, d, i, threads);
          else
            index_.knn_self(k, exclude_self, d, i, threads);
          return 0;
        });
      },
      py::arg("points"), py::arg("queries"), py::arg("k"), py::arg("box"), py::arg("exclude_self"),
      py::arg("threads"), py::arg("d2_out"), py::arg("index_out"),
      "Fills (M, k) squared distances and indices of each query's k nearest points.");

  m.def(
      "within",
      [](const py::buffer& points, const py::object& queries, double r, const py::object& box,
         bool exclude_self, unsigned threads) {
        const RealArray p = real_array(points, "points", 3, false, SIZE_MAX);
        std::optional<RealArray> q;
        if (!queries.is_none())
          q = real_array(queries.cast<py::buffer>(), "queries", 3, false, SIZE_MAX);
        const bp::KnnConfig config = config_of(box);
        IntArray offsets, index, d2;
        {
          py::gil_scoped_release release;
          const bp::Neighbours found = translated([&] {
            const bp::KnnIndex index_(knn_points_of(p), config);
            return q ? index_.within(knn_points_of(*q), r, threads)
                     : index_.within_self(r, exclude_self, threads);
          });
          offsets = column_of(found.offsets);
          index = column_of(found.index);
          d2.rows = found.d2.size();
          d2.data.resize(found.d2.size());
          for (std::size_t t = 0; t < found.d2.size(); ++t)
            d2.data[t] = std::bit_cast<std::int64_t>(found.d2[t]);
          d2.data.trim();
        }
        return py::make_tuple(std::move(offsets), std::move(index), std::move(d2));
      },
      py::arg("points"), py::arg("queries"), py::arg("r"), py::arg("box"), py::arg("exclude_self"),
      py::arg("threads"),
      "(offsets, indices, bits of the squared distances) of every point within r of each query.");
}

}  // namespace broadphase_python
