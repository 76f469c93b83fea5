/// \file inline_stack.hpp
/// The traversal stack every tree uses: a small inline array with a heap
/// fallback, so deep traversals never drop a node and shallow ones never
/// allocate.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace broadphase::detail {

/// A LIFO stack holding its first N entries inline and the rest on the heap.
template <class T, std::size_t N>
class InlineStack {
 public:
  /// Pushes `v`; allocates only beyond N entries.
  void push(const T& v) {
    if (size_ < N)
      inline_[size_] = v;
    else
      heap_.push_back(v);
    ++size_;
  }
  /// Removes and returns the top entry (the stack must not be empty).
  T pop() {
    --size_;
    if (size_ < N) return inline_[size_];
    T v = heap_.back();
    heap_.pop_back();
    return v;
  }
  /// True when nothing is on the stack.
  bool empty() const { return size_ == 0; }
  /// Entries on the stack.
  std::size_t size() const { return size_; }
  /// Entry `i`, counted from the bottom.
  const T& operator[](std::size_t i) const { return i < N ? inline_[i] : heap_[i - N]; }
  /// Empties the stack, keeping any heap capacity.
  void clear() {
    size_ = 0;
    heap_.clear();
  }

 private:
  std::array<T, N> inline_;
  std::vector<T> heap_;
  std::size_t size_ = 0;
};

}  // namespace broadphase::detail
