/// \file input.cpp
/// Reading and checking the caller's arrays: formats, shapes and row counts
/// first, then every value, before the library reads anything.
#include "input.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace broadphase_python {

std::string number_text(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string shape_text(const py::buffer_info& b) {
  std::string s = "(";
  for (std::size_t k = 0; k < b.shape.size(); ++k)
    s += (k ? ", " : "") + std::to_string(b.shape[k]);
  return s + (b.shape.size() == 1 ? ",)" : ")");
}

RealArray real_array(const py::buffer& b, const char* name, std::size_t cols, bool allow_scalar,
                     std::size_t n) {
  RealArray a;
  a.info = std::make_shared<py::buffer_info>(b.request());
  const py::buffer_info& info = *a.info;
  std::string fmt = info.format;
  if (!fmt.empty() && (fmt[0] == '<' || fmt[0] == '=' || fmt[0] == '@')) fmt = fmt.substr(1);
  if (fmt == "d" && info.itemsize == 8) {
    a.type = bp::Real::f64;
  } else if (fmt == "f" && info.itemsize == 4) {
    a.type = bp::Real::f32;
  } else {
    throw BadInput(std::string(name) + ": expected float64 or float32 values, got buffer format '" +
                   info.format + "' (the broadphase package converts other types first)");
  }
  const std::string want =
      cols ? "(N, " + std::to_string(cols) + ")" : (allow_scalar ? "a scalar or (N,)" : "(N,)");
  if (info.ndim == 0 && cols == 0 && allow_scalar) {
    a.scalar = true;
    a.rows = n == SIZE_MAX ? 0 : n;
    return a;
  }
  if (cols == 0 ? info.ndim != 1
                : (info.ndim != 2 || info.shape[1] != static_cast<py::ssize_t>(cols)))
    throw BadInput(std::string(name) + ": expected shape " + want + ", got " + shape_text(info));
  a.rows = static_cast<std::size_t>(info.shape[0]);
  if (n != SIZE_MAX && a.rows != n)
    throw BadInput(std::string(name) + ": expected " + std::to_string(n) +
                   " rows (one per object), got " + std::to_string(a.rows));
  a.cols = cols;
  a.row_stride = info.strides[0];
  a.col_stride = cols ? info.strides[1] : 0;
  return a;
}

namespace {

std::optional<RealArray> optional_real(const py::object& o, const char* name, std::size_t cols,
                                       bool allow_scalar, std::size_t n) {
  if (o.is_none()) return std::nullopt;
  return real_array(o.cast<py::buffer>(), name, cols, allow_scalar, n);
}

}  // namespace

void check_values(const RealArray& a, const char* name, bool extent) {
  const std::size_t rows = a.scalar ? 1 : a.rows;
  const std::size_t cols = std::max<std::size_t>(a.cols, 1);
  for (std::size_t c = 0; c < cols; ++c) {
    const bp::Column col = a.column(c);
    for (std::size_t i = 0; i < rows; ++i) {
      const double v = col.at(i);
      if (std::isfinite(v) && (!extent || v >= 0)) continue;
      std::string where = name;
      if (!a.scalar)
        where += "[" + std::to_string(i) + (a.cols ? ", " + std::to_string(c) : "") + "]";
      if (!std::isfinite(v)) throw BadInput(where + " is " + number_text(v) + " (must be finite)");
      throw BadInput(where + " is negative (" + number_text(v) + ")");
    }
  }
}

void check_kinds(const KindArray& k, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t v = k.data[static_cast<std::ptrdiff_t>(i) * k.stride];
    if (v > 1)
      throw BadInput("kinds[" + std::to_string(i) + "] is " + std::to_string(v) +
                     " (0 is a sphere, 1 a box)");
  }
}

namespace {

KindArray kind_array(const py::buffer& b, std::size_t n) {
  KindArray k;
  k.info = std::make_shared<py::buffer_info>(b.request());
  const py::buffer_info& info = *k.info;
  if (info.itemsize != 1 || !(info.format == "B" || info.format == "?" || info.format == "b"))
    throw BadInput("kinds: expected uint8 or bool values, got buffer format '" + info.format + "'");
  if (info.ndim != 1 || static_cast<std::size_t>(info.shape[0]) != n)
    throw BadInput("kinds: expected shape (" + std::to_string(n) + ",), got " + shape_text(info));
  k.data = static_cast<const std::uint8_t*>(info.ptr);
  k.stride = info.strides[0];
  check_kinds(k, n);
  return k;
}

}  // namespace

ObjectArrays object_arrays(const py::buffer& centers, const py::object& radii,
                           const py::object& half, const py::object& kinds,
                           const char* centers_name, const char* radii_name,
                           const char* half_name) {
  ObjectArrays o;
  o.centers = real_array(centers, centers_name, 3, false, SIZE_MAX);
  const std::size_t n = o.centers.rows;
  o.radii = optional_real(radii, radii_name, 0, true, n);
  o.half = optional_real(half, half_name, 3, false, n);
  if (!o.radii && !o.half)
    throw BadInput(std::string("give ") + radii_name + " (spheres) or " + half_name +
                   " (boxes), or both with kinds");
  if (!kinds.is_none()) {
    if (!o.radii || !o.half)
      throw BadInput(std::string("kinds needs both ") + radii_name + " and " + half_name);
    o.kinds = kind_array(kinds.cast<py::buffer>(), n);
  } else if (o.radii && o.half) {
    throw BadInput(std::string("both ") + radii_name + " and " + half_name +
                   " given: say which object is which with kinds (0 sphere, 1 box)");
  }
  if (n > std::numeric_limits<std::uint32_t>::max() - 1)
    throw BadInput(std::string(centers_name) + ": more objects than 32-bit indices can name");
  {
    py::gil_scoped_release nogil;
    check_values(o.centers, centers_name, false);
    if (o.radii) check_values(*o.radii, radii_name, true);
    if (o.half) check_values(*o.half, half_name, true);
  }
  bp::Objects& ob = o.objects;
  ob.count = n;
  ob.x = o.centers.column(0);
  ob.y = o.centers.column(1);
  ob.z = o.centers.column(2);
  if (o.radii) {
    ob.radius = o.radii->column(0);
    if (o.radii->scalar) ob.radius.stride = 0;
  }
  if (o.half) {
    ob.half_x = o.half->column(0);
    ob.half_y = o.half->column(1);
    ob.half_z = o.half->column(2);
  }
  if (o.kinds) {
    ob.kind = o.kinds->data;
    ob.kind_stride = o.kinds->stride;
  }
  return o;
}

std::vector<std::uint32_t> filter_column(const py::buffer& b, const char* name, std::size_t n) {
  const py::buffer_info info = b.request();
  std::string fmt = info.format;
  if (!fmt.empty() && (fmt[0] == '<' || fmt[0] == '=' || fmt[0] == '@')) fmt = fmt.substr(1);
  if (info.itemsize != 4 || !(fmt == "I" || fmt == "L"))
    throw BadInput(std::string(name) + ": expected uint32 values, got buffer format '" +
                   info.format + "' (the broadphase package converts other integer types first)");
  if (info.ndim != 1 || static_cast<std::size_t>(info.shape[0]) != n)
    throw BadInput(std::string(name) + ": expected shape (" + std::to_string(n) +
                   ",), one value per object, got " + shape_text(info));
  std::vector<std::uint32_t> out(n);
  const auto* p = static_cast<const unsigned char*>(info.ptr);
  for (std::size_t i = 0; i < n; ++i)
    std::memcpy(&out[i], p + static_cast<std::ptrdiff_t>(i) * info.strides[0], 4);
  return out;
}

void attach_filters(ObjectArrays& o, const py::object& groups, const py::object& masks,
                    const char* groups_name, const char* masks_name) {
  if (groups.is_none() && masks.is_none()) return;
  if (groups.is_none() || masks.is_none())
    throw BadInput(std::string("give both ") + groups_name + " and " + masks_name);
  const std::size_t n = o.objects.count;
  o.groups = filter_column(groups.cast<py::buffer>(), groups_name, n);
  o.masks = filter_column(masks.cast<py::buffer>(), masks_name, n);
  o.objects.groups = o.groups;
  o.objects.masks = o.masks;
}

bp::Shape checked_box(const std::vector<double>& lo, const std::vector<double>& hi) {
  if (lo.size() != 3 || hi.size() != 3) throw BadInput("lo and hi: expected 3 numbers each");
  bp::Vec3 c, h;
  for (int a = 0; a < 3; ++a) {
    const char* nm = a == 0 ? "0" : (a == 1 ? "1" : "2");
    if (!std::isfinite(lo[a]))
      throw BadInput(std::string("lo[") + nm + "] is " + number_text(lo[a]));
    if (!std::isfinite(hi[a]))
      throw BadInput(std::string("hi[") + nm + "] is " + number_text(hi[a]));
    if (hi[a] < lo[a])
      throw BadInput(std::string("hi[") + nm + "] < lo[" + nm + "] (" + number_text(hi[a]) + " < " +
                     number_text(lo[a]) + ")");
    c[a] = (lo[a] + hi[a]) / 2;
    h[a] = (hi[a] - lo[a]) / 2;
  }
  const bp::Shape s = bp::Shape::box(c, h);
  if (!bp::is_valid(s)) throw BadInput("lo, hi: the box overflows a double");
  return s;
}

}  // namespace broadphase_python
