#include <algorithm>
#include <broadphase/detail/cell_tally.hpp>
#include <broadphase/grid_implicit.hpp>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

namespace broadphase {

void GridImplicitOptions::check() const {
  detail::check_number("grid-implicit", "cell", cell, 1e-300, 1e300, true);
}

GridImplicit::GridImplicit(const Config& c, const GridImplicitOptions& o)
    : world_(check_config(c, "grid-implicit").world) {
  o.check();
  const double cell = o.cell;
  trigger_.forced = cell > 0;
  layout(cell > 0 ? cell : detail::initial_cell_size(c),
         std::max<std::size_t>(1, (c.expected_objects + 63) / 64));
}

void GridImplicit::layout(double cell, std::size_t words) {
  // width_over: a world with finite corners may be wider than the largest
  // double ([-1e308, 1e308]); its width / kMaxSlabs is still finite.
  for (int a = 0; a < 3; ++a)
    cell = std::max(cell, detail::width_over(world_.lo[a], world_.hi[a], kMaxSlabs));
  std::int32_t n[3];
  for (int a = 0; a < 3; ++a) {
    n[a] = detail::cells_across(world_.lo[a], world_.hi[a], cell, double{kMaxSlabs});
    slabs_[a] = n[a];
  }
  map_ = detail::CellMap(world_.lo, cell, n);
  words_ = words;
  summary_words_ = (words_ + 63) / 64;
  for (int a = 0; a < 3; ++a) {
    bits_[a].assign(static_cast<std::size_t>(n[a]) * words_, 0);
    summary_[a].assign(static_cast<std::size_t>(n[a]) * summary_words_, 0);
  }
  occupied_.clear();
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
    if (!store_.slots().alive(i)) continue;
    occupied_.add(box_[i]);
    range_[i] = map_.range(box_[i]);
    for (int a = 0; a < 3; ++a) set_bits(i, a, range_[i].lo[a], range_[i].hi[a], true);
  }
}

void GridImplicit::set_bits(std::uint32_t i, int axis, std::int32_t lo, std::int32_t hi, bool on) {
  const std::uint64_t bit = std::uint64_t{1} << (i % 64);
  const std::size_t w = i / 64;
  const std::uint64_t word_bit = std::uint64_t{1} << (w % 64);
  std::uint64_t* p = bits_[axis].data() + static_cast<std::size_t>(lo) * words_ + w;
  std::uint64_t* q = summary_[axis].data() + static_cast<std::size_t>(lo) * summary_words_ + w / 64;
  for (std::int32_t s = lo; s <= hi; ++s, p += words_, q += summary_words_) {
    *p = on ? (*p | bit) : (*p & ~bit);
    *q = *p != 0 ? (*q | word_bit) : (*q & ~word_bit);
  }
}

Handle GridImplicit::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  const std::uint32_t i = h.index;
  if (i >= box_.size()) {
    box_.resize(i + 1);
    range_.resize(i + 1);
  }
  box_[i] = bounds_f(s);
  // A re-layout places every live object, this one included.
  const std::size_t need = std::size_t{i} / 64 + 1;
  if (trigger_.due(store_.size())) {
    trigger_.chosen_at = store_.size();
    layout(detail::auto_cell_size(store_, box_), std::max(words_, need));
  } else if (need > words_) {
    // Slots outgrew the bit arrays: double them (amortised O(1) per insert).
    layout(map_.cell(), std::max(2 * words_, need));
  } else {
    occupied_.add(box_[i]);
    range_[i] = map_.range(box_[i]);
    for (int a = 0; a < 3; ++a) set_bits(i, a, range_[i].lo[a], range_[i].hi[a], true);
  }
  return h;
}

void GridImplicit::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  for (int a = 0; a < 3; ++a) set_bits(i, a, range_[i].lo[a], range_[i].hi[a], false);
  store_.erase(h);
  if (trigger_.due(store_.size())) {
    trigger_.chosen_at = store_.size();
    layout(detail::auto_cell_size(store_, box_), words_);
  }
}

void GridImplicit::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.set_shape(h, s);
  box_[i] = bounds_f(s);
  occupied_.add(box_[i]);
  const detail::CellRange r = map_.range(box_[i]);
  for (int a = 0; a < 3; ++a) {
    if (r.lo[a] == range_[i].lo[a] && r.hi[a] == range_[i].hi[a]) continue;
    set_bits(i, a, range_[i].lo[a], range_[i].hi[a], false);
    set_bits(i, a, r.lo[a], r.hi[a], true);
  }
  range_[i] = r;
}

std::size_t GridImplicit::memory_bytes() const {
  std::size_t bytes = store_.memory_bytes() + box_.capacity() * sizeof(AabbF) +
                      range_.capacity() * sizeof(detail::CellRange);
  for (const auto& b : bits_) bytes += b.capacity() * sizeof(std::uint64_t);
  for (const auto& b : summary_) bytes += b.capacity() * sizeof(std::uint64_t);
  return bytes;
}

void GridImplicit::validate() const {
  const auto fail = validate_store("grid-implicit");
  if (store_.slot_count() > words_ * 64) fail("slots outgrew the bit arrays");
  for (int a = 0; a < 3; ++a) {
    std::vector<std::uint64_t> want(bits_[a].size(), 0);
    for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
      if (!store_.slots().alive(i)) continue;
      if (a == 0) {
        const AabbF b = bounds_f(store_.shape(i));
        if (std::memcmp(&b, &box_[i], sizeof b) != 0) fail("stale bounds");
        if (!(map_.range(b) == range_[i])) fail("stale slab range");
        if (!occupied_.holds(b)) fail("an object outside the occupied box");
      }
      for (std::int32_t s = range_[i].lo[a]; s <= range_[i].hi[a]; ++s)
        want[static_cast<std::size_t>(s) * words_ + i / 64] |= std::uint64_t{1} << (i % 64);
    }
    if (want != bits_[a]) fail("slab bits disagree with the objects' ranges");
    std::vector<std::uint64_t> sum(summary_[a].size(), 0);
    for (std::size_t j = 0; j < want.size(); ++j)
      if (want[j] != 0) {
        const std::size_t s = j / words_, w = j % words_;
        sum[s * summary_words_ + w / 64] |= std::uint64_t{1} << (w % 64);
      }
    if (sum != summary_[a]) fail("slab summaries disagree with the slab bits");
  }
}

void GridImplicit::visit_cells(CellVisitor visitor) const {
  detail::CellTally tally;
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i)
    if (store_.slots().alive(i)) tally.add(0, range_[i]);
  tally.report([&](int, const detail::CellKey& k) { return map_.box(k); }, visitor);
}

}  // namespace broadphase
