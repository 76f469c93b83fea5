// The geometry of the MPI path (mpi.hpp, src/mpi/
// partition.cpp), which decides on which rank each pair is reported: a
// fuzzed tree of cuts (a grid over a fuzzed world, or any tree of cuts at
// nasty coordinates, as the bisection builds) and fuzzed spheres and boxes.
// Checked, for every input:
// - every point has exactly one owner, whose region holds it;
// - an object reaches (ranks_meeting, any margin >= 0) the owner of its
//   centre, and each rank at most once;
// - for two objects that overlap, the owner of the per-axis maximum of
//   their lower corners is reached by both: the rank that reports the pair
//   holds both objects, so no pair is lost and none is reported twice;
// - an object that alone() places inside a rank reaches that rank only,
//   and a pair with it is that rank's.
// It needs only mpi.h's declarations, no MPI runtime: the exchange itself
// runs in the MPI tests under mpirun (tests/mpi), which libFuzzer cannot
// drive.
#include <algorithm>
#include <array>
#include <broadphase/mpi.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>
#include <vector>

#include "support.hpp"

namespace {

using namespace broadphase;
namespace bd = broadphase::mpi;

// A tree of cuts over `ranks` leaves [first, first + ranks): returns the
// child reference (node index, or -1 - rank for a leaf).
int random_tree(FuzzedDataProvider& in, std::vector<bd::Partition::Node>& nodes, int first,
                int ranks) {
  if (ranks == 1) return -1 - first;
  const int left = in.ConsumeIntegralInRange(1, ranks - 1);
  const int index = static_cast<int>(nodes.size());
  nodes.push_back({in.ConsumeIntegralInRange(0, 2), fuzz::nasty_coordinate(in), 0, 0});
  const int l = random_tree(in, nodes, first, left);
  const int r = random_tree(in, nodes, first + left, ranks - left);
  nodes[static_cast<std::size_t>(index)].left = l;
  nodes[static_cast<std::size_t>(index)].right = r;
  return index;
}

void check_reach(const bd::Partition& p, const Shape& s, double margin, std::vector<int>& reach) {
  reach.clear();
  p.ranks_meeting(bounds(s), margin, reach);
  std::vector<int> sorted = reach;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
    fuzz::finding("ranks_meeting lists a rank twice");
  for (int r : reach)
    if (r < 0 || r >= p.size()) fuzz::finding("ranks_meeting lists rank " + std::to_string(r));
  for (int r = 0; r < p.size(); ++r)
    if (p.alone(r, bounds(s), margin) && !(reach.size() == 1 && reach[0] == r))
      fuzz::finding("alone() says rank " + std::to_string(r) +
                    " only, ranks_meeting lists others or not it");
}

bool reaches(const std::vector<int>& reach, int rank) {
  return std::find(reach.begin(), reach.end(), rank) != reach.end();
}

void check_owner(const bd::Partition& p, const Vec3& q, const char* what) {
  const int o = p.owner(q);
  if (o < 0 || o >= p.size()) fuzz::finding(std::string(what) + ": owner out of range");
  // Regions are half-open with faces at +-infinity: a point at +infinity
  // lies in none of them (it is never a centre or a lower corner).
  if (q.x == INFINITY || q.y == INFINITY || q.z == INFINITY) return;
  for (int r = 0; r < p.size(); ++r)
    if (p.holds(r, q) != (r == o))
      fuzz::finding(
          std::string(what) + ": rank " + std::to_string(r) +
          (r == o ? " owns a point its region does not hold" : " holds a point another rank owns"));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  bd::Partition part;
  if (in.ConsumeBool()) {
    // A grid over a finite, non-empty world, as Domain builds it.
    Aabb world;
    for (int a = 0; a < 3; ++a) {
      double lo = fuzz::nasty_coordinate(in), hi = fuzz::nasty_coordinate(in);
      if (lo > hi) std::swap(lo, hi);
      if (!(lo < hi)) hi = lo + 1;
      if (!std::isfinite(hi)) return 0;
      world.lo[a] = lo;
      world.hi[a] = hi;
    }
    const std::array<int, 3> dims{in.ConsumeIntegralInRange(1, 4), in.ConsumeIntegralInRange(1, 4),
                                  in.ConsumeIntegralInRange(1, 4)};
    part = bd::Partition::grid(world, dims);
  } else {
    // Any tree of cuts (the bisection's are chosen from the objects).
    const int ranks = in.ConsumeIntegralInRange(1, 16);
    std::vector<bd::Partition::Node> nodes;
    random_tree(in, nodes, 0, ranks);
    part = bd::Partition(std::move(nodes), ranks);
  }
  const double margin = in.ConsumeBool() ? 0.0 : fuzz::nasty_size(in);
  std::vector<Shape> shapes;
  const int n = in.ConsumeIntegralInRange(1, 12);
  for (int i = 0; i < n && in.remaining_bytes() > 0; ++i) shapes.push_back(fuzz::nasty_shape(in));
  std::vector<std::vector<int>> reach(shapes.size());
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    check_reach(part, shapes[i], margin, reach[i]);
    check_owner(part, shapes[i].center, "a centre");
    if (!reaches(reach[i], part.owner(shapes[i].center)))
      fuzz::finding("object " + std::to_string(i) + " does not reach the owner of its centre");
  }
  for (std::size_t i = 0; i < shapes.size(); ++i)
    for (std::size_t j = i + 1; j < shapes.size(); ++j) {
      if (!overlaps(shapes[i], shapes[j])) continue;
      const Aabb a = bounds(shapes[i]), b = bounds(shapes[j]);
      const Vec3 q{std::max(a.lo.x, b.lo.x), std::max(a.lo.y, b.lo.y), std::max(a.lo.z, b.lo.z)};
      check_owner(part, q, "a pair's point");
      const int o = part.owner(q);
      for (const Aabb* box : {&a, &b})
        for (int r = 0; r < part.size(); ++r)
          if (part.alone(r, *box, margin) && r != o)
            fuzz::finding("objects " + std::to_string(i) + " and " + std::to_string(j) +
                          " overlap and one lies inside rank " + std::to_string(r) +
                          ", but their pair is rank " + std::to_string(o) + "'s");
      if (!reaches(reach[i], o) || !reaches(reach[j], o))
        fuzz::finding("objects " + std::to_string(i) + " and " + std::to_string(j) +
                      " overlap, but the rank that reports their pair (" + std::to_string(o) +
                      ") does not hold both");
    }
  return 0;
}
