#include <broadphase/sap.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace broadphase {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();

// hi - lo rounded up, and one float more, so it bounds the exact extent;
// infinite when the box does not fit in float.
float extent_of(float lo, float hi) {
  const double d = static_cast<double>(hi) - static_cast<double>(lo);
  if (!(d < static_cast<double>(std::numeric_limits<float>::max()))) return kInf;
  return std::nextafter(round_up(d), kInf);
}
}  // namespace

Sap::Sap(const Config& c, const SapOptions& o) {
  check_config(c, "sap");
  o.check();
  if (c.expected_objects > 0) {
    for (auto& e : ep_) e.reserve(2 * c.expected_objects);
    box_.reserve(c.expected_objects);
    pairs_.reserve(c.expected_objects);
  }
}

AabbF Sap::normalized_bounds(const Shape& s) {
  AabbF b = bounds_f(s);
  for (int a = 0; a < 3; ++a) {
    if (b.lo[a] == 0) b.lo[a] = 0;
    if (b.hi[a] == 0) b.hi[a] = 0;
  }
  return b;
}

float Sap::lower_limit(float lo, float extent) {
  if (extent == kInf || lo == -kInf) return -kInf;
  return std::nextafter(round_down(static_cast<double>(lo) - static_cast<double>(extent)), -kInf);
}

int Sap::scan_axis() const {
  int best = 0;
  for (int a = 1; a < 3; ++a)
    if (max_extent_[a] < max_extent_[best]) best = a;
  return best;
}

void Sap::grow_extent(const AabbF& b) {
  for (int a = 0; a < 3; ++a)
    max_extent_[a] = std::max(max_extent_[a], extent_of(b.lo[a], b.hi[a]));
}

Handle Sap::insert(const Shape& s, std::uint64_t user, Motion) {
  if (store_.slot_count() >= 0x7fffffffu && store_.size() == store_.slot_count())
    throw std::length_error("sap: too many objects");
  const Handle h = store_.insert(s, user);
  const std::uint32_t i = h.index;
  if (i >= box_.size()) box_.resize(i + 1);
  const AabbF b = normalized_bounds(s);
  box_[i] = b;
  grow_extent(b);
  for (int a = 0; a < 3; ++a) {
    auto& e = ep_[a];
    for (const std::uint64_t k : {key(b.lo[a], false, i), key(b.hi[a], true, i)})
      e.insert(std::lower_bound(e.begin(), e.end(), k), k);
  }
  scan(b, [&](std::uint32_t o) {
    if (o != i) pairs_.insert(i, o);
    return true;
  });
  return h;
}

void Sap::remove(Handle h) {
  const std::uint32_t i = store_.index_of(h);
  const AabbF b = box_[i];
  scan(b, [&](std::uint32_t o) {
    if (o != i) pairs_.erase(i, o);
    return true;
  });
  for (int a = 0; a < 3; ++a) {
    auto& e = ep_[a];
    for (const std::uint64_t k : {key(b.lo[a], false, i), key(b.hi[a], true, i)})
      e.erase(std::lower_bound(e.begin(), e.end(), k));
  }
  store_.erase(h);
}

void Sap::crossing(std::uint32_t self, bool begins, std::uint32_t other) {
  ++swaps_;
  if (other == self) return;
  if (!begins) {
    pairs_.erase(self, other);
  } else if (boxes_overlap(box_[self], box_[other])) {
    // Checked on all three axes with the new box: the other axes' lists may
    // still hold the old endpoints, and the set ignores a pair added twice.
    pairs_.insert(self, other);
  }
}

void Sap::move_endpoint(int axis, std::uint64_t from, std::uint64_t to) {
  if (from == to) return;
  auto& e = ep_[axis];
  std::size_t i = static_cast<std::size_t>(std::lower_bound(e.begin(), e.end(), from) - e.begin());
  const std::uint32_t self = slot_of(from);
  const bool upper = is_upper(from);
  if (to > from) {
    // Moving right: a lower end passing an upper end separates the pair on
    // this axis; an upper end passing a lower end may begin an overlap.
    while (i + 1 < e.size() && e[i + 1] < to) {
      const std::uint64_t other = e[i + 1];
      if (is_upper(other) != upper) crossing(self, upper, slot_of(other));
      e[i] = other;
      ++i;
    }
  } else {
    while (i > 0 && e[i - 1] > to) {
      const std::uint64_t other = e[i - 1];
      if (is_upper(other) != upper) crossing(self, !upper, slot_of(other));
      e[i] = other;
      --i;
    }
  }
  e[i] = to;
}

void Sap::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.set_shape(h, s);
  const AabbF old = box_[i];
  const AabbF b = normalized_bounds(s);
  box_[i] = b;
  grow_extent(b);
  for (int a = 0; a < 3; ++a) {
    const std::uint64_t lo0 = key(old.lo[a], false, i), lo1 = key(b.lo[a], false, i);
    const std::uint64_t hi0 = key(old.hi[a], true, i), hi1 = key(b.hi[a], true, i);
    // Order the two moves so that the lower end never crosses its own upper end.
    if (hi1 > hi0) {
      move_endpoint(a, hi0, hi1);
      move_endpoint(a, lo0, lo1);
    } else {
      move_endpoint(a, lo0, lo1);
      move_endpoint(a, hi0, hi1);
    }
  }
}

void Sap::update(std::span<const Move> moves) {
  // Checked first: a bad move met after the switch to the rebuild path left
  // the endpoint lists disagreeing with the boxes (issue 21, finding 3).
  check_moves(*this, moves);
  // Coherent batches go object by object. When a batch has crossed more
  // endpoints than a full rebuild would roughly cost (incoherent motion: an
  // explosion), the rest of it is applied at once and the lists and the pair
  // set are rebuilt by sorting and one sweep. Every single update leaves
  // the structure complete, so switching midway is safe.
  // After a batch that had to rebuild early, the next ones rebuild at once,
  // retrying the incremental path every few batches to notice coherence.
  // A rebuild sorts 2n endpoints per axis and re-enters every box pair, so
  // that is the crossing budget before giving up on the incremental path.
  const std::uint64_t budget =
      swaps_ + kRebuildCrossings * (2 * store_.size() + 64) + 2 * pairs_.size();
  std::size_t k = 0;
  if (incoherent_batches_ == 0 || incoherent_batches_ % kRetryEvery == 0)
    for (; k < moves.size() && swaps_ <= budget; ++k) update(moves[k].handle, moves[k].shape);
  if (k < moves.size()) {
    rebuild(moves.subspan(k));
    incoherent_batches_ += 2 * k < moves.size() ? 1 : 0;
  } else {
    incoherent_batches_ = 0;
  }
  // The largest extents only grow object by object; tighten them once per
  // batch so that a vanished large object stops widening every scan.
  max_extent_ = {};
  for (std::uint32_t i = 0; i < store_.slot_count(); ++i)
    if (store_.slots().alive(i)) grow_extent(box_[i]);
}

void Sap::rebuild(std::span<const Move> rest) {
  for (const Move& m : rest) {
    const std::uint32_t i = store_.set_shape(m.handle, m.shape);
    box_[i] = normalized_bounds(m.shape);
  }
  ++rebuilds_;
  // Along the axis where the centres spread most, few boxes share a slab.
  std::array<double, 3> sum{}, sum2{};
  for (int a = 0; a < 3; ++a) {
    auto& e = ep_[a];
    e.clear();
    for (std::uint32_t i = 0; i < store_.slot_count(); ++i) {
      if (!store_.slots().alive(i)) continue;
      e.push_back(key(box_[i].lo[a], false, i));
      e.push_back(key(box_[i].hi[a], true, i));
      const double c =
          0.5 * (static_cast<double>(box_[i].lo[a]) + static_cast<double>(box_[i].hi[a]));
      sum[a] += c;
      sum2[a] += c * c;
    }
    std::sort(e.begin(), e.end());
  }
  const double n = static_cast<double>(std::max<std::size_t>(1, store_.size()));
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (sum2[a] / n - (sum[a] / n) * (sum[a] / n) >
        sum2[axis] / n - (sum[axis] / n) * (sum[axis] / n))
      axis = a;
  pairs_.clear();
  sweep_lows_.clear();
  for (const std::uint64_t k : ep_[axis])
    if (!is_upper(k)) sweep_lows_.push_back(slot_of(k));
  for (std::size_t x = 0; x < sweep_lows_.size(); ++x) {
    const AabbF& bx = box_[sweep_lows_[x]];
    for (std::size_t y = x + 1; y < sweep_lows_.size(); ++y) {
      const AabbF& by = box_[sweep_lows_[y]];
      if (by.lo[axis] > bx.hi[axis]) break;
      if (boxes_overlap(bx, by)) pairs_.insert(sweep_lows_[x], sweep_lows_[y]);
    }
  }
}

std::size_t Sap::memory_bytes() const {
  std::size_t bytes =
      store_.memory_bytes() + box_.capacity() * sizeof(AabbF) + pairs_.memory_bytes();
  for (const auto& e : ep_) bytes += e.capacity() * sizeof(std::uint64_t);
  return bytes;
}

void Sap::validate() const {
  const auto fail = validate_store("sap");
  pairs_.validate();
  for (int a = 0; a < 3; ++a) {
    const auto& e = ep_[a];
    if (e.size() != 2 * store_.size()) fail("endpoint count");
    for (std::size_t k = 1; k < e.size(); ++k)
      if (!(e[k - 1] < e[k])) fail("endpoint list not sorted");
    for (const std::uint64_t k : e) {
      const std::uint32_t o = slot_of(k);
      if (!store_.slots().alive(o)) fail("endpoint of a dead slot");
      const float v = is_upper(k) ? box_[o].hi[a] : box_[o].lo[a];
      if (k != key(v, is_upper(k), o)) fail("endpoint disagrees with box");
    }
  }
  for (std::uint32_t o = 0; o < store_.slot_count(); ++o) {
    if (!store_.slots().alive(o)) continue;
    const AabbF b = normalized_bounds(store_.shape(o));
    for (int a = 0; a < 3; ++a) {
      if (b.lo[a] != box_[o].lo[a] || b.hi[a] != box_[o].hi[a])
        fail("stored box is not the shape's bounds");
      if (extent_of(b.lo[a], b.hi[a]) > max_extent_[a]) fail("largest extent too small");
    }
  }
  for (const auto& p : pairs_.pairs())
    if (!store_.slots().alive(p.a) || !store_.slots().alive(p.b) ||
        !boxes_overlap(box_[p.a], box_[p.b]))
      fail("pair set holds a pair whose boxes do not overlap");
  // Count overlapping boxes independently with a sweep along x.
  std::vector<std::uint32_t> active, where(store_.slot_count());
  std::size_t count = 0;
  for (const std::uint64_t k : ep_[0]) {
    const std::uint32_t o = slot_of(k);
    if (is_upper(k)) {
      const std::uint32_t at = where[o];
      active[at] = active.back();
      where[active[at]] = at;
      active.pop_back();
      continue;
    }
    for (const std::uint32_t p : active) count += boxes_overlap(box_[o], box_[p]);
    where[o] = static_cast<std::uint32_t>(active.size());
    active.push_back(o);
  }
  if (count != pairs_.size()) fail("pair set misses overlapping boxes");
}

}  // namespace broadphase
