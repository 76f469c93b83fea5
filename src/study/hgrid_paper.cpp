#include <algorithm>
#include <array>
#include <bit>
#include <broadphase/study/hgrid_paper.hpp>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

namespace broadphase {

namespace {

// Cell coordinates stay within ±2^40, where a double still resolves 2^-12
// of a cell, so probe boxes stay 2 cells wide; centres beyond go oversize.
constexpr double kCellLimit = 0x1p40;

// How far an object's bounds reach from its centre, as a fraction of its
// level's cell side. The level rule keeps the bounds' largest extent at most
// 1/4 of the side, so the exact reach is at most 1/8 of it; the bounds are
// built with rounding that can shift the centre off the middle by 2^-12 of
// the extent (their slack is 2^-40 relative, rounding 2^-52), and 65/512 =
// 1/8 * (1 + 1/64) covers that with a wide margin.
constexpr double kReachFraction = 65.0 / 512.0;

// Clamps a probe box edge into the range of valid cells, plus one, so that
// every cell an object can have is still compared correctly. Monotone, and
// a NaN from a malformed query shape lands below every cell.
std::int64_t clamp_cell(double f) {
  if (!(f >= -kCellLimit)) return -static_cast<std::int64_t>(kCellLimit) - 1;
  if (f > kCellLimit) return static_cast<std::int64_t>(kCellLimit) + 1;
  return static_cast<std::int64_t>(f);
}

}  // namespace

void HGridPaperOptions::check() const {
  detail::check_integer("hgrid-paper", "levels", static_cast<std::uint64_t>(levels), 1,
                        HGridPaper::kMaxLevels);
}

HGridPaper::HGridPaper(const Config& c, const HGridPaperOptions& o) {
  check_config(c, "hgrid-paper");
  o.check();
  levels_ = o.levels;
  origin_ = c.world.lo;
  const Vec3 extent = c.world.hi - c.world.lo;
  const double side = std::max(extent.x, std::max(extent.y, extent.z));
  if (!(side > 0) || !std::isfinite(side))
    throw InvalidConfig("hgrid-paper: the world box must be finite and non-empty");
  for (int k = 0; k <= levels_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    side_[i] = std::ldexp(side, -k);
    inv_side_[i] = std::ldexp(1.0 / side, k);
    reach_[i] = side_[i] * kReachFraction;
  }
  const std::size_t buckets = std::bit_ceil(std::max<std::size_t>(64, c.expected_objects));
  head_.assign(buckets, kNull);
  mask_ = buckets - 1;
}

int HGridPaper::level_for_extent(double extent) const {
  const double need = 4 * extent;  // exact: a power of two (or +inf)
  if (!(need <= side_[1])) return 0;
  if (need <= side_[static_cast<std::size_t>(levels_)]) return levels_;
  // A first guess from the exponent, then exact steps against the sides.
  int k = std::clamp(std::ilogb(side_[0] / need), 1, levels_);
  while (k < levels_ && side_[static_cast<std::size_t>(k + 1)] >= need) ++k;
  while (side_[static_cast<std::size_t>(k)] < need) --k;
  return k;
}

HGridPaper::Placement HGridPaper::place(const Shape& s) const {
  const Aabb b = bounds(s);
  const double extent = std::max(b.hi.x - b.lo.x, std::max(b.hi.y - b.lo.y, b.hi.z - b.lo.z));
  Placement p{level_for_extent(extent), {0, 0, 0}};
  if (p.level == 0) return p;
  // Bounds that, widened by the coarsest level's reach and taken from the
  // origin, overflow (an object near +-1.8e308) would give probe boxes
  // clamped to +-2^40 cells: walks that never end (issue 21, finding 2).
  // Such objects go oversize, tested against everything.
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite((b.lo[a] - reach_[1]) - origin_[a]) ||
        !std::isfinite((b.hi[a] + reach_[1]) - origin_[a]))
      return {0, {0, 0, 0}};
  for (int a = 0; a < 3; ++a) {
    const double f = cell_coord(s.center[a], a, p.level);
    if (!(std::fabs(f) <= kCellLimit)) return {0, {0, 0, 0}};
    p.cell[a] = static_cast<std::int64_t>(f);
  }
  return p;
}

HGridPaper::CellBox HGridPaper::probe_box(const Aabb& b, int level) const {
  // An object of this level that overlaps `b` has its centre within `b`
  // widened by the reach; `cell_coord` is monotone, so the centre's cell
  // lies between the cells of the widened corners.
  const double reach = reach_[static_cast<std::size_t>(level)];
  CellBox box{};
  box.volume = 1;
  for (int a = 0; a < 3; ++a) {
    box.lo[a] = clamp_cell(cell_coord(b.lo[a] - reach, a, level));
    box.hi[a] = clamp_cell(cell_coord(b.hi[a] + reach, a, level));
    box.volume *= static_cast<double>(std::max<std::int64_t>(0, box.hi[a] - box.lo[a] + 1));
  }
  return box;
}

std::uint32_t HGridPaper::bucket_of(int level, const std::int64_t* cell) const {
  std::uint64_t h = static_cast<std::uint64_t>(cell[0]) * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<std::uint64_t>(cell[1]) * 0xC2B2AE3D27D4EB4Full;
  h ^= static_cast<std::uint64_t>(cell[2]) * 0x165667B19E3779F9ull;
  h ^= static_cast<std::uint64_t>(level) * 0x27D4EB2F165667C5ull;
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 29;
  return static_cast<std::uint32_t>(h & mask_);
}

void HGridPaper::make_room(std::uint32_t i, const Placement& p) {
  if (i >= entry_.size()) {
    entry_.resize(i + 1);
    slot_.resize(i + 1);
    prev_.resize(i + 1);
  }
  if (p.level == 0) {
    oversize_.reserve(oversize_.size() + 1);
  } else if (in_table_ >= head_.size()) {
    grow_table();
  }
}

void HGridPaper::link(std::uint32_t i, const Placement& p) {
  Entry& e = entry_[i];
  e.level = static_cast<std::uint8_t>(p.level);
  ++count_[static_cast<std::size_t>(p.level)];
  if (p.level == 0) {
    slot_[i] = static_cast<std::uint32_t>(oversize_.size());
    oversize_.push_back(i);
    return;
  }
  std::copy(p.cell, p.cell + 3, e.cell);
  occupied_.add(bounds_f(store_.shape(i)));
  const std::uint32_t b = bucket_of(p.level, p.cell);
  push_front(b, i);
  slot_[i] = b;
  ++in_table_;
}

void HGridPaper::unlink(std::uint32_t i) {
  const Entry& e = entry_[i];
  --count_[e.level];
  if (e.level == 0) {
    const std::uint32_t pos = slot_[i];
    oversize_[pos] = oversize_.back();
    slot_[oversize_[pos]] = pos;
    oversize_.pop_back();
    return;
  }
  // Doubly linked, so a crowded cell (hundreds of objects in one coarse
  // cell) costs no walk.
  const std::uint32_t before = prev_[i];
  if (before == kNull) {
    if (head_[slot_[i]] != i) throw std::logic_error("hgrid-paper: object missing from its bucket");
    head_[slot_[i]] = e.next;
  } else {
    entry_[before].next = e.next;
  }
  if (e.next != kNull) prev_[e.next] = before;
  --in_table_;
}

void HGridPaper::push_front(std::uint32_t b, std::uint32_t i) {
  entry_[i].next = head_[b];
  if (head_[b] != kNull) prev_[head_[b]] = i;
  prev_[i] = kNull;
  head_[b] = i;
}

void HGridPaper::grow_table() {
  std::vector<std::uint32_t> head(head_.size() * 2, kNull);
  head_.swap(head);
  mask_ = head_.size() - 1;
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
    if (!store_.slots().alive(i) || i >= entry_.size() || entry_[i].level == 0) continue;
    const std::uint32_t b = bucket_of(entry_[i].level, entry_[i].cell);
    push_front(b, i);
    slot_[i] = b;
  }
}

Handle HGridPaper::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  const Placement p = place(s);
  try {
    make_room(h.index, p);
  } catch (...) {
    store_.erase(h);
    throw;
  }
  link(h.index, p);
  return h;
}

void HGridPaper::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  unlink(i);
  store_.erase(h);
}

void HGridPaper::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.index_of(h);
  require_valid(s);
  const Placement p = place(s);
  const Entry& e = entry_[i];
  const bool stays = p.level == e.level &&
                     (p.level == 0 ||
                      (p.cell[0] == e.cell[0] && p.cell[1] == e.cell[1] && p.cell[2] == e.cell[2]));
  // Allocate before anything changes, so a failed allocation leaves the
  // object where it was.
  if (!stays) make_room(i, p);
  store_.set_shape(h, s);
  if (stays) {
    if (p.level != 0) occupied_.add(bounds_f(s));
    return;
  }
  unlink(i);
  link(i, p);
}

std::size_t HGridPaper::memory_bytes() const {
  return store_.memory_bytes() + entry_.capacity() * sizeof(Entry) +
         (slot_.capacity() + prev_.capacity() + head_.capacity() + oversize_.capacity()) *
             sizeof(std::uint32_t);
}

void HGridPaper::validate() const {
  const auto fail = validate_store("hgrid-paper");
  const std::uint32_t slots = store_.slot_count();
  if (entry_.size() < slots && store_.size() > 0) fail("fewer entries than slots");
  std::array<std::uint32_t, kMaxLevels + 1> count{};
  for (std::uint32_t i = 0; i < slots; ++i) {
    if (!store_.slots().alive(i)) continue;
    const Entry& e = entry_[i];
    const Placement p = place(store_.shape(i));
    const std::string who = "object " + std::to_string(i);
    if (p.level != e.level || (p.level != 0 && (p.cell[0] != e.cell[0] || p.cell[1] != e.cell[1] ||
                                                p.cell[2] != e.cell[2])))
      fail(who + " is not at the level and cell its shape prescribes");
    if (e.level != 0 && !occupied_.holds(bounds_f(store_.shape(i))))
      fail(who + " lies outside the occupied box");
    if (e.level == 0 ? (slot_[i] >= oversize_.size() || oversize_[slot_[i]] != i)
                     : slot_[i] != bucket_of(e.level, e.cell))
      fail(who + " does not remember its bucket or oversize place");
    ++count[e.level];
  }
  if (count != count_) fail("per-level counts disagree");
  if (oversize_.size() != count_[0] || in_table_ + oversize_.size() != store_.size())
    fail("table and oversize counts disagree with the size");
  // Walk every chain: at most in_table_ steps in all (so a cycle is caught),
  // every entry alive, in the table, in the bucket it remembers.
  std::vector<char> seen(slots, 0);
  std::size_t chained = 0;
  for (std::uint32_t b = 0; b < head_.size(); ++b) {
    std::uint32_t before = kNull;
    for (std::uint32_t j = head_[b]; j != kNull; before = j, j = entry_[j].next) {
      if (j >= slots || !store_.slots().alive(j) || entry_[j].level == 0 || slot_[j] != b ||
          prev_[j] != before || seen[j] || ++chained > in_table_)
        fail("bucket " + std::to_string(b) +
             " chains a dead, foreign or repeated object, a wrong back link, or "
             "a cycle");
      seen[j] = 1;
    }
  }
  if (chained != in_table_) fail("objects missing from the chains");
}

void HGridPaper::visit_cells(CellVisitor visitor) const {
  std::map<std::array<std::int64_t, 4>, std::size_t> count;
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
    if (!store_.slots().alive(i) || entry_[i].level == 0) continue;
    const Entry& e = entry_[i];
    ++count[{e.level, e.cell[0], e.cell[1], e.cell[2]}];
  }
  for (const auto& [k, n] : count) {
    const double side = side_[static_cast<std::size_t>(k[0])];
    Aabb box;
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = origin_[a] + static_cast<double>(k[a + 1]) * side;
      box.hi[a] = origin_[a] + static_cast<double>(k[a + 1] + 1) * side;
    }
    visitor(box, static_cast<int>(k[0]), n);
  }
}

}  // namespace broadphase
