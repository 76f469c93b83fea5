#include <algorithm>
#include <bit>
#include <broadphase/detail/cell_tally.hpp>
#include <broadphase/grid_static.hpp>
#include <cstring>
#include <stdexcept>
#include <string>

namespace broadphase {

using detail::CellKey;
using detail::CellRange;
using detail::kNone;

namespace {

// Calls f(cell) for each cell of a range, x fastest.
template <class F>
void for_cells(const CellRange& r, F&& f) {
  CellKey c;
  for (c.c[2] = r.lo[2]; c.c[2] <= r.hi[2]; ++c.c[2])
    for (c.c[1] = r.lo[1]; c.c[1] <= r.hi[1]; ++c.c[1])
      for (c.c[0] = r.lo[0]; c.c[0] <= r.hi[0]; ++c.c[0]) f(c);
}

std::size_t cell_count(const CellRange& r) { return static_cast<std::size_t>(r.cells()); }

}  // namespace

void GridStaticOptions::check() const {
  detail::check_number("grid-static", "cell", cell, 1e-300, 1e300, true);
  if (policy != GridStaticPolicy::rebuild && policy != GridStaticPolicy::patch &&
      policy != GridStaticPolicy::automatic)
    throw InvalidConfig("grid-static: option 'policy' is not a GridStaticPolicy");
}

GridStatic::GridStatic(const Config& c, const GridStaticOptions& o)
    : origin_(check_config(c, "grid-static").world.lo) {
  o.check();
  const double cell = o.cell;
  cache_fixed_ = o.cache_fixed;
  policy_ = o.policy;
  trigger_.forced = cell > 0;
  map_ = detail::CellMap(origin_, cell > 0 ? cell : detail::initial_cell_size(c));
  const std::size_t buckets = std::bit_ceil(std::max<std::size_t>(4 * c.expected_objects, 64));
  shift_ = 64 - std::countr_zero(buckets);
  for (Table* t : {&fixed_, &dyn_}) {
    t->count.assign(buckets, 0);
    t->start.assign(buckets + 1, 0);
  }
}

void GridStatic::grow_slots(std::uint32_t i) {
  if (i < box_.size()) return;
  box_.resize(i + 1);
  range_.resize(i + 1);
  kind_.resize(i + 1, kDead);
  where_.resize(i + 1, kNone);
  degree_.resize(i + 1, 0);
}

Handle GridStatic::insert(const Shape& s, std::uint64_t user, Motion m) {
  if (store_.slot_count() >= (1u << 29)) throw std::length_error("grid-static: full");
  const Handle h = store_.insert(s, user);
  const std::uint32_t i = h.index;
  grow_slots(i);
  kind_[i] = m == Motion::fixed && cache_fixed_ ? kFixed : kDynamic;
  box_[i] = bounds_f(s);
  range_[i] = map_.range(box_[i]);
  attach(i, true);
  finish_mutation();
  if (kind_[i] == kFixed) cache_pairs_of(i);
  return h;
}

void GridStatic::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  detach(i, true);
  drop_pairs_of(i);
  kind_[i] = kDead;
  store_.erase(h);
  finish_mutation();
}

void GridStatic::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.set_shape(h, s);
  move_one(i, bounds_f(s), policy_ != Policy::rebuild);
  finish_mutation();
}

void GridStatic::update(std::span<const Move> moves) {
  for (const Move& m : moves) {
    store_.index_of(m.handle);
    require_valid(m.shape);
  }
  const bool patch = policy_ != Policy::rebuild;
  // `auto`: patching costs a few bucket scans per object that changed cells,
  // a rebuild one pass over the buckets and the dynamic entries. Estimating
  // a scan at ~16 bucket steps gives the break-even below; docs/grids.md
  // has both policies measured (rebuild wins when everything moves).
  const std::size_t limit = dyn_.count.size() / 16 + 16;
  std::size_t changed = 0;
  for (const Move& m : moves) {
    const std::uint32_t i = store_.set_shape(m.handle, m.shape);
    const AabbF b = bounds_f(m.shape);
    if (policy_ == Policy::automatic && !dyn_.dirty && !(map_.range(b) == range_[i]) &&
        ++changed > limit)
      dyn_.dirty = true;
    move_one(i, b, patch);
  }
  finish_mutation();
}

void GridStatic::move_one(std::uint32_t i, const AabbF& b, bool patch) {
  const CellRange r = map_.range(b);
  if (kind_[i] == kDynamic && where_[i] == kNone && r == range_[i]) {
    box_[i] = b;
    occupied_.add(b);
    return;
  }
  const bool was_fixed = kind_[i] == kFixed;
  detach(i, patch || was_fixed);
  if (was_fixed) {
    drop_pairs_of(i);
    kind_[i] = kDynamic;
  }
  box_[i] = b;
  range_[i] = r;
  attach(i, patch);
}

void GridStatic::attach(std::uint32_t i, bool patch) {
  if (range_[i].cells() > kMaxCells) {
    where_[i] = static_cast<std::uint32_t>(overflow_.size());
    overflow_.push_back(i);
    return;
  }
  entries_total_ += cell_count(range_[i]);
  occupied_.add(box_[i]);
  Table& t = table_of(i);
  if (!patch || t.dirty || !add_entries(t, i)) t.dirty = true;
}

void GridStatic::detach(std::uint32_t i, bool patch) {
  if (where_[i] != kNone) {
    detail::leave_list(overflow_, where_, i);
    return;
  }
  entries_total_ -= cell_count(range_[i]);
  Table& t = table_of(i);
  if (patch && !t.dirty) {
    remove_entries(t, i);
  } else {
    t.dirty = true;
  }
}

bool GridStatic::add_entries(Table& t, std::uint32_t i) {
  const CellRange& r = range_[i];
  bool ok = true;
  for_cells(r, [&](const CellKey& c) {
    if (!ok) return;
    const std::size_t k = bucket_of(c);
    if (t.count[k] == t.start[k + 1] - t.start[k]) {
      ok = false;
      return;
    }
    std::uint32_t at = t.start[k] + t.count[k]++;
    if (t.sorted()) {
      // Keep the fixed segment sorted by low x: shift the later ones up.
      while (at > t.start[k] && t.boxes[at - 1].lo[0] > box_[i].lo[0]) {
        t.entries[at] = t.entries[at - 1];
        t.boxes[at] = t.boxes[at - 1];
        --at;
      }
      t.boxes[at] = box_[i];
    }
    t.entries[at] = {c, i << 3 | detail::offset_mask(r, c)};
  });
  return ok;
}

void GridStatic::remove_entries(Table& t, std::uint32_t i) {
  for_cells(range_[i], [&](const CellKey& c) {
    const std::size_t k = bucket_of(c);
    Entry* e = t.entries.data() + t.start[k];
    for (std::uint32_t j = 0; j < t.count[k]; ++j) {
      if ((e[j].tag >> 3) == i && e[j].key == c) {
        const std::uint32_t last = --t.count[k];
        if (t.sorted()) {
          // Close the gap in order (the fixed segment stays sorted by x).
          AabbF* b = t.boxes.data() + t.start[k];
          for (std::uint32_t m = j; m < last; ++m) {
            e[m] = e[m + 1];
            b[m] = b[m + 1];
          }
        } else {
          e[j] = e[last];
        }
        return;
      }
    }
  });
}

void GridStatic::rebuild(Table& t) {
  const Kind kind = t.kind;
  ++rebuilds_;
  const std::size_t buckets = t.count.size();
  std::fill(t.count.begin(), t.count.end(), 0u);
  const std::uint32_t slots = store_.slot_count();
  for (std::uint32_t i = 0; i < slots; ++i)
    if (kind_[i] == kind && where_[i] == kNone)
      for_cells(range_[i], [&](const CellKey& c) { ++t.count[bucket_of(c)]; });
  // Free slots after each bucket's entries so that patches rarely find a
  // bucket full: half again for the moving population, a quarter for the
  // fixed one (it changes only on insert and remove), plus two: with one,
  // inserting objects one by one re-packed every few dozen inserts (a
  // bucket table is full as soon as any bucket takes two new entries).
  std::uint32_t running = 0;
  for (std::size_t k = 0; k < buckets; ++k) {
    t.start[k] = running;
    running += t.count[k] + (t.sorted() ? t.count[k] / 4 : t.count[k] / 2) + 2;
    t.count[k] = 0;
  }
  t.start[buckets] = running;
  t.entries.resize(running);
  if (t.sorted()) {
    t.boxes.resize(running);
    // Entering the objects by increasing low x leaves every fixed segment
    // sorted without a per-segment sort.
    std::vector<std::uint32_t> order;
    for (std::uint32_t i = 0; i < slots; ++i)
      if (kind_[i] == kind && where_[i] == kNone) order.push_back(i);
    std::sort(order.begin(), order.end(),
              [&](std::uint32_t a, std::uint32_t b) { return box_[a].lo[0] < box_[b].lo[0]; });
    for (std::uint32_t i : order) add_entries(t, i);
  } else {
    for (std::uint32_t i = 0; i < slots; ++i)
      if (kind_[i] == kind && where_[i] == kNone) add_entries(t, i);
  }
  t.dirty = false;
}

void GridStatic::finish_mutation() {
  if (trigger_.due(store_.size())) {
    trigger_.chosen_at = store_.size();
    regrid(detail::auto_cell_size(store_, box_));
    return;
  }
  if (entries_total_ > 2 * dyn_.count.size()) {
    const std::size_t buckets = std::bit_ceil(entries_total_);
    shift_ = 64 - std::countr_zero(buckets);
    for (Table* t : {&fixed_, &dyn_}) {
      t->count.assign(buckets, 0);
      t->start.assign(buckets + 1, 0);
      t->dirty = true;
    }
  }
  if (fixed_.dirty) rebuild(fixed_);
  if (dyn_.dirty) rebuild(dyn_);
}

void GridStatic::regrid(double cell) {
  map_ = detail::CellMap(origin_, cell);
  overflow_.clear();
  occupied_.clear();
  entries_total_ = 0;
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
    where_[i] = kNone;
    if (kind_[i] == kDead) continue;
    range_[i] = map_.range(box_[i]);
    if (range_[i].cells() > kMaxCells) {
      where_[i] = static_cast<std::uint32_t>(overflow_.size());
      overflow_.push_back(i);
    } else {
      entries_total_ += cell_count(range_[i]);
      occupied_.add(box_[i]);
    }
  }
  const std::size_t buckets = std::bit_ceil(std::max<std::size_t>(entries_total_, 64));
  shift_ = 64 - std::countr_zero(buckets);
  for (Table* t : {&fixed_, &dyn_}) {
    t->count.assign(buckets, 0);
    t->start.assign(buckets + 1, 0);
  }
  rebuild(fixed_);
  rebuild(dyn_);
}

void GridStatic::cache_pairs_of(std::uint32_t i, std::uint32_t below) {
  const Shape& s = store_.shape(i);
  auto consider = [&](std::uint32_t b) {
    if (b != i && b < below && kind_[b] == kFixed && box_[i].overlaps(box_[b]) && may_pair(i, b) &&
        overlaps(s, store_.shape(b))) {
      fixed_pairs_.emplace_back(i, b);
      ++degree_[i];
      ++degree_[b];
    }
    return true;
  };
  visit_region(range_[i], 1u, consider);
  for (std::uint32_t o : overflow_) consider(o);
}

void GridStatic::set_filter(Handle h, Filter f) {
  const std::uint32_t i = store_.set_filter(h, f);
  if (kind_[i] != kFixed) return;
  drop_pairs_of(i);
  cache_pairs_of(i);
}

void GridStatic::set_pair_filter(PairFilter pf) {
  pair_filter_ = std::move(pf);
  fixed_pairs_.clear();
  std::fill(degree_.begin(), degree_.end(), 0u);
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i)
    if (kind_[i] == kFixed) cache_pairs_of(i, i);
}

void GridStatic::drop_pairs_of(std::uint32_t i) {
  if (degree_[i] == 0) return;
  std::erase_if(fixed_pairs_, [&](const std::pair<std::uint32_t, std::uint32_t>& p) {
    if (p.first != i && p.second != i) return false;
    --degree_[p.first == i ? p.second : p.first];
    return true;
  });
  degree_[i] = 0;
}

std::size_t GridStatic::memory_bytes() const {
  std::size_t bytes =
      store_.memory_bytes() + box_.capacity() * sizeof(AabbF) +
      range_.capacity() * sizeof(CellRange) + kind_.capacity() +
      (where_.capacity() + degree_.capacity() + overflow_.capacity()) * sizeof(std::uint32_t) +
      fixed_pairs_.capacity() * sizeof(fixed_pairs_[0]);
  for (const Table* t : {&fixed_, &dyn_})
    bytes += t->entries.capacity() * sizeof(Entry) + t->boxes.capacity() * sizeof(AabbF) +
             (t->start.capacity() + t->count.capacity()) * sizeof(std::uint32_t);
  return bytes;
}

void GridStatic::validate() const {
  const auto fail = validate_store("grid-static");
  const std::uint32_t slots = store_.slot_count();
  std::size_t entries = 0;
  for (std::uint32_t i = 0; i < slots; ++i) {
    if (!store_.slots().alive(i)) {
      if (kind_[i] != kDead || where_[i] != kNone || degree_[i] != 0) fail("free slot in use");
      continue;
    }
    if (kind_[i] == kDead) fail("live object marked dead");
    const AabbF b = bounds_f(store_.shape(i));
    if (std::memcmp(&b, &box_[i], sizeof b) != 0) fail("stale bounds");
    if (!(map_.range(b) == range_[i])) fail("stale cell range");
    const bool over = range_[i].cells() > kMaxCells;
    if (over != (where_[i] != kNone)) fail("overflow membership");
    if (!over && !occupied_.holds(b)) fail("an object outside the occupied box");
    if (over && (where_[i] >= overflow_.size() || overflow_[where_[i]] != i))
      fail("overflow position");
    if (!over) entries += cell_count(range_[i]);
    if (kind_[i] != kFixed && degree_[i] != 0) fail("dynamic object with cached pairs");
  }
  if (entries != entries_total_) fail("entry total");
  std::vector<std::uint32_t> seen(slots, 0);
  for (const Table* t : {&fixed_, &dyn_}) {
    if (t->dirty) fail("table left dirty");
    const Kind kind = t->kind;
    const std::size_t buckets = t->count.size();
    if (t->start.size() != buckets + 1 || t->start[buckets] != t->entries.size())
      fail("table layout");
    for (std::size_t k = 0; k < buckets; ++k) {
      if (t->start[k] > t->start[k + 1] || t->count[k] > t->start[k + 1] - t->start[k])
        fail("bucket overfull");
      for (std::uint32_t j = 0; j < t->count[k]; ++j) {
        const Entry& e = t->entries[t->start[k] + j];
        const std::uint32_t o = e.tag >> 3;
        if (o >= slots || kind_[o] != kind || where_[o] != kNone) fail("entry of a wrong object");
        if (bucket_of(e.key) != k || !range_[o].contains(e.key)) fail("entry in a wrong cell");
        if ((e.tag & 7u) != detail::offset_mask(range_[o], e.key)) fail("entry mask");
        if (t->sorted() && std::memcmp(&t->boxes[t->start[k] + j], &box_[o], sizeof(AabbF)) != 0)
          fail("stale bounds in the fixed table");
        ++seen[o];
      }
    }
  }
  for (std::uint32_t i = 0; i < slots; ++i)
    if (kind_[i] != kDead && where_[i] == kNone && seen[i] != cell_count(range_[i]))
      fail("object entered a wrong number of times");
  std::vector<std::uint32_t> degree(slots, 0);
  for (const auto& [a, b] : fixed_pairs_) {
    if (a == b || a >= slots || b >= slots || kind_[a] != kFixed || kind_[b] != kFixed)
      fail("cached pair of non-fixed objects");
    if (!overlaps(store_.shape(a), store_.shape(b))) fail("cached pair does not overlap");
    if (!may_pair(a, b)) fail("cached pair fails the filters");
    ++degree[a];
    ++degree[b];
  }
  for (std::uint32_t i = 0; i < slots; ++i) {
    if (degree[i] != degree_[i]) fail("cached pair count");
    if (kind_[i] != kFixed) continue;
    std::uint32_t want = 0;
    auto count = [&](std::uint32_t b) {
      if (b != i && kind_[b] == kFixed && may_pair(i, b) &&
          overlaps(store_.shape(i), store_.shape(b)))
        ++want;
      return true;
    };
    visit_region(range_[i], 1u, count);
    for (std::uint32_t o : overflow_) count(o);
    if (want != degree[i]) fail("pair cache misses or repeats a fixed pair");
  }
}

void GridStatic::visit_cells(CellVisitor visitor) const {
  detail::CellTally tally;
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i)
    if (kind_[i] != kDead && where_[i] == kNone) tally.add(0, range_[i]);
  tally.report([&](int, const CellKey& k) { return map_.box(k); }, visitor);
}

}  // namespace broadphase
