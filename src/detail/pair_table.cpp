#include <algorithm>
#include <bit>
#include <broadphase/detail/pair_table.hpp>
#include <stdexcept>

namespace broadphase {

namespace detail {

// The finaliser of splitmix64: cheap and mixes both halves of the key into
// the low bits, which index the table.
inline std::uint64_t mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

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

std::size_t PairCache::Table::find_slot(std::uint64_t lo, std::uint64_t hi) const {
  const std::size_t mask = slots_.size() - 1;
  std::size_t i = detail::mix(lo * 0x9E3779B97F4A7C15ull ^ hi) & mask;
  while (slots_[i].used == stamp_ && (slots_[i].lo != lo || slots_[i].hi != hi)) i = (i + 1) & mask;
  return i;
}

void PairCache::Table::grow() {
  std::vector<Slot> old = std::move(slots_);
  slots_.assign(std::max<std::size_t>(64, 2 * old.size()), Slot{});
  for (const Slot& s : old) {
    if (s.used != stamp_) continue;
    slots_[find_slot(s.lo, s.hi)] = s;
  }
}

bool PairCache::Table::insert(Handle a, Handle b) {
  if (2 * (pairs_.size() + 1) > slots_.size()) grow();
  std::uint64_t lo = handle_key(a), hi = handle_key(b);
  if (lo > hi) std::swap(lo, hi);
  Slot& s = slots_[find_slot(lo, hi)];
  if (s.used == stamp_) return false;
  s = {lo, hi, stamp_};
  pairs_.push_back({a, b});
  return true;
}

bool PairCache::Table::contains(Handle a, Handle b) const {
  if (slots_.empty()) return false;
  std::uint64_t lo = handle_key(a), hi = handle_key(b);
  if (lo > hi) std::swap(lo, hi);
  return slots_[find_slot(lo, hi)].used == stamp_;
}

void PairCache::Table::clear() {
  pairs_.clear();
  if (++stamp_ == 0) {
    // The stamp wrapped: old slots could look live again, so wipe them.
    for (Slot& s : slots_) s.used = 0;
    stamp_ = 1;
  }
}

void PairCache::begin_frame() {
  if (in_frame_) throw std::logic_error("PairCache: begin_frame twice without end_frame");
  std::swap(previous_, current_);
  current_.clear();
  in_frame_ = true;
}

void PairCache::add(Handle a, Handle b) {
  if (!in_frame_) throw std::logic_error("PairCache: add outside begin_frame/end_frame");
  current_.insert(a, b);
}

void PairCache::end_frame() {
  if (!in_frame_) throw std::logic_error("PairCache: end_frame without begin_frame");
  in_frame_ = false;
  begun_.clear();
  persisting_.clear();
  ended_.clear();
  for (const Entry& e : current_.pairs())
    (previous_.contains(e.a, e.b) ? persisting_ : begun_).push_back({e.a, e.b});
  for (const Entry& e : previous_.pairs())
    if (!current_.contains(e.a, e.b)) ended_.push_back({e.a, e.b});
}

void PairCache::frame(std::span<const HandlePair> pairs) {
  begin_frame();
  for (const HandlePair& p : pairs) add(p.a, p.b);
  end_frame();
}

bool PairCache::contains(Handle a, Handle b) const { return current_.contains(a, b); }

std::size_t PairCache::memory_bytes() const {
  return previous_.memory_bytes() + current_.memory_bytes() +
         (begun_.capacity() + persisting_.capacity() + ended_.capacity()) * sizeof(HandlePair);
}

}  // namespace broadphase
