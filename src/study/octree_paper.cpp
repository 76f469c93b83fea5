#include <algorithm>
#include <bit>
#include <broadphase/study/octree_paper.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace broadphase {

namespace {

// The index of the first node of each level: 0, 1, 9, 73 (8 * previous + 1).
constexpr std::uint32_t kLevelStart[OctreePaper::kDepth + 1] = {0, 1, 9, 73, 585};

// Interleaves the bits of three level-local coordinates, x lowest, so that
// the child octant (x&1) | (y&1)<<1 | (z&1)<<2 lands in the low three bits.
constexpr std::uint32_t interleave(int x, int y, int z) {
  std::uint32_t m = 0;
  for (int b = 0; b < OctreePaper::kFinest; ++b) {
    m |= static_cast<std::uint32_t>(((x >> b) & 1) | (((y >> b) & 1) << 1) | (((z >> b) & 1) << 2))
         << (3 * b);
  }
  return m;
}

}  // namespace

OctreePaper::OctreePaper(const Config& c, const OctreePaperOptions& o) {
  check_config(c, "octree-paper");
  o.check();
  clamp_outside_ = o.clamp_outside;
  origin_ = c.world.lo;
  const Vec3 extent = c.world.hi - c.world.lo;
  const double side = std::max(extent.x, std::max(extent.y, extent.z));
  if (!(side > 0) || !std::isfinite(side))
    throw InvalidConfig("octree-paper: the world box must be finite and non-empty");
  scale_ = kFinestCells / side;
}

// One formula for every cell decision, monotone in `v` (a subtraction and a
// multiplication by a positive constant, both rounded to nearest, then a
// comparison): if a <= b then cell_of(a) <= cell_of(b). Values below the
// cube give -1, values at or beyond its far side give kFinestCells.
int OctreePaper::cell_of(double v, int axis) const {
  const double t = (v - origin_[axis]) * scale_;
  if (!(t >= 0)) return -1;  // also a NaN from a malformed query shape
  if (t >= kFinestCells) return kFinestCells;
  return static_cast<int>(t);
}

OctreePaper::CellRange OctreePaper::range_of(const Aabb& b) const {
  CellRange r{};
  r.empty = false;
  for (int a = 0; a < 3; ++a) {
    const int lo = cell_of(b.lo[a], a);
    const int hi = cell_of(b.hi[a], a);
    // Objects outside the cube live at the root unless they are clamped
    // into it, so a range wholly outside reaches no descendant.
    if (!clamp_outside_ && (hi < 0 || lo >= kFinestCells)) r.empty = true;
    r.lo[a] = std::clamp(lo, 0, kFinestCells - 1);
    r.hi[a] = std::clamp(hi, 0, kFinestCells - 1);
  }
  return r;
}

std::uint32_t OctreePaper::node_of(const Shape& s) const {
  const Aabb b = bounds(s);
  int lo[3] = {0, 0, 0};
  unsigned straddle = 0;
  for (int a = 0; a < 3; ++a) {
    lo[a] = cell_of(b.lo[a], a);
    int hi = cell_of(b.hi[a], a);
    if (lo[a] < 0 || hi >= kFinestCells) {
      if (!clamp_outside_) return 0;  // not inside the world cube
      lo[a] = std::clamp(lo[a], 0, kFinestCells - 1);
      hi = std::clamp(hi, 0, kFinestCells - 1);
    }
    straddle |= static_cast<unsigned>(lo[a] ^ hi);
  }
  // The highest bit in which the corners' cells differ is the level at
  // which they part; the object lives one level above.
  const int level = kFinest - std::bit_width(straddle);
  const int shift = kFinest - level;
  return kLevelStart[level] + interleave(lo[0] >> shift, lo[1] >> shift, lo[2] >> shift);
}

int OctreePaper::level_of(std::uint32_t node) {
  int level = 0;
  while (node >= kLevelStart[level + 1]) ++level;
  return level;
}

OctreePaper::NodeCell OctreePaper::decode(std::uint32_t node) {
  NodeCell c{level_of(node), 0, 0, 0};
  const std::uint32_t m = node - kLevelStart[c.level];
  for (int b = 0; b < c.level; ++b) {
    c.x |= static_cast<int>((m >> (3 * b)) & 1) << b;
    c.y |= static_cast<int>((m >> (3 * b + 1)) & 1) << b;
    c.z |= static_cast<int>((m >> (3 * b + 2)) & 1) << b;
  }
  return c;
}

void OctreePaper::link(std::uint32_t node, std::uint32_t slot) {
  lists_[node].push_back(slot);
  for (std::uint32_t n = node;; n = (n - 1) / 8) {
    ++subtree_count_[n];
    if (n == 0) break;
  }
}

void OctreePaper::unlink(std::uint32_t node, std::uint32_t slot) {
  std::vector<std::uint32_t>& list = lists_[node];
  const auto it = std::find(list.begin(), list.end(), slot);
  if (it == list.end()) throw std::logic_error("octree-paper: object missing from its node");
  *it = list.back();
  list.pop_back();
  for (std::uint32_t n = node;; n = (n - 1) / 8) {
    --subtree_count_[n];
    if (n == 0) break;
  }
}

Handle OctreePaper::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  link(node_of(s), h.index);
  return h;
}

void OctreePaper::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  unlink(node_of(store_.shape(i)), i);
  store_.erase(h);
}

void OctreePaper::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.index_of(h);
  require_valid(s);
  const std::uint32_t from = node_of(store_.shape(i));
  const std::uint32_t to = node_of(s);
  store_.set_shape(h, s);
  if (from == to) return;
  unlink(from, i);
  link(to, i);
}

std::size_t OctreePaper::memory_bytes() const {
  std::size_t bytes = store_.memory_bytes() + sizeof(lists_) + sizeof(subtree_count_);
  for (const auto& list : lists_) bytes += list.capacity() * sizeof(std::uint32_t);
  return bytes;
}

void OctreePaper::validate() const {
  const auto fail = validate_store("octree-paper");
  std::vector<char> seen(store_.slot_count(), 0);
  std::size_t listed = 0;
  for (std::uint32_t node = 0; node < kNodeCount; ++node) {
    std::size_t below = lists_[node].size();
    if (level_of(node) < kFinest)
      for (std::uint32_t k = 1; k <= 8; ++k) below += subtree_count_[8 * node + k];
    if (subtree_count_[node] != below)
      fail("subtree count of node " + std::to_string(node) + " disagrees with its lists");
    for (std::uint32_t i : lists_[node]) {
      if (!store_.slots().alive(i) || seen[i])
        fail("node " + std::to_string(node) + " lists a dead or repeated object " +
             std::to_string(i));
      seen[i] = 1;
      if (node_of(store_.shape(i)) != node)
        fail("object " + std::to_string(i) + " is in node " + std::to_string(node) +
             ", its bounds prescribe another");
      ++listed;
    }
  }
  if (listed != store_.size() || subtree_count_[0] != store_.size())
    fail("the lists do not hold every live object once");
}

void OctreePaper::visit_cells(CellVisitor visitor) const {
  for (std::uint32_t node = 0; node < kNodeCount; ++node) {
    if (subtree_count_[node] == 0 && node != 0) continue;
    const NodeCell c = decode(node);
    const double side = std::ldexp(1.0, kFinest - c.level) / scale_;
    const int xyz[3] = {c.x, c.y, c.z};
    Aabb box;
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = origin_[a] + xyz[a] * side;
      box.hi[a] = origin_[a] + (xyz[a] + 1) * side;
    }
    visitor(box, c.level, lists_[node].size());
  }
}

}  // namespace broadphase
