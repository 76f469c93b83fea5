#include "rays.hpp"

#include <bit>
#include <broadphase/detail/in_order.hpp>
#include <broadphase/registry.hpp>
#include <cmath>
#include <cstring>
#include <limits>

#include "index.hpp"
#include "input.hpp"

namespace broadphase_python {

std::vector<bp::Ray> ray_arrays(const py::buffer& origins, const py::buffer& directions,
                                const py::object& tmax, const py::object& masks) {
  const RealArray o = real_array(origins, "origins", 3, false, SIZE_MAX);
  const std::size_t n = o.rows;
  const RealArray d = real_array(directions, "directions", 3, false, n);
  std::optional<RealArray> t;
  if (!tmax.is_none()) t = real_array(tmax.cast<py::buffer>(), "tmax", 0, true, n);
  std::vector<std::uint32_t> m;
  if (!masks.is_none()) m = filter_column(masks.cast<py::buffer>(), "ray_masks", n);
  std::vector<bp::Ray> rays(n);
  py::gil_scoped_release nogil;
  for (std::size_t i = 0; i < n; ++i) {
    bp::Ray& r = rays[i];
    r.origin = {o.at(i, 0), o.at(i, 1), o.at(i, 2)};
    r.dir = {d.at(i, 0), d.at(i, 1), d.at(i, 2)};
    if (t) r.tmax = t->at(i, 0) == 0 ? 0.0 : t->at(i, 0);  // -0 counts as 0
    if (!m.empty()) r.mask = m[i];
    const std::string why = bp::ray_problem(r);
    if (!why.empty()) throw BadInput("ray " + std::to_string(i) + ": " + why);
  }
  return rays;
}

namespace {

std::int64_t bits(double t) { return std::bit_cast<std::int64_t>(t); }

IntArray column(std::size_t rows) {
  IntArray a;
  a.rows = rows;
  a.cols = 0;
  a.data.resize(rows);
  return a;
}

}  // namespace

py::tuple cast(const bp::AnyBroadPhase& s, const std::vector<bp::Ray>& rays, bool all_hits,
               unsigned threads, const std::vector<std::uint32_t>* id_of) {
  auto id = [&](bp::Handle h) -> std::int64_t {
    return id_of ? static_cast<std::int64_t>((*id_of)[h.index])
                 : static_cast<std::int64_t>(s.user_data(h));
  };
  if (!all_hits) {
    std::vector<bp::RayHit> closest(rays.size());
    IntArray ids = column(rays.size()), t = column(rays.size());
    {
      py::gil_scoped_release nogil;
      if (id_of == nullptr) {
        bp::cast_rays(s, rays, closest, threads);
      } else {
        // Ties at the same t go to the smallest id, and a structure reuses
        // a removed object's slot for a later id: the visitor keeps the
        // best by (t, id) and clips at its t (ties are still reported).
        bp::detail::run_shares(rays.size(), threads,
                               [&](std::size_t begin, std::size_t end, std::size_t) {
                                 for (std::size_t r = begin; r < end; ++r) {
                                   bp::RayHit& best = closest[r];
                                   best = {bp::Handle{}, std::numeric_limits<double>::infinity()};
                                   s.cast_ray(rays[r], [&](bp::Handle h, double t) {
                                     if (best.handle.is_null() || t < best.t ||
                                         (t == best.t && id(h) < id(best.handle)))
                                       best = {h, t};
                                     return t;
                                   });
                                 }
                               });
      }
      for (std::size_t i = 0; i < rays.size(); ++i) {
        const bool hit = !closest[i].handle.is_null();
        ids.data[i] = hit ? id(closest[i].handle) : -1;
        t.data[i] = bits(hit ? closest[i].t : std::numeric_limits<double>::infinity());
      }
    }
    return py::make_tuple(std::move(ids), std::move(t));
  }
  bp::RayHitRows rows;
  IntArray offsets = column(rays.size() + 1), ids, t;
  {
    py::gil_scoped_release nogil;
    bp::cast_rays_all(s, rays, rows, threads);
    ids = column(rows.hits.size());
    t = column(rows.hits.size());
    for (std::size_t i = 0; i < rows.offsets.size(); ++i)
      offsets.data[i] = static_cast<std::int64_t>(rows.offsets[i]);
    // A row's hits are sorted by t, then slot; by t, then id here.
    for (std::size_t r = 0; r < rays.size(); ++r) {
      auto* first = rows.hits.data() + rows.offsets[r];
      auto* last = rows.hits.data() + rows.offsets[r + 1];
      std::sort(first, last, [&](const bp::RayHit& a, const bp::RayHit& b) {
        return a.t < b.t || (a.t == b.t && id(a.handle) < id(b.handle));
      });
    }
    for (std::size_t k = 0; k < rows.hits.size(); ++k) {
      ids.data[k] = id(rows.hits[k].handle);
      t.data[k] = bits(rows.hits[k].t);
    }
  }
  return py::make_tuple(std::move(offsets), std::move(ids), std::move(t));
}

py::tuple cast_lean(const bp::arrays::RayCaster& c, const std::vector<bp::Ray>& rays, bool all_hits,
                    unsigned threads, const std::vector<std::uint32_t>* id_of) {
  auto id = [&](std::uint32_t index) -> std::int64_t {
    return static_cast<std::int64_t>(id_of ? (*id_of)[index] : index);
  };
  if (!all_hits) {
    std::vector<bp::arrays::IndexHit> closest(rays.size());
    IntArray ids = column(rays.size()), t = column(rays.size());
    {
      py::gil_scoped_release nogil;
      if (id_of == nullptr) {
        c.closest(rays, closest, threads);
      } else {
        // Ties at the same t go to the smallest id, which need not be the
        // smallest index: the visitor keeps the best by (t, id) and clips
        // at its t (hits at exactly the clip are still reported).
        const unsigned shares = bp::detail::thread_count(threads);
        bp::detail::run_shares(
            rays.size(), std::min(shares, bp::ArrayOptions::kMaxThreads),
            [&](std::size_t begin, std::size_t end, std::size_t) {
              for (std::size_t r = begin; r < end; ++r) {
                bp::arrays::IndexHit& best = closest[r];
                c.cast(rays[r], [&](std::uint32_t i, double t) {
                  if (!best.hit() || t < best.t || (t == best.t && id(i) < id(best.index)))
                    best = {i, t};
                  return t;
                });
              }
            });
      }
      for (std::size_t i = 0; i < rays.size(); ++i) {
        ids.data[i] = closest[i].hit() ? id(closest[i].index) : -1;
        t.data[i] = bits(closest[i].t);  // +inf where nothing is hit
      }
    }
    return py::make_tuple(std::move(ids), std::move(t));
  }
  bp::arrays::IndexHitRows rows;
  IntArray offsets = column(rays.size() + 1), ids, t;
  {
    py::gil_scoped_release nogil;
    c.all(rays, rows, threads);
    ids = column(rows.hits.size());
    t = column(rows.hits.size());
    for (std::size_t i = 0; i < rows.offsets.size(); ++i)
      offsets.data[i] = static_cast<std::int64_t>(rows.offsets[i]);
    // A row's hits are sorted by t, then index; by t, then id here.
    if (id_of)
      for (std::size_t r = 0; r < rays.size(); ++r)
        std::sort(rows.hits.begin() + static_cast<std::ptrdiff_t>(rows.offsets[r]),
                  rows.hits.begin() + static_cast<std::ptrdiff_t>(rows.offsets[r + 1]),
                  [&](const bp::arrays::IndexHit& a, const bp::arrays::IndexHit& b) {
                    return a.t < b.t || (a.t == b.t && id(a.index) < id(b.index));
                  });
    for (std::size_t k = 0; k < rows.hits.size(); ++k) {
      ids.data[k] = id(rows.hits[k].index);
      t.data[k] = bits(rows.hits[k].t);
    }
  }
  return py::make_tuple(std::move(offsets), std::move(ids), std::move(t));
}

py::tuple ray_cast_once(const py::buffer& centers, const py::object& radii, const py::object& half,
                        const py::object& kinds, const py::object& groups, const py::object& masks,
                        const py::buffer& origins, const py::buffer& directions,
                        const py::object& tmax, const py::object& ray_masks, bool all_hits,
                        unsigned threads, const std::string& structure) {
  ObjectArrays o = object_arrays(centers, radii, half, kinds);
  attach_filters(o, groups, masks);
  const std::vector<bp::Ray> rays = ray_arrays(origins, directions, tmax, ray_masks);
  // The default: the lean grid for fewer rays than half the objects, else
  // the k-d tree. At 10^5 spheres (scaled-even) on one thread the grid
  // builds in 30 ms and casts 48 000 random rays a second, the tree 460 to
  // 620 ms and 100 000 (bench/arrays/rays_bench.cpp): the grid's call is
  // the shorter up to about 50 000 rays, and builds scale with the objects.
  const bool lean =
      structure == kLeanRays || (structure.empty() && 2 * rays.size() < o.objects.count);
  if (lean) {
    bp::arrays::RayCaster caster;
    {
      py::gil_scoped_release nogil;
      caster.build(o.objects);
    }
    return cast_lean(caster, rays, all_hits, threads, nullptr);
  }
  bp::Config config;
  config.expected_objects = o.objects.count;
  config.world = IndexCore::world_of(o.objects);
  std::unique_ptr<bp::AnyBroadPhase> s =
      bp::make_structure(structure.empty() ? kRayStructure : structure, config);
  {
    py::gil_scoped_release nogil;
    for (std::size_t i = 0; i < o.objects.count; ++i) {
      const bp::Handle h = s->insert(o.objects.shape(i), i, bp::Motion::fixed);
      if (!o.groups.empty()) s->set_filter(h, {o.groups[i], o.masks[i]});
    }
    s->settle();
  }
  return cast(*s, rays, all_hits, threads, nullptr);
}

}  // namespace broadphase_python
