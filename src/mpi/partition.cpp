// The subdomains as a tree of cuts: the grid, and the queries both
// decompositions share (the bisection's cuts are found in domain.cpp).
#include <algorithm>
#include <broadphase/mpi.hpp>
#include <limits>
#include <stdexcept>
#include <string>

namespace broadphase::mpi {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

// Fills rank regions by walking the tree from `child` with `box`. A cut
// outside its node's box (a tree built by hand need not nest its cuts)
// leaves one side empty: the region is the box clipped by the cut, exactly
// the points owner() sends there.
void fill_regions(const std::vector<Partition::Node>& nodes, int child, Aabb box,
                  std::vector<Aabb>& regions) {
  if (child < 0) {
    regions[static_cast<std::size_t>(-1 - child)] = box;
    return;
  }
  const Partition::Node& n = nodes[static_cast<std::size_t>(child)];
  Aabb left = box, right = box;
  left.hi[n.axis] = std::min(box.hi[n.axis], n.cut);
  right.lo[n.axis] = std::max(box.lo[n.axis], n.cut);
  fill_regions(nodes, n.left, left, regions);
  fill_regions(nodes, n.right, right, regions);
}

// The grid's cells [c0, c1) per axis as a balanced subtree; returns the
// child reference (node index, or -1 - rank for a single cell).
int build_grid(std::vector<Partition::Node>& nodes, const Aabb& world,
               const std::array<int, 3>& dims, std::array<int, 3> c0, std::array<int, 3> c1) {
  int axis = -1;
  int most = 1;
  for (int a = 0; a < 3; ++a)
    if (c1[a] - c0[a] > most) {
      most = c1[a] - c0[a];
      axis = a;
    }
  if (axis < 0) return -1 - ((c0[0] * dims[1] + c0[1]) * dims[2] + c0[2]);
  const int mid = (c0[axis] + c1[axis]) / 2;
  // The same expression for every cut, so neighbouring cells share it exactly.
  const double cut = world.lo[axis] + (world.hi[axis] - world.lo[axis]) * mid / dims[axis];
  const int index = static_cast<int>(nodes.size());
  nodes.push_back({axis, cut, 0, 0});
  std::array<int, 3> left_hi = c1, right_lo = c0;
  left_hi[axis] = mid;
  right_lo[axis] = mid;
  const int left = build_grid(nodes, world, dims, c0, left_hi);
  const int right = build_grid(nodes, world, dims, right_lo, c1);
  nodes[static_cast<std::size_t>(index)].left = left;
  nodes[static_cast<std::size_t>(index)].right = right;
  return index;
}
}  // namespace

Partition::Partition(std::vector<Node> nodes, int ranks)
    : nodes_(std::move(nodes)), regions_(static_cast<std::size_t>(ranks)) {
  const Aabb everything{{-kInf, -kInf, -kInf}, {kInf, kInf, kInf}};
  fill_regions(nodes_, nodes_.empty() ? -1 : 0, everything, regions_);
}

Partition Partition::grid(const Aabb& world, std::array<int, 3> dims) {
  std::vector<Node> nodes;
  build_grid(nodes, world, dims, {0, 0, 0}, dims);
  return Partition(std::move(nodes), dims[0] * dims[1] * dims[2]);
}

int Partition::owner(const Vec3& p) const {
  if (nodes_.empty()) return 0;
  int i = 0;
  for (;;) {
    const Node& n = nodes_[static_cast<std::size_t>(i)];
    const int child = p[n.axis] < n.cut ? n.left : n.right;
    if (child < 0) return -1 - child;
    i = child;
  }
}

void Partition::ranks_meeting(const Aabb& box, double margin, std::vector<int>& out) const {
  if (nodes_.empty()) {
    out.push_back(0);
    return;
  }
  // A closed box meets the half-open side below a cut when lo < cut, the
  // side above when hi >= cut: the same comparisons as owner(), so a point
  // of the box always finds its owner among these ranks. Both trees are
  // balanced (depth about log2 of the ranks), so the stack never fills.
  constexpr int kDepth = 256;
  int stack[kDepth];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const int child = stack[--top];
    if (child < 0) {
      out.push_back(-1 - child);
      continue;
    }
    const Node& n = nodes_[static_cast<std::size_t>(child)];
    if (top + 2 > kDepth) throw std::logic_error("Partition: cut tree deeper than 256");
    if (box.hi[n.axis] + margin >= n.cut) stack[top++] = n.right;
    if (box.lo[n.axis] - margin < n.cut) stack[top++] = n.left;
  }
}

bool Partition::holds(int rank, const Vec3& p) const {
  const Aabb& r = regions_[static_cast<std::size_t>(rank)];
  return r.lo.x <= p.x && p.x < r.hi.x && r.lo.y <= p.y && p.y < r.hi.y && r.lo.z <= p.z &&
         p.z < r.hi.z;
}

bool Partition::alone(int rank, const Aabb& box, double margin) const {
  const Aabb& r = regions_[static_cast<std::size_t>(rank)];
  // ranks_meeting goes above a cut when hi + margin >= cut and below it
  // when lo - margin < cut; written so that a NaN is never alone.
  for (int a = 0; a < 3; ++a)
    if (!(box.hi[a] + margin < r.hi[a]) || !(box.lo[a] - margin >= r.lo[a])) return false;
  return true;
}

std::array<int, 3> parse_dims(const std::string& text) {
  std::array<int, 3> d{};
  std::size_t pos = 0;
  for (int a = 0; a < 3; ++a) {
    std::size_t used = 0;
    long v = 0;
    try {
      v = std::stol(text.substr(pos), &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || v < 1 || v > 1 << 20 || text[pos] == '+' || text[pos] == '-')
      throw InvalidConfig("grid '" + text + "': expected AxBxC with whole numbers >= 1");
    d[static_cast<std::size_t>(a)] = static_cast<int>(v);
    pos += used;
    if (a < 2) {
      if (pos >= text.size() || text[pos] != 'x')
        throw InvalidConfig("grid '" + text + "': expected AxBxC with whole numbers >= 1");
      ++pos;
    }
  }
  if (pos != text.size())
    throw InvalidConfig("grid '" + text + "': expected AxBxC with whole numbers >= 1");
  return d;
}

}  // namespace broadphase::mpi
