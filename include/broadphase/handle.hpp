/// \file handle.hpp
/// Stable object handles and the object store every structure keeps.
///
/// A handle is a 32-bit slot index plus a 32-bit generation. A slot's
/// generation is odd while an object lives in it and even while it is free;
/// removing an object bumps it, so every handle to the removed object becomes
/// stale and is detected. Handles of other objects stay valid however many
/// objects come and go. Freed slots are reused last-in first-out, so a fresh
/// structure hands out indices 0, 1, 2, ... in insertion order.
#pragma once

#include <broadphase/geometry.hpp>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace broadphase {

/// Names one object of one structure. Default-constructed handles are null.
struct Handle {
  static constexpr std::uint32_t kNullIndex = 0xffffffffu;
  std::uint32_t index = kNullIndex;
  std::uint32_t generation = 0;

  constexpr bool is_null() const { return index == kNullIndex; }
  friend constexpr bool operator==(Handle, Handle) = default;
};

/// Thrown when a stale, null or foreign handle is passed to a structure.
class InvalidHandle : public std::invalid_argument {
 public:
  explicit InvalidHandle(Handle h)
      : std::invalid_argument("broadphase: stale or invalid handle (index " +
                              std::to_string(h.index) + ", generation " +
                              std::to_string(h.generation) + ")") {}
};

/// Thrown when a shape has a NaN or infinite number or a negative extent.
class InvalidShape : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Throws InvalidShape unless `is_valid(s)`.
inline void require_valid(const Shape& s) {
  if (!is_valid(s))
    throw InvalidShape(
        "broadphase: invalid shape (NaN or infinite coordinate, negative extent, or a sphere "
        "with unequal half-extents)");
}

/// Hands out slot indices with generations. O(1) for every operation.
/// Not thread-safe for writers; const members may run concurrently.
class SlotMap {
 public:
  /// Takes a free slot (the most recently freed one first) or a new one.
  Handle allocate() {
    std::uint32_t i;
    if (free_head_ != Handle::kNullIndex) {
      i = free_head_;
      free_head_ = next_free_[i];
    } else {
      i = static_cast<std::uint32_t>(generation_.size());
      if (i == Handle::kNullIndex) throw std::length_error("broadphase: too many objects");
      generation_.push_back(0);
      next_free_.push_back(Handle::kNullIndex);
    }
    ++generation_[i];  // even (free) -> odd (alive)
    ++live_;
    return {i, generation_[i]};
  }

  /// Frees the slot of `h`. Throws InvalidHandle when `h` is not alive.
  void release(Handle h) {
    const std::uint32_t i = index_of(h);
    ++generation_[i];  // odd -> even: every handle to this object is now stale
    next_free_[i] = free_head_;
    free_head_ = i;
    --live_;
  }

  /// True when `h` names a live object of this map.
  bool contains(Handle h) const {
    return h.index < generation_.size() && generation_[h.index] == h.generation &&
           (h.generation & 1u) != 0;
  }

  /// The slot index of a live handle. Throws InvalidHandle otherwise.
  std::uint32_t index_of(Handle h) const {
    if (!contains(h)) throw InvalidHandle(h);
    return h.index;
  }

  /// True when slot `i` holds a live object.
  bool alive(std::uint32_t i) const { return i < generation_.size() && (generation_[i] & 1u) != 0; }
  /// The live handle of slot `i` (which must be alive).
  Handle handle(std::uint32_t i) const { return {i, generation_[i]}; }
  /// Starts loading slot i's generation (a hint, see ObjectStore::prefetch).
  void prefetch(std::uint32_t i) const { __builtin_prefetch(generation_.data() + i); }

  /// One past the largest slot index ever handed out.
  std::uint32_t slot_count() const { return static_cast<std::uint32_t>(generation_.size()); }
  std::size_t size() const { return live_; }
  std::size_t memory_bytes() const {
    return generation_.capacity() * sizeof(std::uint32_t) +
           next_free_.capacity() * sizeof(std::uint32_t);
  }
  void clear() {
    generation_.clear();
    next_free_.clear();
    free_head_ = Handle::kNullIndex;
    live_ = 0;
  }

  /// Throws std::logic_error when the free list and the live count disagree.
  void validate() const {
    std::size_t free_count = 0;
    for (std::uint32_t i = free_head_; i != Handle::kNullIndex; i = next_free_[i]) {
      if (i >= generation_.size() || (generation_[i] & 1u) != 0 ||
          ++free_count > generation_.size())
        throw std::logic_error("SlotMap: corrupt free list");
    }
    if (free_count + live_ != generation_.size())
      throw std::logic_error("SlotMap: live count disagrees with the free list");
  }

 private:
  std::vector<std::uint32_t> generation_;
  std::vector<std::uint32_t> next_free_;
  std::uint32_t free_head_ = Handle::kNullIndex;
  std::size_t live_ = 0;
};

/// Slots plus each object's shape and user data: the part every structure
/// stores the same way. Structures keep their own per-object data in arrays
/// indexed by the same slot index.
class ObjectStore {
 public:
  /// Validates the shape, takes a slot, stores shape and user data.
  Handle insert(const Shape& s, std::uint64_t user) {
    require_valid(s);
    const Handle h = slots_.allocate();
    if (h.index >= shapes_.size()) {
      shapes_.resize(h.index + 1);
      user_.resize(h.index + 1);
    }
    shapes_[h.index] = s;
    user_[h.index] = user;
    if (h.index < filters_.size()) filters_[h.index] = Filter{};
    return h;
  }
  /// Frees the slot; returns its index. Throws InvalidHandle.
  std::uint32_t erase(Handle h) {
    const std::uint32_t i = slots_.index_of(h);
    slots_.release(h);
    return i;
  }
  /// Validates and stores a new shape; returns the slot index.
  std::uint32_t set_shape(Handle h, const Shape& s) {
    const std::uint32_t i = slots_.index_of(h);
    require_valid(s);
    shapes_[i] = s;
    return i;
  }

  /// Sets the collision filter of a live object. Throws InvalidHandle.
  /// The filters take no memory until the first object gets one other than
  /// the default (a world without filters pays nothing for them).
  std::uint32_t set_filter(Handle h, Filter f) {
    const std::uint32_t i = slots_.index_of(h);
    if (filters_.empty() && f == Filter{}) return i;
    if (filters_.size() < shapes_.size()) filters_.resize(shapes_.size());
    filters_[i] = f;
    return i;
  }
  /// The filter of slot `i` (the default for slots never given one).
  Filter filter(std::uint32_t i) const { return i < filters_.size() ? filters_[i] : Filter{}; }
  Filter filter_of(Handle h) const { return filter(slots_.index_of(h)); }
  /// True once any object was given a filter other than the default: until
  /// then every pair passes and walks may skip the filter test.
  bool filtered() const { return !filters_.empty(); }
  /// True when slots `i` and `j` may pair by their filters.
  bool may_pair(std::uint32_t i, std::uint32_t j) const {
    return filters_.empty() || filters_pass(filter(i), filter(j));
  }
  /// True when a ray with `mask` sees slot `i`.
  bool sees(std::uint32_t mask, std::uint32_t i) const { return (filter(i).group & mask) != 0; }
  const Shape& shape(std::uint32_t i) const { return shapes_[i]; }
  std::uint64_t user(std::uint32_t i) const { return user_[i]; }
  std::uint64_t user_data(Handle h) const { return user_[slots_.index_of(h)]; }
  const Shape& shape_of(Handle h) const { return shapes_[slots_.index_of(h)]; }
  const SlotMap& slots() const { return slots_; }
  Handle handle(std::uint32_t i) const { return slots_.handle(i); }
  /// Starts loading what an exact test of object i reads (its shape, handle
  /// and filter): a hint, for walks that test objects a step after finding
  /// them (KdTree::closest_hits).
  void prefetch(std::uint32_t i) const {
    __builtin_prefetch(shapes_.data() + i);
    slots_.prefetch(i);
    if (i < filters_.size()) __builtin_prefetch(filters_.data() + i);
  }
  std::uint32_t index_of(Handle h) const { return slots_.index_of(h); }
  bool contains(Handle h) const { return slots_.contains(h); }
  std::size_t size() const { return slots_.size(); }
  std::uint32_t slot_count() const { return slots_.slot_count(); }
  std::size_t memory_bytes() const {
    return slots_.memory_bytes() + shapes_.capacity() * sizeof(Shape) +
           user_.capacity() * sizeof(std::uint64_t) + filters_.capacity() * sizeof(Filter);
  }
  void clear() {
    slots_.clear();
    shapes_.clear();
    user_.clear();
    filters_.clear();
  }
  void validate() const { slots_.validate(); }

 private:
  SlotMap slots_;
  std::vector<Shape> shapes_;
  std::vector<std::uint64_t> user_;
  std::vector<Filter> filters_;  // empty until a filter other than the default is set
};

}  // namespace broadphase
