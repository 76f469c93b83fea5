// The lean path's tests' shared pieces: the layouts a caller keeps its
// objects in (`Storage`), the brute-force oracle, and random worlds of
// spheres and boxes. Used by test_arrays.cpp and test_pair_tracker.cpp.
#pragma once

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace broadphase::arrays_testing {

// How the caller keeps its objects.
enum class Layout {
  aos_double,      // one record of 8 doubles per object (x y z r hx hy hz pad)
  soa_double,      // one array per column
  aos_float,       // records of 8 floats
  soa_float,       // float columns
  strided_double,  // records of 15 doubles with the values at odd places
};
constexpr Layout kLayouts[] = {Layout::aos_double, Layout::soa_double, Layout::aos_float,
                               Layout::soa_float, Layout::strided_double};
inline const char* name(Layout l) {
  switch (l) {
    case Layout::aos_double:
      return "aos_double";
    case Layout::soa_double:
      return "soa_double";
    case Layout::aos_float:
      return "aos_float";
    case Layout::soa_float:
      return "soa_float";
    case Layout::strided_double:
      return "strided_double";
  }
  return "?";
}
inline bool is_float(Layout l) { return l == Layout::aos_float || l == Layout::soa_float; }

// The caller's memory for a set of shapes in one layout, and its view.
// `scalar_radius`: every object a sphere of one shared radius (stride 0).
struct Storage {
  std::vector<double> d;
  std::vector<float> f;
  std::vector<std::uint8_t> kinds;
  Objects objects;

  Storage(const std::vector<Shape>& shapes, Layout layout, bool scalar_radius = false) {
    const std::size_t n = shapes.size();
    bool any_sphere = false, any_box = false;
    for (const Shape& s : shapes) (s.is_sphere() ? any_sphere : any_box) = true;
    const bool mixed = any_sphere && any_box;
    const bool aos = layout == Layout::aos_double || layout == Layout::aos_float ||
                     layout == Layout::strided_double;
    const std::size_t rec = layout == Layout::strided_double ? 15 : 8;
    auto place = [&](std::size_t i, int col) {  // element index of column col of object i
      if (layout == Layout::strided_double) return i * rec + 1 + 2 * static_cast<std::size_t>(col);
      return aos ? i * rec + static_cast<std::size_t>(col) : static_cast<std::size_t>(col) * n + i;
    };
    const std::size_t total = std::max<std::size_t>(1, n * rec + 16);
    if (is_float(layout))
      f.assign(total, 0);
    else
      d.assign(total, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const Shape& s = shapes[i];
      const double v[7] = {s.center.x, s.center.y, s.center.z, s.half.x,
                           s.half.x,   s.half.y,   s.half.z};
      for (int c = 0; c < 7; ++c) {
        if (is_float(layout))
          f[place(i, c)] = static_cast<float>(v[c]);
        else
          d[place(i, c)] = v[c];
      }
    }
    objects.count = n;
    const std::ptrdiff_t stride = aos ? static_cast<std::ptrdiff_t>(rec) : 1;
    auto column = [&](int c) {
      if (is_float(layout)) return Column::of(f.data() + place(0, c), stride);
      return Column::of(d.data() + place(0, c), stride);
    };
    objects.x = column(0);
    objects.y = column(1);
    objects.z = column(2);
    if (any_sphere || n == 0) {
      objects.radius = column(3);
      if (scalar_radius) objects.radius.stride = 0;
    }
    if (any_box) {
      objects.half_x = column(4);
      objects.half_y = column(5);
      objects.half_z = column(6);
    }
    if (mixed) {
      kinds.resize(n);
      for (std::size_t i = 0; i < n; ++i) kinds[i] = shapes[i].is_sphere() ? 0 : 1;
      objects.kind = kinds.data();
    }
  }
  Storage(const Storage&) = delete;
};

inline bool less(const IndexPair& a, const IndexPair& b) {
  return a.i != b.i ? a.i < b.i : a.j < b.j;
}

// Object i's filter: from the filter columns, else the default.
inline Filter filter_of(const Objects& o, std::uint32_t i) {
  if (o.groups.empty()) return {};
  return {o.groups[i], o.masks[i]};
}

// Each object's shape and filter, read once from its columns (read per
// pair, the columns' reading was most of the oracle's time under ASan).
inline std::pair<std::vector<Shape>, std::vector<Filter>> shapes_and_filters(const Objects& o) {
  std::pair<std::vector<Shape>, std::vector<Filter>> out;
  out.first.reserve(o.count);
  out.second.reserve(o.count);
  for (std::uint32_t i = 0; i < o.count; ++i) {
    out.first.push_back(o.shape(i));
    out.second.push_back(filter_of(o, i));
  }
  return out;
}

// Brute force over overlaps() and the filter rule.
inline std::vector<IndexPair> oracle(const Objects& o) {
  const auto [s, f] = shapes_and_filters(o);
  std::vector<IndexPair> out;
  for (std::uint32_t i = 0; i < o.count; ++i)
    for (std::uint32_t j = i + 1; j < o.count; ++j)
      if (filters_pass(f[i], f[j]) && overlaps(s[i], s[j])) out.push_back({i, j});
  return out;
}

inline std::vector<IndexPair> oracle(const Objects& a, const Objects& b) {
  const auto [sa, fa] = shapes_and_filters(a);
  const auto [sb, fb] = shapes_and_filters(b);
  std::vector<IndexPair> out;
  for (std::uint32_t i = 0; i < a.count; ++i)
    for (std::uint32_t j = 0; j < b.count; ++j)
      if (filters_pass(fa[i], fb[j]) && overlaps(sa[i], sb[j])) out.push_back({i, j});
  return out;
}

// Filter columns for n objects: random bits (layers 0), or `layers` groups
// each pairing with itself and its two neighbouring groups only.
struct FilterColumns {
  std::vector<std::uint32_t> groups, masks;
  FilterColumns(std::size_t n, int layers, Rng& rng) { redraw(n, layers, rng); }
  void redraw(std::size_t n, int layers, Rng& rng) {
    groups.resize(n);
    masks.resize(n);
    for (std::size_t i = 0; i < n; ++i) draw(i, layers, rng);
  }
  void draw(std::size_t i, int layers, Rng& rng) {
    if (layers == 0) {
      groups[i] = static_cast<std::uint32_t>(rng.below(16));
      masks[i] = static_cast<std::uint32_t>(rng.next());
      return;
    }
    const auto n = static_cast<std::uint32_t>(layers);
    const auto l = static_cast<std::uint32_t>(rng.below(n));
    groups[i] = 1u << l;
    masks[i] = (1u << l) | (1u << ((l + 1) % n)) | (1u << ((l + n - 1) % n));
  }
  void attach(Objects& o) const {
    o.groups = groups;
    o.masks = masks;
  }
};

inline std::vector<IndexPair> sorted(std::vector<IndexPair> v) {
  std::sort(v.begin(), v.end(), less);
  return v;
}

// The kinds of random worlds.
// Sets of spheres only (`spheres`, `similar`, `lattice`, `sizes`) take
// the one-shot's cell kernel (src/arrays/sphere_kernel.hpp) where it suits
// them; the others the multi-level grid.
enum class World {
  spheres,
  boxes,
  mixed,
  touching,
  coincident,
  decades,
  zero,
  similar,
  lattice,
  sizes
};
constexpr World kWorlds[] = {World::spheres,    World::boxes,   World::mixed, World::touching,
                             World::coincident, World::decades, World::zero,  World::similar,
                             World::lattice,    World::sizes};
inline const char* name(World w) {
  const char* names[] = {"spheres", "boxes", "mixed",   "touching", "coincident",
                         "decades", "zero",  "similar", "lattice",  "sizes"};
  return names[static_cast<int>(w)];
}

inline Shape random_shape(World w, Rng& rng, double world) {
  const Vec3 c{rng.uniform(0, world), rng.uniform(0, world), rng.uniform(0, world)};
  auto box = [&](double s) {
    return Shape::box(c, {rng.uniform(0, s), rng.uniform(0, s), rng.uniform(0, s)});
  };
  switch (w) {
    case World::spheres:
      return Shape::sphere(c, rng.uniform(0.5, 5));
    case World::boxes:
      return box(5);
    case World::mixed:
      return rng.below(2) ? Shape::sphere(c, rng.uniform(0, 5)) : box(5);
    case World::touching: {
      // A lattice of spacing 4 with radius 2 or half-extents 2: neighbours
      // touch exactly (all values are small integers, exact in float too).
      const Vec3 l{4.0 * static_cast<double>(rng.below(6)), 4.0 * static_cast<double>(rng.below(6)),
                   4.0 * static_cast<double>(rng.below(6))};
      return rng.below(2) ? Shape::sphere(l, 2) : Shape::box(l, {2, 2, 2});
    }
    case World::coincident: {
      const Vec3 l{static_cast<double>(rng.below(3)) * 10, 5, 5};
      return rng.below(3) ? Shape::sphere(l, static_cast<double>(rng.below(3)))
                          : Shape::box(l, {0, 1, 0.5});
    }
    case World::decades: {
      const double s = std::pow(10.0, rng.uniform(-3, 2.5));
      return rng.below(2) ? Shape::sphere(c, s) : Shape::box(c, {s, s * 0.1, s * 3});
    }
    case World::zero:
      return rng.below(2) ? Shape::sphere(c, rng.below(4) ? 0.0 : 3.0) : box(rng.below(2) ? 0 : 3);
    case World::similar:
      return Shape::sphere(c, rng.uniform(1, 2));
    case World::lattice: {
      // Spheres of radius 2 or 1 on a lattice of spacing 4 (neighbours of
      // radius 2 touch exactly, on the cells' borders), some on one place.
      const Vec3 l{4.0 * static_cast<double>(rng.below(6)), 4.0 * static_cast<double>(rng.below(6)),
                   4.0 * static_cast<double>(rng.below(6))};
      return Shape::sphere(l, rng.below(4) ? 2.0 : 1.0);
    }
    case World::sizes:
      return Shape::sphere(c, std::pow(10.0, rng.uniform(-3, 1)));
  }
  return Shape::sphere(c, 1);
}

inline std::vector<Shape> random_world(World w, std::size_t n, Rng& rng) {
  const double world = 20.0 * std::cbrt(static_cast<double>(n) / 10.0) + 1;
  std::vector<Shape> out;
  for (std::size_t i = 0; i < n; ++i) out.push_back(random_shape(w, rng, world));
  return out;
}

}  // namespace broadphase::arrays_testing
