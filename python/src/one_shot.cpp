/// \file one_shot.cpp
/// The one-shot calls: the caller's arrays read and checked, the pairs found
/// with the GIL released, and handed back as an `IntArray`.
#include "one_shot.hpp"

#include <broadphase/arrays/periodic.hpp>

#include "input.hpp"

namespace broadphase_python {

bp::ArrayOptions array_options(unsigned threads, bool sorted, double skin) {
  bp::ArrayOptions o;
  o.threads = threads;
  o.sorted = sorted;
  o.skin = skin;
  return o;
}

namespace {

/// Runs `find(sink)` with the GIL released, the pairs appended to an int64
/// (M, 2) array as the library hands them over.
template <class Find>
IntArray pairs_array(Find&& find) {
  IntArray out;
  out.cols = 2;
  {
    py::gil_scoped_release nogil;
    find([&out](std::span<const bp::IndexPair> chunk) {
      append_pairs(out.data, chunk);
      return true;
    });
  }
  out.data.trim();
  out.rows = out.data.size() / 2;
  return out;
}

}  // namespace

IntArray find_pairs_once(const py::buffer& centers, const py::object& radii, const py::object& half,
                         const py::object& kinds, bool sorted, unsigned threads,
                         const py::object& groups, const py::object& masks) {
  ObjectArrays o = object_arrays(centers, radii, half, kinds);
  attach_filters(o, groups, masks);
  return pairs_array([&](const bp::PairSink& sink) {
    bp::find_pairs(o.objects, sink, array_options(threads, sorted));
  });
}

IntArray find_pairs_between(const py::buffer& a_centers, const py::object& a_radii,
                            const py::object& a_half, const py::object& a_kinds,
                            const py::buffer& b_centers, const py::object& b_radii,
                            const py::object& b_half, const py::object& b_kinds, unsigned threads,
                            const py::object& a_groups, const py::object& a_masks,
                            const py::object& b_groups, const py::object& b_masks) {
  ObjectArrays a =
      object_arrays(a_centers, a_radii, a_half, a_kinds, "centers", "radii", "half_extents");
  ObjectArrays b = object_arrays(b_centers, b_radii, b_half, b_kinds, "other_centers",
                                 "other_radii", "other_half_extents");
  attach_filters(a, a_groups, a_masks);
  attach_filters(b, b_groups, b_masks, "other_groups", "other_masks");
  return pairs_array([&](const bp::PairSink& sink) {
    bp::find_pairs(a.objects, b.objects, sink, array_options(threads, true));
  });
}

py::tuple find_periodic_pairs_once(const py::buffer& centers, const py::object& radii,
                                   const py::object& half, const py::object& kinds,
                                   std::array<double, 3> box, std::array<bool, 3> periodic,
                                   bool sorted, const py::object& groups, const py::object& masks) {
  ObjectArrays o = object_arrays(centers, radii, half, kinds);
  attach_filters(o, groups, masks);
  const bp::PeriodicCell cell{{box[0], box[1], box[2]}, periodic};
  IntArray pairs, shifts;
  pairs.cols = 2;
  shifts.cols = 3;
  {
    py::gil_scoped_release nogil;
    const bp::ShiftedPairSink sink = [&](std::span<const bp::ShiftedPair> chunk) {
      for (const bp::ShiftedPair& p : chunk) {
        pairs.data.push_back(p.i);
        pairs.data.push_back(p.j);
        shifts.data.push_back(p.shift.x);
        shifts.data.push_back(p.shift.y);
        shifts.data.push_back(p.shift.z);
      }
      return true;
    };
    bp::find_pairs(o.objects, cell, sink, array_options(1, sorted));
  }
  pairs.data.trim();
  shifts.data.trim();
  pairs.rows = pairs.data.size() / 2;
  shifts.rows = shifts.data.size() / 3;
  return py::make_tuple(py::cast(std::move(pairs)), py::cast(std::move(shifts)));
}

}  // namespace broadphase_python
