// QuantizedSweep: an incremental sweep and prune over quantized boxes that
// adds and removes pairs in Bullet's pair cache exactly as btAxisSweep3
// (16-bit grid) and bt32BitAxisSweep3 (32-bit grid) do: the same grid, the
// same order of end points, the same calls in the same order with the same
// arguments, the same proxy numbers. A world stepped over it follows the
// same trajectory, bit for bit, as over Bullet's sweep (the pair cache's
// array, whose order Bullet's islands and manifolds depend on, is the same
// after every call).
//
// Internal to broadphase::bullet, for BulletBroadphase to forward its
// calls to when the quantized test is asked for: a btBroadphaseInterface in
// its own right, made from what btAxisSweep3's constructor takes.
//
// The grid. Each axis of the world box is cut into `top` cells (top =
// 65535 for 16 bits, 2^31 - 1 for 32: Bullet keeps the 32-bit positions
// below 2^31 so that their differences fit an int). A box corner maps to
// the cell it falls in, clamped to [0, top]; a low end then takes the even
// number at or below its cell, a high end the odd number at or above (cell
// | 1), so the grid box contains the exact box and a low end never ties
// with a high end. Two proxies pair when their grid boxes overlap on all
// three axes: every pair of overlapping exact boxes, and some pairs of
// boxes a cell or two apart.
//
// Order of events. Each axis keeps its 2n end points sorted by grid
// position between two sentinels. A moved end point walks to its place by
// swaps; a low end passing a high end (or the reverse) is where a pair can
// begin or end, and the pair is added or removed at once (when the two
// boxes overlap on the other two axes). The order of the end points, and so
// of the events, depends on the tie rule (an end point walking down stops at
// an equal position, one walking up passes it) and on the order of the
// walks (setAabb: axis x, y, z; on each, the low end down, the high end up,
// the low end up, the high end down); both are Bullet's.
//
// Thread-safety: one thread at a time for everything (rayTest and aabbTest
// only read, and may run together when nothing mutates).
#pragma once

#include <btBulletCollisionCommon.h>

#include <cstdint>
#include <memory>
#include <vector>

namespace broadphase::bullet_detail {

class QuantizedSweep final : public btBroadphaseInterface {
 public:
  /// One end point on one axis: its grid position (even for a low end, odd
  /// for a high end) and the number of its proxy (0 for a sentinel).
  struct EndPoint {
    std::uint32_t position;
    std::uint32_t proxy;
  };

  /// A sweep over the grid of `bits` (16 or 32) bits laid over the box
  /// [world_min, world_max], with room for `max_proxies` proxies (numbered
  /// 1 to max_proxies; memory for all is taken here, as Bullet does), its
  /// pairs in `cache` (not owned; it must outlive this object) or, when
  /// null, in a btHashedOverlappingPairCache of its own (as btAxisSweep3).
  /// (Bullet's defaults: 16 384 proxies for btAxisSweep3, 1 500 000 for
  /// bt32BitAxisSweep3. The grid depends on the world box and the bits
  /// alone; the count only bounds the proxy numbers.)
  /// Boxes outside the world box are clamped to it (their pairs are then
  /// those of the clamped boxes, as in Bullet).
  ///
  /// Throws broadphase::InvalidConfig for `bits` other than 16 or 32, a
  /// world box with a non-finite corner, lo >= hi on an axis, or a width
  /// whose grid scale is not finite, and for `max_proxies` of 0 or above
  /// what the grid's numbers hold (32 766 for 16 bits, where Bullet asserts
  /// under 32 767; 2^31 - 2 for 32 bits).
  QuantizedSweep(const btVector3& world_min, const btVector3& world_max, std::uint32_t max_proxies,
                 int bits, btOverlappingPairCache* cache = nullptr);
  ~QuantizedSweep() override;
  QuantizedSweep(const QuantizedSweep&) = delete;
  QuantizedSweep& operator=(const QuantizedSweep&) = delete;

  /// Adds a proxy and, at once, its pairs with the proxies whose grid boxes
  /// overlap its own. Its number (m_uniqueId) is the most recently freed
  /// one, else the lowest never used, as btAxisSweep3 numbers its handles.
  /// Throws broadphase::InvalidConfig when max_proxies are live (Bullet
  /// asserts and, without asserts, overwrites its sentinel); nothing is
  /// changed then.
  btBroadphaseProxy* createProxy(const btVector3& aabbMin, const btVector3& aabbMax, int shapeType,
                                 void* userPtr, int collisionFilterGroup, int collisionFilterMask,
                                 btDispatcher* dispatcher) override;
  /// Removes the proxy: with a cache that removes at once (hashed), all its
  /// pairs first; with a deferred one (sorted), its pairs stay until the
  /// next calculateOverlappingPairs, as in Bullet.
  void destroyProxy(btBroadphaseProxy* proxy, btDispatcher* dispatcher) override;
  /// Sets the proxy's box and moves its end points, adding and removing
  /// pairs as they pass others. Same as Bullet for every box with min <=
  /// max on each axis; a coordinate NaN maps to the grid's low side (what
  /// Bullet's float-to-integer conversion gives on x86-64); a box with min
  /// > max on an axis is taken as flat at its min there (Bullet's sweep
  /// pairs such a proxy with itself and then corrupts its edge indices).
  void setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin, const btVector3& aabbMax,
               btDispatcher* dispatcher) override;
  /// The box last given to createProxy or setAabb (exact, not the grid's).
  void getAabb(btBroadphaseProxy* proxy, btVector3& aabbMin, btVector3& aabbMax) const override;

  /// Calls `callback.process` for every proxy, in the order of their high
  /// ends on x, whatever the ray: btAxisSweep3 without its ray accelerator.
  /// The callback tests the ray itself (btCollisionWorld's does).
  void rayTest(const btVector3& rayFrom, const btVector3& rayTo, btBroadphaseRayCallback& callback,
               const btVector3& aabbMin = btVector3(0, 0, 0),
               const btVector3& aabbMax = btVector3(0, 0, 0)) override;
  /// Calls `callback.process` for every proxy whose exact box overlaps the
  /// closed box [aabbMin, aabbMax], in the order of their high ends on x.
  void aabbTest(const btVector3& aabbMin, const btVector3& aabbMax,
                btBroadphaseAabbCallback& callback) override;

  /// Nothing to do with a cache that removes at once: its pairs are current
  /// after every call. With a deferred cache, drops what Bullet's sweep
  /// drops here: duplicate pairs and pairs whose grid boxes no longer
  /// overlap (their algorithms cleaned through `dispatcher`).
  void calculateOverlappingPairs(btDispatcher* dispatcher) override;

  btOverlappingPairCache* getOverlappingPairCache() override { return cache_; }
  const btOverlappingPairCache* getOverlappingPairCache() const override { return cache_; }

  /// The world box given to the constructor.
  void getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const override;
  /// With no proxy live, numbers proxies from 1 again.
  void resetPool(btDispatcher* dispatcher) override;
  /// Prints nothing, as btAxisSweep3.
  void printStats() override {}

  /// A second receiver of every pair added and removed by the sweep (not
  /// of the removals of destroyProxy), after the cache: Bullet's
  /// setOverlappingPairUserCallback. Null for none; not owned.
  void set_pair_callback(btOverlappingPairCallback* callback) { pair_callback_ = callback; }

  /// Live proxies.
  std::uint32_t proxy_count() const { return live_; }
  /// The most proxies live at once.
  std::uint32_t max_proxies() const { return capacity_ - 1; }
  /// 16 or 32.
  int bits() const { return bits_; }
  /// The end points on `axis` (0, 1, 2), sentinels included: 2 *
  /// proxy_count() + 2 of them, in sweep order.
  std::uint32_t end_point_count() const { return 2 * live_ + 2; }
  EndPoint end_point(int axis, std::uint32_t index) const { return axes_[axis][index]; }
  /// Where the low (or high) end point of a live proxy is on `axis`.
  std::uint32_t end_point_index(const btBroadphaseProxy* proxy, int axis, bool high) const;
  /// True when the grid boxes of the two live proxies overlap (the test
  /// the deferred cleanup applies).
  bool grid_boxes_overlap(const btBroadphaseProxy* a, const btBroadphaseProxy* b) const;

 private:
  struct Proxy;
  enum class End { low, high };

  void quantize(const btVector3& point, End end, std::uint32_t (&out)[3]) const;
  void grid_box(const btVector3& lo, const btVector3& hi, std::uint32_t (&low)[3],
                std::uint32_t (&high)[3]) const;
  Proxy& proxy(std::uint32_t number) const;
  bool overlap_off_axis(const Proxy& a, const Proxy& b, int axis) const;
  void walk_down(int axis, std::uint32_t index, End end, bool report, btDispatcher* dispatcher);
  void walk_up(int axis, std::uint32_t index, End end, bool report, btDispatcher* dispatcher);
  void begin_pair(Proxy& a, Proxy& b);
  void end_pair(Proxy& a, Proxy& b, btDispatcher* dispatcher);

  int bits_;
  std::uint32_t top_;  // the highest grid position, also the sentinels' (see the file comment)
  std::uint32_t even_mask_;  // clears a position's lowest bit
  btVector3 world_min_, world_max_;
  btVector3 scale_;  // grid cells per world unit, per axis

  std::uint32_t capacity_;  // proxy numbers 0 (the sentinels') to capacity_ - 1
  std::uint32_t live_ = 0;
  std::uint32_t first_free_ = 1;  // 0 when every number is taken
  std::unique_ptr<Proxy[]> proxies_;
  std::vector<EndPoint> axes_[3];  // 2 * capacity_ end points each

  btOverlappingPairCache* cache_;
  std::unique_ptr<btOverlappingPairCache> owned_cache_;
  btOverlappingPairCallback* pair_callback_ = nullptr;
};

}  // namespace broadphase::bullet_detail
