#include <algorithm>
#include <array>
#include <bit>
#include <broadphase/sort_sweep.hpp>
#include <stdexcept>

namespace broadphase {

namespace {
std::uint32_t ordered(float f) {
  const std::uint32_t u = std::bit_cast<std::uint32_t>(f);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

// Sorts 64-bit values by their upper 32 bits: three counting passes of 11
// bits (least significant first), stable, ping-ponging between two buffers.
void radix_sort_high(std::vector<std::uint64_t>& v, std::vector<std::uint64_t>& tmp) {
  tmp.resize(v.size());
  for (int shift = 32; shift < 64; shift += 11) {
    std::array<std::uint32_t, 2048> count{};
    for (const std::uint64_t x : v) ++count[(x >> shift) & 2047];
    std::uint32_t sum = 0;
    for (std::uint32_t& c : count) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (const std::uint64_t x : v) tmp[count[(x >> shift) & 2047]++] = x;
    v.swap(tmp);
  }
}

constexpr std::size_t kRadixFrom = 256;  // below this std::sort wins
}  // namespace

SortSweep::SortSweep(const Config& c, const SortSweepOptions& o) {
  check_config(c, "sort-sweep");
  o.check();
  box_.reserve(c.expected_objects);
  dense_.reserve(c.expected_objects);
}

Handle SortSweep::insert(const Shape& s, std::uint64_t user, Motion) {
  const Handle h = store_.insert(s, user);
  if (h.index >= slot_pos_.size()) slot_pos_.resize(h.index + 1);
  slot_pos_[h.index] = static_cast<std::uint32_t>(dense_.size());
  dense_.push_back(h.index);
  box_.push_back(bounds_f(s));
  return h;
}

void SortSweep::remove(Handle h) {
  const std::uint32_t i = store_.erase(h);
  const std::uint32_t pos = slot_pos_[i];
  dense_[pos] = dense_.back();
  box_[pos] = box_.back();
  slot_pos_[dense_[pos]] = pos;
  dense_.pop_back();
  box_.pop_back();
}

void SortSweep::update(Handle h, const Shape& s) {
  const std::uint32_t i = store_.set_shape(h, s);
  box_[slot_pos_[i]] = bounds_f(s);
}

int SortSweep::sweep_axis() const {
  // Variance of the centres, accumulated in double (the sums of squares of
  // float centres would lose the small differences that matter).
  std::array<double, 3> sum{}, sum2{};
  for (const AabbF& b : box_)
    for (int a = 0; a < 3; ++a) {
      const double c = 0.5 * (static_cast<double>(b.lo[a]) + static_cast<double>(b.hi[a]));
      sum[a] += c;
      sum2[a] += c * c;
    }
  int best = 0;
  double best_var = -1;
  const double n = static_cast<double>(std::max<std::size_t>(1, box_.size()));
  for (int a = 0; a < 3; ++a) {
    const double var = sum2[a] / n - (sum[a] / n) * (sum[a] / n);
    if (var > best_var) {
      best_var = var;
      best = a;
    }
  }
  return best;
}

const std::vector<SortSweep::Item>& SortSweep::sorted() const {
  struct Buffers {
    std::vector<std::uint64_t> keys, tmp;
    std::vector<Item> items;
  };
  thread_local Buffers buf;
  const int a0 = sweep_axis();
  const int a1 = (a0 + 1) % 3, a2 = (a0 + 2) % 3;
  const std::size_t n = box_.size();
  buf.keys.resize(n);
  for (std::size_t d = 0; d < n; ++d)
    buf.keys[d] = (std::uint64_t(ordered(box_[d].lo[a0])) << 32) | d;
  if (n >= kRadixFrom)
    radix_sort_high(buf.keys, buf.tmp);
  else
    std::sort(buf.keys.begin(), buf.keys.end());
  buf.items.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t d = static_cast<std::uint32_t>(buf.keys[k]);
    const AabbF& b = box_[d];
    buf.items[k] = {b.lo[a0], b.hi[a0], b.lo[a1], b.hi[a1], b.lo[a2], b.hi[a2], dense_[d]};
  }
  return buf.items;
}

std::size_t SortSweep::memory_bytes() const {
  return store_.memory_bytes() + box_.capacity() * sizeof(AabbF) +
         (dense_.capacity() + slot_pos_.capacity()) * sizeof(std::uint32_t);
}

void SortSweep::validate() const {
  const auto fail = validate_store("sort-sweep");
  if (dense_.size() != store_.size() || box_.size() != dense_.size()) fail("dense array size");
  for (std::size_t p = 0; p < dense_.size(); ++p) {
    if (!store_.slots().alive(dense_[p]) || slot_pos_[dense_[p]] != p)
      fail("dense array and slot positions disagree");
    const AabbF b = bounds_f(store_.shape(dense_[p]));
    for (int a = 0; a < 3; ++a)
      if (b.lo[a] != box_[p].lo[a] || b.hi[a] != box_[p].hi[a])
        fail("stored box is not the shape's bounds");
  }
}

}  // namespace broadphase
