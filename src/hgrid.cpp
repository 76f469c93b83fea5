#include <algorithm>
#include <bit>
#include <broadphase/detail/cell_tally.hpp>
#include <broadphase/hgrid.hpp>
#include <cstring>
#include <stdexcept>
#include <string>

namespace broadphase {

using detail::CellKey;
using detail::kNone;

HGrid::HGrid(const Config& c, const HGridOptions& o) {
  check_config(c, "hgrid");
  o.check();
  table_.assign(std::bit_ceil(std::max<std::size_t>(64, 2 * c.expected_objects)),
                Cell{0, {}, kNone});
  count_.assign(kMaxLevel - kMinLevel + 1, 0);
}

int HGrid::level_for(const AabbF& b) {
  double extent = 0, magnitude = 0;
  for (int a = 0; a < 3; ++a) {
    extent = std::max(extent, static_cast<double>(b.hi[a]) - static_cast<double>(b.lo[a]));
    magnitude = std::max({magnitude, std::fabs(static_cast<double>(b.lo[a])),
                          std::fabs(static_cast<double>(b.hi[a]))});
  }
  if (!std::isfinite(extent) || !std::isfinite(magnitude)) return kMaxLevel + 1;
  int level = kMinLevel;
  if (extent > 0) {
    // The finest k with 2^k >= extent.
    int e = 0;
    const double m = std::frexp(extent, &e);
    level = std::max(level, m == 0.5 ? e - 1 : e);
  }
  // Keep cell coordinates within 2^21 of the origin, far inside int32.
  if (magnitude > 0) level = std::max(level, std::ilogb(magnitude) - 20);
  return level;
}

Handle HGrid::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  const std::uint32_t i = h.index;
  if (i >= box_.size()) {
    box_.resize(i + 1);
    level_.resize(i + 1, 0);
    cell_.resize(i + 1);
    next_.resize(i + 1, kNone);
    prev_.resize(i + 1, kNone);
    where_.resize(i + 1, kNone);
  }
  box_[i] = bounds_f(s);
  place(i);
  return h;
}

void HGrid::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  lift(i);
  store_.erase(h);
}

void HGrid::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.set_shape(h, s);
  const AabbF b = bounds_f(s);
  if (where_[i] == kNone) {
    const int level = level_for(b);
    if (level == level_[i]) {
      if (cell_for(b, level) == cell_[i]) {
        box_[i] = b;
        occupied_.add(b);
        return;
      }
    }
  }
  lift(i);
  box_[i] = b;
  place(i);
}

void HGrid::place(std::uint32_t i) {
  const int level = level_for(box_[i]);
  if (level > kMaxLevel) {
    where_[i] = static_cast<std::uint32_t>(overflow_.size());
    overflow_.push_back(i);
    return;
  }
  level_[i] = level;
  const AabbF& b = box_[i];
  occupied_.add(b);
  cell_[i] = cell_for(b, level);
  if (2 * (cells_used_ + 1) > table_.size()) grow_table();
  Cell& c = table_[find(level, cell_[i])];
  if (c.head == kNone) {
    c.level = level;
    c.key = cell_[i];
    ++cells_used_;
  }
  next_[i] = c.head;
  prev_[i] = kNone;
  if (c.head != kNone) prev_[c.head] = i;
  c.head = i;
  count_in_block(i, +1);
  if (count_[level - kMinLevel]++ == 0)
    levels_.insert(std::lower_bound(levels_.begin(), levels_.end(), level), level);
}

void HGrid::lift(std::uint32_t i) {
  if (where_[i] != kNone) {
    detail::leave_list(overflow_, where_, i);
    return;
  }
  const int level = level_[i];
  const std::size_t p = find(level, cell_[i]);
  if (prev_[i] == kNone) {
    table_[p].head = next_[i];
  } else {
    next_[prev_[i]] = next_[i];
  }
  if (next_[i] != kNone) prev_[next_[i]] = prev_[i];
  if (table_[p].head == kNone) erase_cell(p);
  count_in_block(i, -1);
  if (--count_[level - kMinLevel] == 0)
    levels_.erase(std::lower_bound(levels_.begin(), levels_.end(), level));
}

void HGrid::count_in_block(std::uint32_t i, int change) {
  const int tag = level_[i] + kBlockTag;
  const CellKey k = block_of(cell_[i]);
  if (change > 0 && 2 * (cells_used_ + 1) > table_.size()) grow_table();
  const std::size_t p = find(tag, k);
  Cell& c = table_[p];
  if (c.head == kNone) {
    c.level = tag;
    c.key = k;
    c.head = 0;
    ++cells_used_;
  }
  c.head += static_cast<std::uint32_t>(change);
  if (c.head == 0) erase_cell(p);
}

void HGrid::erase_cell(std::size_t p) {
  // Backward-shift deletion keeps linear probing free of tombstones: later
  // cells of the same probe run move up into the hole.
  const std::size_t mask = table_.size() - 1;
  std::size_t i = p;
  for (std::size_t j = (p + 1) & mask; table_[j].head != kNone; j = (j + 1) & mask) {
    const std::size_t k =
        detail::hash_cell(table_[j].key, static_cast<std::uint32_t>(table_[j].level)) & mask;
    const bool stays = i <= j ? (i < k && k <= j) : (i < k || k <= j);
    if (stays) continue;
    table_[i] = table_[j];
    i = j;
  }
  table_[i].head = kNone;
  --cells_used_;
}

void HGrid::grow_table() {
  std::vector<Cell> old(2 * table_.size(), Cell{0, {}, kNone});
  old.swap(table_);
  for (const Cell& c : old)
    if (c.head != kNone) table_[find(c.level, c.key)] = c;
}

int HGrid::level_of(Handle h) const {
  const std::uint32_t i = store_.index_of(h);
  return where_[i] == kNone ? level_[i] : kMaxLevel + 1;
}

std::size_t HGrid::memory_bytes() const {
  return store_.memory_bytes() + box_.capacity() * sizeof(AabbF) +
         level_.capacity() * sizeof(std::int32_t) + cell_.capacity() * sizeof(CellKey) +
         (next_.capacity() + prev_.capacity() + where_.capacity() + overflow_.capacity() +
          count_.capacity()) *
             sizeof(std::uint32_t) +
         table_.capacity() * sizeof(Cell) + levels_.capacity() * sizeof(int);
}

void HGrid::validate() const {
  const auto fail = validate_store("hgrid");
  std::vector<std::uint32_t> count(count_.size(), 0);
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
    if (!store_.slots().alive(i)) {
      if (where_[i] != kNone) fail("free slot in the overflow list");
      continue;
    }
    const AabbF b = bounds_f(store_.shape(i));
    if (std::memcmp(&b, &box_[i], sizeof b) != 0) fail("stale bounds");
    if (where_[i] == kNone && !occupied_.holds(b)) fail("an object outside the occupied box");
    const int level = level_for(b);
    if ((level > kMaxLevel) != (where_[i] != kNone)) fail("overflow membership");
    if (where_[i] != kNone) {
      if (where_[i] >= overflow_.size() || overflow_[where_[i]] != i) fail("overflow position");
      continue;
    }
    if (level != level_[i]) fail("object on the wrong level");
    const CellKey k = cell_for(b, level);
    if (!(k == cell_[i])) fail("object in the wrong cell");
    ++count[level - kMinLevel];
    const Cell& c = table_[find(level, k)];
    if (c.head == kNone) fail("object's cell missing from the table");
    if (prev_[i] == kNone ? c.head != i : next_[prev_[i]] != i) fail("broken backward link");
    if (next_[i] != kNone &&
        (prev_[next_[i]] != i || level_[next_[i]] != level || !(cell_[next_[i]] == k)))
      fail("broken forward link");
  }
  if (count != count_) fail("per-level counts");
  std::vector<int> levels;
  for (std::size_t l = 0; l < count.size(); ++l)
    if (count[l] != 0) levels.push_back(static_cast<int>(l) + kMinLevel);
  if (levels != levels_) fail("occupied level list");
  std::size_t used = 0, blocks = 0;
  for (std::size_t p = 0; p < table_.size(); ++p) {
    const Cell& c = table_[p];
    if (c.head == kNone) continue;
    ++used;
    if (find(c.level, c.key) != p) fail("table cell unreachable by probing");
    if (c.level > kMaxLevel) {
      ++blocks;
      if (c.level - kBlockTag < kMinLevel || c.level - kBlockTag > kMaxLevel)
        fail("table entry of no level");
      continue;
    }
    if (c.head >= store_.slot_count() || level_[c.head] != c.level || !(cell_[c.head] == c.key))
      fail("table cell heads a foreign object");
  }
  if (used != cells_used_) fail("table cell count");
  // Every block counts the objects of its cells, and no other block is kept.
  std::size_t counted = 0;
  std::vector<std::uint32_t> in_block(table_.size(), 0);
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
    if (!store_.slots().alive(i) || where_[i] != kNone) continue;
    const std::size_t p = find(level_[i] + kBlockTag, block_of(cell_[i]));
    if (table_[p].head == kNone) fail("object's block missing from the table");
    if (in_block[p]++ == 0) ++counted;
  }
  for (std::size_t p = 0; p < table_.size(); ++p)
    if (table_[p].head != kNone && table_[p].level > kMaxLevel && table_[p].head != in_block[p])
      fail("block count");
  if (counted != blocks) fail("block count");
}

void HGrid::visit_cells(CellVisitor visitor) const {
  detail::CellTally tally;
  for (const Cell& c : table_) {
    if (c.head == kNone || c.level > kMaxLevel) continue;  // empty, or a block
    for (std::uint32_t b = c.head; b != kNone; b = next_[b]) tally.add(c.level, c.key);
  }
  tally.report(
      [](int level, const CellKey& k) {
        const double e = edge(level);
        return Aabb{{k.c[0] * e, k.c[1] * e, k.c[2] * e},
                    {(k.c[0] + 1.0) * e, (k.c[1] + 1.0) * e, (k.c[2] + 1.0) * e}};
      },
      visitor);
}

}  // namespace broadphase
