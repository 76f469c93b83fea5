#include <algorithm>
#include <bit>
#include <broadphase/detail/pair_table.hpp>
#include <stdexcept>

namespace broadphase {

namespace detail {

std::size_t PairTable::home(std::uint64_t k) const { return mix(k) & (slots_.size() - 1); }

std::uint32_t PairTable::find(std::uint64_t k) const {
  if (slots_.empty()) return kEmpty;
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t i = home(k);; i = (i + 1) & mask) {
    if (slots_[i].key == k) return static_cast<std::uint32_t>(i);
    if (slots_[i].key == kEmptyKey) return kEmpty;
  }
}

void PairTable::rehash(std::size_t capacity) {
  slots_.assign(capacity, Slot{kEmptyKey, 0});
  const std::size_t mask = capacity - 1;
  for (std::size_t d = 0; d < dense_.size(); ++d) {
    const std::uint64_t k = key(dense_[d].a, dense_[d].b);
    std::size_t i = home(k);
    while (slots_[i].key != kEmptyKey) i = (i + 1) & mask;
    slots_[i] = {k, static_cast<std::uint32_t>(d)};
  }
}

void PairTable::reserve(std::size_t n) {
  const std::size_t want = std::bit_ceil(std::max<std::size_t>(16, 2 * n));
  if (want > slots_.size()) rehash(want);
  dense_.reserve(n);
}

bool PairTable::insert(std::uint32_t a, std::uint32_t b) {
  if (2 * (dense_.size() + 1) > slots_.size()) rehash(std::max<std::size_t>(16, 2 * slots_.size()));
  const std::uint64_t k = key(a, b);
  const std::size_t mask = slots_.size() - 1;
  std::size_t i = home(k);
  for (;; i = (i + 1) & mask) {
    if (slots_[i].key == k) return false;
    if (slots_[i].key == kEmptyKey) break;
  }
  slots_[i] = {k, static_cast<std::uint32_t>(dense_.size())};
  dense_.push_back(a < b ? Pair{a, b} : Pair{b, a});
  return true;
}

bool PairTable::erase(std::uint32_t a, std::uint32_t b) {
  const std::uint32_t at = find(key(a, b));
  if (at == kEmpty) return false;
  // Move the last dense member into the hole and repoint its slot.
  const std::uint32_t hole = slots_[at].dense;
  const Pair last = dense_.back();
  dense_.pop_back();
  if (hole != dense_.size()) {
    dense_[hole] = last;
    slots_[find(key(last.a, last.b))].dense = hole;
  }
  // Backward-shift deletion: pull later members of the probe run into the
  // gap so that no lookup ever stops early at it.
  const std::size_t mask = slots_.size() - 1;
  std::size_t gap = at;
  for (std::size_t i = (gap + 1) & mask; slots_[i].key != kEmptyKey; i = (i + 1) & mask) {
    const std::size_t h = home(slots_[i].key);
    // Movable when its home is not inside (gap, i] cyclically.
    const bool movable = gap <= i ? (h <= gap || h > i) : (h <= gap && h > i);
    if (movable) {
      slots_[gap] = slots_[i];
      gap = i;
    }
  }
  slots_[gap].key = kEmptyKey;
  return true;
}

void PairTable::clear() {
  for (Slot& s : slots_) s.key = kEmptyKey;
  dense_.clear();
}

void PairTable::validate() const {
  std::size_t live = 0;
  for (const Slot& s : slots_) {
    if (s.key == kEmptyKey) continue;
    ++live;
    if (s.dense >= dense_.size() || key(dense_[s.dense].a, dense_[s.dense].b) != s.key)
      throw std::logic_error("PairTable: slot and dense array disagree");
  }
  if (live != dense_.size()) throw std::logic_error("PairTable: member count");
  for (const Pair& p : dense_)
    if (p.a > p.b || !contains(p.a, p.b)) throw std::logic_error("PairTable: unreachable member");
}

}  // namespace detail

}  // namespace broadphase
