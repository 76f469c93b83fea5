// SlotMap and ObjectStore: generations, stale handles, LIFO reuse.
#include <gtest/gtest.h>

#include <broadphase/handle.hpp>
#include <cmath>

namespace broadphase {
namespace {

TEST(SlotMap, HandsOutIndicesInOrderWithOddGenerations) {
  SlotMap m;
  for (std::uint32_t i = 0; i < 5; ++i) {
    const Handle h = m.allocate();
    EXPECT_EQ(h.index, i);
    EXPECT_EQ(h.generation, 1u);
    EXPECT_TRUE(m.contains(h));
    EXPECT_TRUE(m.alive(i));
  }
  EXPECT_EQ(m.size(), 5u);
  EXPECT_EQ(m.slot_count(), 5u);
  m.validate();
}

TEST(SlotMap, ReleasedHandlesAreStale) {
  SlotMap m;
  const Handle a = m.allocate();
  const Handle b = m.allocate();
  m.release(a);
  EXPECT_FALSE(m.contains(a));
  EXPECT_FALSE(m.alive(a.index));
  EXPECT_THROW(m.index_of(a), InvalidHandle);
  EXPECT_THROW(m.release(a), InvalidHandle);
  EXPECT_TRUE(m.contains(b));
  EXPECT_EQ(m.size(), 1u);
  m.validate();
}

TEST(SlotMap, ReusesFreedSlotsLastInFirstOut) {
  SlotMap m;
  Handle h[4];
  for (Handle& x : h) x = m.allocate();
  m.release(h[1]);
  m.release(h[3]);
  m.release(h[2]);
  const Handle r1 = m.allocate();
  const Handle r2 = m.allocate();
  const Handle r3 = m.allocate();
  EXPECT_EQ(r1.index, 2u);
  EXPECT_EQ(r2.index, 3u);
  EXPECT_EQ(r3.index, 1u);
  EXPECT_EQ(r1.generation, 3u);
  // The old handle to the reused slot stays stale.
  EXPECT_FALSE(m.contains(h[2]));
  EXPECT_TRUE(m.contains(r1));
  EXPECT_EQ(m.allocate().index, 4u);
  m.validate();
}

TEST(SlotMap, NullAndForeignHandlesAreNotContained) {
  SlotMap m;
  m.allocate();
  EXPECT_TRUE(Handle{}.is_null());
  EXPECT_FALSE(m.contains(Handle{}));
  EXPECT_FALSE(m.contains(Handle{7, 1}));
  EXPECT_FALSE(m.contains(Handle{0, 2}));  // even: a free slot's generation
  EXPECT_FALSE(m.contains(Handle{0, 3}));  // a future generation
  EXPECT_THROW(m.index_of(Handle{}), InvalidHandle);
}

TEST(SlotMap, ManyGenerationsOfOneSlot) {
  SlotMap m;
  Handle last;
  for (int i = 0; i < 1000; ++i) {
    last = m.allocate();
    EXPECT_EQ(last.index, 0u);
    EXPECT_EQ(last.generation, static_cast<std::uint32_t>(2 * i + 1));
    m.release(last);
  }
  EXPECT_EQ(m.size(), 0u);
  EXPECT_EQ(m.slot_count(), 1u);
  m.clear();
  EXPECT_EQ(m.allocate(), (Handle{0, 1}));
}

TEST(ObjectStore, KeepsShapesAndUserDataBySlot) {
  ObjectStore s;
  const Handle a = s.insert(Shape::sphere({1, 2, 3}, 4), 42);
  const Handle b = s.insert(Shape::box({0, 0, 0}, {1, 2, 3}), 7);
  EXPECT_EQ(s.user_data(a), 42u);
  EXPECT_EQ(s.shape_of(b), Shape::box({0, 0, 0}, {1, 2, 3}));
  EXPECT_EQ(s.set_shape(a, Shape::sphere({0, 0, 0}, 1)), a.index);
  EXPECT_EQ(s.shape_of(a), Shape::sphere({0, 0, 0}, 1));
  EXPECT_EQ(s.erase(a), a.index);
  EXPECT_THROW(s.shape_of(a), InvalidHandle);
  EXPECT_THROW(s.set_shape(a, Shape::sphere({0, 0, 0}, 1)), InvalidHandle);
  const Handle c = s.insert(Shape::sphere({9, 9, 9}, 0), 9);
  EXPECT_EQ(c.index, a.index);
  EXPECT_NE(c.generation, a.generation);
  EXPECT_EQ(s.size(), 2u);
  s.validate();
}

TEST(ObjectStore, RejectsInvalidShapesWithoutTakingASlot) {
  ObjectStore s;
  EXPECT_THROW(s.insert(Shape::sphere({0, 0, 0}, -1), 0), InvalidShape);
  EXPECT_THROW(s.insert(Shape::sphere({std::nan(""), 0, 0}, 1), 0), InvalidShape);
  EXPECT_THROW(s.insert(Shape::box({0, 0, 0}, {1, INFINITY, 1}), 0), InvalidShape);
  EXPECT_EQ(s.size(), 0u);
  EXPECT_EQ(s.slot_count(), 0u);
  const Handle h = s.insert(Shape::sphere({0, 0, 0}, 1), 0);
  EXPECT_THROW(s.set_shape(h, Shape::sphere({0, 0, 0}, -2)), InvalidShape);
  EXPECT_EQ(s.shape_of(h), Shape::sphere({0, 0, 0}, 1));
}

}  // namespace
}  // namespace broadphase
