#include <algorithm>
#include <bit>
#include <broadphase/detail/pair_table.hpp>
#include <broadphase/pair_cache.hpp>
#include <stdexcept>

namespace broadphase {

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
