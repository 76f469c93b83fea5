// The lean path's one-shot calls over the caller's arrays (arrays.hpp): the
// sphere kernel for sets of spheres, else a multi-level hashed grid of float
// boxes built per call; exact tests read from the caller's data. The tracker
// is in pair_tracker.cpp.
#include <algorithm>
#include <bit>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/detail/in_order.hpp>
#include <broadphase/handle.hpp>
#include <cmath>
#include <limits>
#include <sstream>
#include <thread>

#include "box_grid.hpp"
#include "calls.hpp"
#include "sphere_kernel.hpp"

namespace broadphase::arrays {
namespace {

// The grid, the chunk hand-over and the sphere kernel (src/detail/).
using namespace detail;  // NOLINT(google-build-using-namespace)

// Indices are 32-bit; one value is kept free so that a count fits too.
constexpr std::size_t kMaxObjects = std::numeric_limits<std::uint32_t>::max();

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

[[noreturn]] void bad(const char* what, std::size_t i, const std::string& why) {
  throw InvalidObjects(std::string(what) + "[" + std::to_string(i) + "]: " + why, i);
}

// One set, or two concatenated (the bipartite calls): index k < na is
// a's object k, the others b's object k - na.
struct Source {
  const Objects* a = nullptr;
  const Objects* b = nullptr;
  std::size_t na = 0;
  std::size_t n = 0;

  Shape shape(std::size_t k) const {
    return k < na ? read_shape(*a, static_cast<std::uint32_t>(k))
                  : read_shape(*b, static_cast<std::uint32_t>(k - na));
  }
};

detail::BigVector<AabbF> float_bounds(const Source& src) {
  detail::BigVector<AabbF> boxes(src.n);
  for (std::size_t k = 0; k < src.n; ++k) boxes[k] = bounds_f(src.shape(k));
  return boxes;
}

ArrayCallStats one_shot(const Source& src, bool bipartite, const PairSink& sink,
                        const ArrayOptions& options) {
  ArrayCallStats stats;
  const detail::BigVector<AabbF> boxes = float_bounds(src);
  ArrayGrid grid;
  // Up to 8 bucket starts an object (32 bytes, freed with the call) buy
  // the row-by-row layout on most levels (see ArrayGrid::build).
  grid.build(boxes, 8);

  // A bipartite call where one set has filters and the other not: the
  // other's objects take the default filter.
  PairFilterColumns filters;
  std::vector<std::uint32_t> default_group, default_mask;
  if (!bipartite) {
    filters = PairFilterColumns::of(*src.a);
  } else if (!src.a->groups.empty() || !src.b->groups.empty()) {
    const Filter d;
    auto side = [&](const Objects& o, std::span<const std::uint32_t>& g,
                    std::span<const std::uint32_t>& m) {
      if (!o.groups.empty()) {
        g = o.groups;
        m = o.masks;
        return;
      }
      default_group.assign(o.count, d.group);
      default_mask.assign(o.count, d.mask);
      g = default_group;
      m = default_mask;
    };
    side(*src.a, filters.gi, filters.mi);
    side(*src.b, filters.gj, filters.mj);
  }
  Emitter emit(sink, options.sorted, stats, filters);
  const auto na = static_cast<std::uint32_t>(src.na);
  // The shapes in the probing order, so that a probe's exact tests read
  // its partners from nearby memory rather than from the caller's order
  // (perf at 1 000 000 spheres: 28% of the call on those reads before).
  // Written in the caller's order from each object's place: the reads of
  // the caller's columns are then sequential (a miss per column per object
  // when read in the probing order).
  detail::BigVector<Shape> placed(grid.probe_count());
  {
    detail::BigVector<std::uint32_t> at(src.n);
    for (std::size_t k = 0; k < placed.size(); ++k)
      at[grid.probe_object(k)] = static_cast<std::uint32_t>(k);
    for (std::size_t i = 0; i < src.n; ++i) placed[at[i]] = src.shape(i);
  }
  run_in_order<PairChunk>(
      grid.probe_count(), thread_count(options.threads),
      [&](std::size_t begin, std::size_t end, PairChunk& out) {
        out.pairs.clear();
        out.tests = 0;
        for (std::size_t k = begin; k < end; ++k) {
          const std::uint32_t i = grid.probe_object(k);
          const Shape& si = placed[k];
          grid.probe(k, [&](std::uint32_t j, std::uint32_t p) {
            if (bipartite && ((i < na) == (j < na))) return;
            ++out.tests;
            if (!overlaps(si, p == ArrayGrid::kNoPlace ? src.shape(j) : placed[p])) return;
            if (bipartite)
              out.pairs.push_back(i < na ? IndexPair{i, j - na} : IndexPair{j, i - na});
            else
              out.pairs.push_back(ordered(i, j));
          });
        }
      },
      [&](PairChunk& c) { return emit.deliver(c); });
  emit.finish();
  return stats;
}

}  // namespace

namespace {

// The checks of check_objects that do not read a value: the count and the
// columns.
void check_columns(const Objects& o, const char* what) {
  if (o.count > kMaxObjects)
    throw InvalidObjects(std::string(what) + ": " + std::to_string(o.count) +
                             " objects, more than 32-bit indices can name (" +
                             std::to_string(kMaxObjects) + ")",
                         SIZE_MAX);
  detail::check_filter_columns(o, what);
  if (o.count == 0) return;
  auto missing = [&](const char* column) {
    throw InvalidObjects(std::string(what) + ": column " + column + " is missing", SIZE_MAX);
  };
  if (o.x.empty()) missing("x");
  if (o.y.empty()) missing("y");
  if (o.z.empty()) missing("z");
  const bool halves = !o.half_x.empty() && !o.half_y.empty() && !o.half_z.empty();
  if (o.kind == nullptr && o.radius.empty() && !halves)
    missing(o.half_x.empty() ? "half_x (or radius)" : (o.half_y.empty() ? "half_y" : "half_z"));
}

// The values of object i.
void check_object(const Objects& o, std::size_t i, const char* what) {
  static const char* const kAxis[3] = {"x", "y", "z"};
  static const char* const kHalf[3] = {"half_x", "half_y", "half_z"};
  const Column* centre[3] = {&o.x, &o.y, &o.z};
  const Column* half[3] = {&o.half_x, &o.half_y, &o.half_z};
  for (int a = 0; a < 3; ++a) {
    const double v = centre[a]->at(i);
    if (!std::isfinite(v)) bad(what, i, std::string(kAxis[a]) + " is " + fmt(v));
  }
  bool sphere = !o.radius.empty();
  if (o.kind != nullptr) {
    const std::uint8_t k = o.kind[static_cast<std::ptrdiff_t>(i) * o.kind_stride];
    if (k > 1) bad(what, i, "kind is " + std::to_string(k) + " (0 sphere, 1 box)");
    sphere = k == 0;
  }
  if (sphere) {
    if (o.radius.empty()) bad(what, i, "is a sphere but the radius column is missing");
    const double r = o.radius.at(i);
    if (!std::isfinite(r)) bad(what, i, "radius is " + fmt(r));
    if (r < 0) bad(what, i, "radius is negative (" + fmt(r) + ")");
  } else {
    for (int a = 0; a < 3; ++a) {
      if (half[a]->empty())
        bad(what, i, std::string("is a box but the ") + kHalf[a] + " column is missing");
      const double h = half[a]->at(i);
      if (!std::isfinite(h)) bad(what, i, std::string(kHalf[a]) + " is " + fmt(h));
      if (h < 0) bad(what, i, std::string(kHalf[a]) + " is negative (" + fmt(h) + ")");
    }
  }
}

}  // namespace

void ArrayOptions::check() const {
  ::broadphase::detail::check_number("arrays", "skin", skin, 0, std::numeric_limits<double>::max(),
                                     true);
  ::broadphase::detail::check_integer("arrays", "threads", threads, 0, kMaxThreads);
}

void check_objects(const Objects& o, const char* what) {
  check_columns(o, what);
  for (std::size_t i = 0; i < o.count; ++i) check_object(o, i, what);
}

namespace detail {

void check_filter_columns(const Objects& o, const char* what) {
  if (o.groups.empty() && o.masks.empty()) return;
  if (o.groups.size() != o.count || o.masks.size() != o.count)
    throw InvalidObjects(std::string(what) + ": the filter columns hold " +
                             std::to_string(o.groups.size()) + " groups and " +
                             std::to_string(o.masks.size()) + " masks for " +
                             std::to_string(o.count) + " objects",
                         SIZE_MAX);
}

void check_listed(const Objects& o, const std::vector<std::uint64_t>& listed) {
  check_columns(o, "objects");
  for (std::size_t w = 0; w < listed.size(); ++w)
    for (std::uint64_t b = listed[w]; b != 0; b &= b - 1)
      check_object(o, w * 64 + static_cast<unsigned>(std::countr_zero(b)), "objects");
}

}  // namespace detail

ArrayCallStats find_pairs(const Objects& objects, const PairSink& sink,
                          const ArrayOptions& options) {
  options.check();
  detail::check_filter_columns(objects, "objects");
  // The sphere kernel checks the values it reads in its first pass; a set
  // it refuses, for a bad value or another reason, is checked here.
  {
    detail::SphereCells cells;
    if (cells.build(objects))
      return cell_pairs(cells, sink, options, nullptr, PairFilterColumns::of(objects));
  }
  check_objects(objects);
  Source src{&objects, nullptr, objects.count, objects.count};
  return one_shot(src, false, sink, options);
}

ArrayCallStats find_pairs(const Objects& objects, std::vector<IndexPair>& out,
                          const ArrayOptions& options) {
  return find_pairs(objects, append_to(out), options);
}

ArrayCallStats find_pairs(const Objects& a, const Objects& b, const PairSink& sink,
                          const ArrayOptions& options) {
  options.check();
  check_objects(a, "a");
  check_objects(b, "b");
  if (a.count + b.count > kMaxObjects)
    throw InvalidObjects("a and b: " + std::to_string(a.count + b.count) +
                             " objects together, more than 32-bit indices can name",
                         SIZE_MAX);
  Source src{&a, &b, a.count, a.count + b.count};
  return one_shot(src, true, sink, options);
}

ArrayCallStats find_pairs(const Objects& a, const Objects& b, std::vector<IndexPair>& out,
                          const ArrayOptions& options) {
  return find_pairs(a, b, append_to(out), options);
}

std::vector<std::uint32_t> query(const Objects& objects, const Shape& shape) {
  require_valid(shape);
  check_objects(objects);
  std::vector<std::uint32_t> out;
  const AabbF qb = bounds_f(shape);
  for (std::size_t i = 0; i < objects.count; ++i) {
    const Shape s = objects.shape(i);
    if (qb.overlaps(bounds_f(s)) && overlaps(shape, s))
      out.push_back(static_cast<std::uint32_t>(i));
  }
  return out;
}

}  // namespace broadphase::arrays
