// The periodic adapter (periodic.hpp, docs/periodic.md): originals and
// images in one structure, and the rule that keeps each periodic pair once.
#include <algorithm>
#include <broadphase/periodic.hpp>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

namespace broadphase {

namespace {

constexpr int kOriginal = 13;  // Shift{}.code()
constexpr std::uint64_t kCodeBits = 31;
constexpr std::uint64_t kNoKey = ~std::uint64_t{0};  // code 31: neither original nor image

const char* const kAxis[] = {"x", "y", "z"};

}  // namespace

PeriodicBroadPhase::PeriodicBroadPhase(AnyBroadPhase& inner, PeriodicCell cell)
    : inner_(inner), cell_(cell) {
  for (int a = 0; a < 3; ++a)
    if (!(std::isfinite(cell_.length[a]) && cell_.length[a] > 0))
      throw std::invalid_argument(std::string("periodic cell: the length on ") + kAxis[a] +
                                  " must be finite and > 0");
  if (inner_.size() != 0)
    throw std::invalid_argument("periodic cell: the structure to wrap must be empty");
  cover({0, 0, 0});
}

void PeriodicBroadPhase::check_shape(const Shape& s) const {
  require_valid(s);
  for (int a = 0; a < 3; ++a) {
    if (!cell_.periodic[a]) continue;
    const double l = cell_.length[a];
    if (!(s.center[a] >= 0 && s.center[a] <= l))
      throw InvalidShape(std::string("periodic cell: a centre's ") + kAxis[a] + " " +
                         std::to_string(s.center[a]) + " is outside [0, " + std::to_string(l) +
                         "] on a periodic axis");
    if (!(s.half[a] < l / 2))
      throw InvalidShape(std::string("periodic cell: a half-extent on ") + kAxis[a] + " of " +
                         std::to_string(s.half[a]) + " is not below half the cell (" +
                         std::to_string(l / 2) + ")");
  }
}

bool PeriodicBroadPhase::cover(const Vec3& h) {
  bool grew = false;
  for (int a = 0; a < 3; ++a) {
    if (!cell_.periodic[a] || (h[a] <= max_half_[a] && reach_[a] > 0)) continue;
    max_half_[a] = std::max(max_half_[a], h[a]);
    // The margin covers the rounding of the contract's shifted centre and of
    // its differences (a few ulps of 2 L_a and of e_a + e_b): 2^-40 of them.
    reach_[a] = max_half_[a] + (cell_.length[a] + max_half_[a]) * 0x1p-40;
    grew = true;
  }
  return grew;
}

void PeriodicBroadPhase::reserve_reach(const Vec3& largest_half) {
  if (cover(largest_half)) renew_all();
}

void PeriodicBroadPhase::image_codes(const Shape& s, std::vector<std::uint8_t>& out) const {
  out.clear();
  // Per axis, the shifts the object takes: 0 always, +1 near the low face,
  // -1 near the high face (both when the reach spans the cell).
  int options[3][3];
  int count[3];
  for (int a = 0; a < 3; ++a) {
    count[a] = 0;
    options[a][count[a]++] = 0;
    if (!cell_.periodic[a]) continue;
    const double c = s.center[a], e = s.half[a];
    if (c - e <= reach_[a]) options[a][count[a]++] = 1;
    if (c + e >= cell_.length[a] - reach_[a]) options[a][count[a]++] = -1;
  }
  for (int i = 0; i < count[0]; ++i)
    for (int j = 0; j < count[1]; ++j)
      for (int k = 0; k < count[2]; ++k) {
        const int code = (options[0][i] + 1) + 3 * (options[1][j] + 1) + 9 * (options[2][k] + 1);
        if (code != kOriginal) out.push_back(static_cast<std::uint8_t>(code));
      }
  std::sort(out.begin(), out.end());
}

Shape PeriodicBroadPhase::moved(const Shape& s, int code) const {
  // The contract's shifted centre: c + S_a * L_a in double, per axis.
  const Shift t = Shift::of_code(code);
  Shape m = s;
  for (int a = 0; a < 3; ++a)
    if (t[a] != 0) m.center[a] = s.center[a] + t[a] * cell_.length[a];
  return m;
}

void PeriodicBroadPhase::renew_images(std::size_t k, const Shape& shape, std::vector<Move>& moves) {
  Slot& slot = slots_[k];
  image_codes(shape, codes_);
  std::vector<Image> next;
  next.reserve(codes_.size());
  auto old = slot.images.begin();
  for (std::uint8_t code : codes_) {
    while (old != slot.images.end() && old->code < code) {
      drop(old->handle);
      --images_;
      ++old;
    }
    const Shape image = moved(shape, code);
    if (old != slot.images.end() && old->code == code) {
      moves.push_back({old->handle, image});
      next.push_back(*old++);
    } else {
      next.push_back({code, put(image, key(k, code), slot.motion, slot.filter)});
      ++images_;
    }
  }
  for (; old != slot.images.end(); ++old) {
    drop(old->handle);
    --images_;
  }
  slot.images = std::move(next);
}

void PeriodicBroadPhase::renew_all() {
  std::vector<Move> moves;
  for (std::size_t k = 0; k < slots_.size(); ++k)
    if (!slots_[k].original.is_null()) renew_images(k, inner_.shape(slots_[k].original), moves);
  inner_.update(moves);
}

Handle PeriodicBroadPhase::insert(const Shape& s, std::uint64_t user, Motion m, Filter f) {
  check_shape(s);
  std::size_t k;
  if (!free_.empty()) {
    k = free_.back();
    free_.pop_back();
  } else {
    k = slots_.size();
    slots_.emplace_back();
  }
  Slot& slot = slots_[k];
  slot.user = user;
  slot.filter = f;
  slot.motion = m;
  slot.images.clear();
  slot.original = put(s, key(k, kOriginal), m, f);
  ++live_;
  if (cover(s.half)) {
    renew_all();
  } else {
    std::vector<Move> moves;
    renew_images(k, s, moves);
  }
  return slot.original;
}

Handle PeriodicBroadPhase::put(const Shape& s, std::uint64_t k, Motion m, Filter f) {
  const Handle h = inner_.insert(s, k, m, f);
  if (h.index >= key_of_.size()) key_of_.resize(std::size_t{h.index} + 1, kNoKey);
  key_of_[h.index] = k;
  return h;
}

void PeriodicBroadPhase::drop(Handle h) {
  inner_.remove(h);
  key_of_[h.index] = kNoKey;
}

std::size_t PeriodicBroadPhase::slot_of(Handle h) const {
  // The structure's handle of an original, its slot in key_of_ (no virtual
  // call: a frame asks for every mover and every pair's two objects).
  if (h.index >= key_of_.size() || (key_of_[h.index] & kCodeBits) != kOriginal)
    throw InvalidHandle(h);
  const auto k = static_cast<std::size_t>(key_of_[h.index] >> 5);
  if (!(slots_[k].original == h)) throw InvalidHandle(h);
  return k;
}

void PeriodicBroadPhase::remove(Handle h) {
  const std::size_t k = slot_of(h);
  Slot& slot = slots_[k];
  for (const Image& im : slot.images) drop(im.handle);
  images_ -= slot.images.size();
  slot.images.clear();
  drop(slot.original);
  slot.original = Handle{};
  free_.push_back(k);
  --live_;
}

void PeriodicBroadPhase::update(Handle h, const Shape& s) {
  const Move m{h, s};
  update(std::span<const Move>(&m, 1));
}

void PeriodicBroadPhase::update(std::span<const Move> moves) {
  std::vector<std::size_t> moved_slots;
  moved_slots.reserve(moves.size());
  for (const Move& m : moves) {
    moved_slots.push_back(slot_of(m.handle));
    check_shape(m.shape);
  }
  bool grew = false;
  for (const Move& m : moves) grew = cover(m.shape.half) || grew;
  // Each slot once, with its last move's shape. A replay's moves come in
  // ascending slots already (no handle twice): then no sort (update's
  // samples fell from 8.5% to 7.8% of a replay of 20 000 objects, 4000
  // moving, under perf).
  std::vector<std::size_t> order;  // indices into `moves`, one per slot
  if (std::adjacent_find(moved_slots.begin(), moved_slots.end(), std::greater_equal<>()) !=
      moved_slots.end()) {
    order.resize(moves.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return moved_slots[a] < moved_slots[b]; });
    std::size_t kept = 0;
    for (std::size_t i = 0; i < order.size(); ++i)
      if (i + 1 == order.size() || moved_slots[order[i + 1]] != moved_slots[order[i]])
        order[kept++] = order[i];
    order.resize(kept);
  }
  std::vector<Move> inner_moves;
  inner_moves.reserve(moves.size());
  const std::size_t count = order.empty() ? moves.size() : order.size();
  for (std::size_t n = 0; n < count; ++n) {
    const std::size_t i = order.empty() ? n : order[n];
    const std::size_t k = moved_slots[i];
    inner_moves.push_back({slots_[k].original, moves[i].shape});
    if (!grew) renew_images(k, moves[i].shape, inner_moves);
  }
  inner_.update(inner_moves);
  if (grew) renew_all();
}

void PeriodicBroadPhase::set_filter(Handle h, Filter f) {
  Slot& slot = slots_[slot_of(h)];
  slot.filter = f;
  inner_.set_filter(slot.original, f);
  for (const Image& im : slot.images) inner_.set_filter(im.handle, f);
}

Filter PeriodicBroadPhase::filter(Handle h) const { return slots_[slot_of(h)].filter; }

bool PeriodicBroadPhase::contains(Handle h) const {
  if (h.index >= key_of_.size() || (key_of_[h.index] & kCodeBits) != kOriginal) return false;
  return slots_[static_cast<std::size_t>(key_of_[h.index] >> 5)].original == h;
}

Shape PeriodicBroadPhase::shape(Handle h) const {
  return inner_.shape(slots_[slot_of(h)].original);
}

std::uint64_t PeriodicBroadPhase::user_data(Handle h) const { return slots_[slot_of(h)].user; }

QueryCost PeriodicBroadPhase::find_pairs(std::vector<PeriodicPair>& out) const {
  std::vector<HandlePair> copies;
  const QueryCost cost = inner_.find_pairs(copies);
  for (const HandlePair& p : copies) {
    std::uint64_t ua = key_of_[p.a.index], ub = key_of_[p.b.index];
    std::size_t ka = static_cast<std::size_t>(ua >> 5), kb = static_cast<std::size_t>(ub >> 5);
    if (ka == kb) continue;  // an object and its own image: not a pair
    // The object that stays in place is the one with the smaller user data
    // (then slot): the contract's i of i < j. Keep the pair only when that
    // copy is its original; the other copy's shift is then S.
    const std::uint64_t user_a = slots_[ka].user, user_b = slots_[kb].user;
    if (user_b < user_a || (user_b == user_a && kb < ka)) {
      std::swap(ua, ub);
      std::swap(ka, kb);
    }
    if ((ua & kCodeBits) != kOriginal) continue;
    out.push_back({slots_[ka].original, slots_[kb].original,
                   Shift::of_code(static_cast<int>(ub & kCodeBits))});
  }
  return cost;
}

QueryCost PeriodicBroadPhase::cast_ray(const Ray& r,
                                       FunctionRef<double(Handle, double)> visitor) const {
  return inner_.cast_ray(r, [&](Handle h, double t) {
    if ((key_of_[h.index] & kCodeBits) != kOriginal) return kRayGoOn;  // rays do not wrap
    return visitor(h, t);
  });
}

std::size_t PeriodicBroadPhase::memory_bytes() const {
  std::size_t bytes = inner_.memory_bytes() + slots_.capacity() * sizeof(Slot) +
                      free_.capacity() * sizeof(std::size_t) +
                      key_of_.capacity() * sizeof(std::uint64_t);
  for (const Slot& s : slots_) bytes += s.images.capacity() * sizeof(Image);
  return bytes;
}

void PeriodicBroadPhase::validate() const {
  auto fail = [](const std::string& why) { throw std::logic_error("periodic adapter: " + why); };
  std::size_t live = 0, images = 0;
  std::vector<std::uint8_t> codes;
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const Slot& slot = slots_[k];
    if (slot.original.is_null()) {
      if (!slot.images.empty()) fail("free slot " + std::to_string(k) + " holds images");
      continue;
    }
    ++live;
    const std::string at = "object in slot " + std::to_string(k);
    if (!inner_.contains(slot.original) || inner_.user_data(slot.original) != key(k, kOriginal) ||
        key_of_[slot.original.index] != key(k, kOriginal) ||

        !(inner_.filter(slot.original) == slot.filter))
      fail(at + ": its original is not held as it should be");
    const Shape shape = inner_.shape(slot.original);
    image_codes(shape, codes);
    if (codes.size() != slot.images.size()) fail(at + ": not the images the rule gives it");
    for (std::size_t i = 0; i < codes.size(); ++i) {
      const Image& im = slot.images[i];
      if (im.code != codes[i] || !inner_.contains(im.handle) ||
          inner_.user_data(im.handle) != key(k, im.code) ||
          key_of_[im.handle.index] != key(k, im.code) ||
          !(inner_.shape(im.handle) == moved(shape, im.code)) ||
          !(inner_.filter(im.handle) == slot.filter))
        fail(at + ": image " + std::to_string(im.code) + " is wrong");
    }
    images += codes.size();
  }
  if (live != live_ || images != images_ || live + free_.size() != slots_.size())
    fail("the counts disagree with the slots");
  if (inner_.size() != live_ + images_) fail("the structure holds other objects");
  inner_.validate();
}

}  // namespace broadphase
