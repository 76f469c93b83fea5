/// \file input.hpp
/// The input side of the Python module: numpy arrays (any object with the
/// buffer protocol) read in place as reals, kinds and sets of objects, each
/// value checked, bad input refused as `BadInput` (ValueError in Python)
/// naming the argument and the index.
#pragma once

#include <pybind11/pybind11.h>

#include <broadphase/arrays/arrays.hpp>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace broadphase_python {

namespace py = pybind11;
namespace bp = broadphase;

/// Input the binding refuses: translated to ValueError.
class BadInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

std::string number_text(double v);

/// A float64 or float32 array read in place: `rows` x `cols` (cols 0: 1-D,
/// rows 0 and stride 0 for a scalar), byte strides as numpy gives them.
struct RealArray {
  std::shared_ptr<py::buffer_info> info;  // keeps the exporter's view alive
  bp::Real type = bp::Real::f64;
  std::size_t rows = 0;
  std::size_t cols = 0;
  std::ptrdiff_t row_stride = 0;
  std::ptrdiff_t col_stride = 0;
  bool scalar = false;

  bp::Column column(std::size_t c) const {
    return {
        static_cast<const unsigned char*>(info->ptr) + static_cast<std::ptrdiff_t>(c) * col_stride,
        row_stride, type};
  }
  double at(std::size_t i, std::size_t c) const { return column(c).at(scalar ? 0 : i); }
};

std::string shape_text(const py::buffer_info& b);

/// Reads a buffer as reals. `cols` 3 wants (N, 3); `cols` 0 wants (N,) or,
/// with `allow_scalar`, a 0-d value shared by every object. `n` (when not
/// SIZE_MAX) is the row count the other arguments fixed.
RealArray real_array(const py::buffer& b, const char* name, std::size_t cols, bool allow_scalar,
                     std::size_t n);

/// Every value finite, every extent >= 0; the message names the argument and
/// the index (numpy's notation) of the first bad value.
void check_values(const RealArray& a, const char* name, bool extent);

/// The kinds column: uint8 (or bool) (N,), 0 sphere, 1 box.
struct KindArray {
  std::shared_ptr<py::buffer_info> info;
  const std::uint8_t* data = nullptr;
  std::ptrdiff_t stride = 1;
};

void check_kinds(const KindArray& k, std::size_t n);

/// A set of objects as the caller's arrays, checked, with the views that
/// keep the arrays alive.
struct ObjectArrays {
  RealArray centers;
  std::optional<RealArray> radii, half;
  std::optional<KindArray> kinds;
  // Collision filters, copied (8 bytes an object): empty, or one group and
  // one mask per object; `objects.groups`/`masks` view them.
  std::vector<std::uint32_t> groups, masks;
  bp::Objects objects;
};

/// Reads a uint32 (N,) column of filter bits (the package converts and
/// range-checks other integer types first).
std::vector<std::uint32_t> filter_column(const py::buffer& b, const char* name, std::size_t n);

/// Reads `groups` and `masks` (both None: no filters; the package fills one
/// that is missing with the default) into `o` and points its objects at them.
void attach_filters(ObjectArrays& o, const py::object& groups, const py::object& masks,
                    const char* groups_name = "groups", const char* masks_name = "masks");

/// Reads and checks one set of objects (the GIL is held while the buffers
/// are requested, and released for the value checks).
ObjectArrays object_arrays(const py::buffer& centers, const py::object& radii,
                           const py::object& half, const py::object& kinds,
                           const char* centers_name = "centers", const char* radii_name = "radii",
                           const char* half_name = "half_extents");

bp::Shape checked_box(const std::vector<double>& lo, const std::vector<double>& hi);

}  // namespace broadphase_python
