// Rays over the caller's arrays (arrays/rays.hpp): the lean path's
// multi-level grid (box_grid.hpp) over the objects' float bounds, each level
// marched by the library's conservative march (detail::RayGridMarch), the
// exact test reading the caller's arrays.
#include <algorithm>
#include <broadphase/arrays/rays.hpp>
#include <broadphase/detail/ray_walk.hpp>
#include <broadphase/rays.hpp>
#include <stdexcept>

#include "box_grid.hpp"
#include "calls.hpp"

namespace broadphase::arrays {
namespace {

using broadphase::detail::OccupiedBox;
using broadphase::detail::RayGridLevel;
using broadphase::detail::RaySlots;

// A level whose occupied cells span more than this on an axis is not
// marched (its cell keys would not fit the march's 32-bit keys): its
// objects are tested on every ray instead. Only worlds spread over more
// than a billion of their own cells have one.
constexpr std::int64_t kMaxSpan = std::int64_t{1} << 30;

// One level as the march sees it.
struct MarchLevel {
  RayGridLevel level;  // for the march's steps and reach
  double inv = 0;
  double half = 0;  // half a cell (see `key`)
  std::int64_t lo[3] = {0, 0, 0};
  std::int32_t top[3] = {0, 0, 0};  // the occupied cells' keys: 0..top
  double budget = 0;                // cells worth visiting before a scan of the level is cheaper
  OccupiedBox occupied;

  // The key of coordinate x on axis a: the level's cell of x - h/2,
  // relative to its lowest occupied one, clamped to one beyond the occupied
  // ones (cells there hold nothing). Clamping keeps the map monotone, all
  // the march needs. The half cell: an object sits in the cell of its low
  // corner, at most h below any point P of it, so its cell lies in
  // cell(P - h) .. cell(P), which is key(P - h/2) .. key(P + h/2): a reach
  // of h/2 about the shifted map instead of h about the plain one, a cell
  // fewer on each axis of every step's range.
  std::int32_t key(double x, int a) const {
    const std::int64_t c = detail::ArrayGrid::cell_of(x - half, inv) - lo[a];
    return static_cast<std::int32_t>(std::clamp<std::int64_t>(c, -1, std::int64_t{top[a]} + 1));
  }
};

// The threads a batch takes: 0 is every core, at most kMaxThreads.
unsigned shares_of(unsigned threads) {
  return std::min(detail::thread_count(threads), ArrayOptions::kMaxThreads);
}

}  // namespace

struct RayCaster::Impl {
  Objects objects;
  std::vector<AabbF> boxes;  // object i's float bounds
  detail::ArrayGrid grid;
  std::vector<MarchLevel> levels;
  // The order the levels are marched in: most hits expected first (objects
  // times their cross-section, count·h²), so that a closest-hit cast clips
  // its tmax early and marches the other levels only that far. Measured at
  // 10^5 spheres of radius 0.5 to 50 (scaled-even, most of them on the
  // coarse levels), 10^5 random rays on one thread: finest first, with a
  // reach of a whole cell, marched the fine levels to the world's end,
  // 1 600 rays/s (the k-d tree 86 000); this order and the half cell of
  // MarchLevel::key, 22 600; culling before the tested set (Cast::test),
  // 48 000.
  std::vector<std::uint32_t> order;

  // The cast of one ray: RayCast's culling, clipping and visiting, the
  // exact test reading the caller's arrays (the library's RayCast reads a
  // structure's store).
  template <class V>
  struct Cast : broadphase::detail::RayCast<V> {
    using Base = broadphase::detail::RayCast<V>;
    Cast(const Objects& o, const Ray& r, V& v) : Base(nullptr, r, v), objects(o) {}
    std::uint32_t group(std::uint32_t i) const {
      return objects.groups.empty() ? Filter{}.group : objects.groups[i];
    }
    // Object i, whose float box `box` holds its bounds: the mask, the
    // culling by the box (conservative, RayCull), and for those left, once
    // per ray (`tested`), the exact test. False when the visitor stopped
    // the cast. The box is the grid entry's, read in bucket order; the
    // culling before the set keeps the set to the few objects it passes
    // (a set of every object culled outgrew its inline table on most rays).
    bool test(std::uint32_t i, const AabbF& box, RaySlots& tested) {
      const std::uint32_t g = group(i);
      if ((g & this->ray.mask) == 0) return true;
      double t;
      if (!this->cull.enter(box, this->tmax, t)) return true;
      if (!tested.insert(i)) return true;
      return this->test_object(Handle{i, 0}, detail::read_shape(objects, i), g);
    }
    const Objects& objects;
  };

  template <class V>
  std::uint64_t cast(const Ray& ray, V& visitor) const {
    using broadphase::detail::RayGridMarch;
    Cast<V> cast(objects, ray, visitor);
    // An object is in one cell of one level, but the march may meet a cell
    // twice and a scan follows a partial march: the set keeps each object
    // tested once.
    RaySlots tested;
    auto test = [&](const detail::GridEntry& e) { return cast.test(e.index, e.box, tested); };
    for (const std::uint32_t b : order) {
      const MarchLevel& m = levels[b];
      if (m.occupied.empty()) continue;
      const RayGridMarch march(
          m.level, [&](double x, int a) { return m.key(x, a); },
          [&](const broadphase::detail::CellKey& k) {
            return grid.for_cell(b, k.c[0] + m.lo[0], k.c[1] + m.lo[1], k.c[2] + m.lo[2], test);
          });
      using Outcome = typename decltype(march)::Outcome;
      switch (march.march(cast, m.budget, &m.occupied)) {
        case Outcome::finished:
          break;
        case Outcome::stopped:
          return cast.cost.tests;
        case Outcome::scan:
          if (!grid.for_level(b, test)) return cast.cost.tests;
          break;
      }
    }
    // The objects too wide for any level (or with an infinite float box).
    for (const std::uint32_t i : grid.big())
      if (!cast.test(i, boxes[i], tested)) break;
    return cast.cost.tests;
  }

  IndexHit closest(const Ray& ray) const {
    IndexHit best;
    auto v = [&](Handle h, double t) {
      if (t < best.t || (t == best.t && h.index < best.index)) best = {h.index, t};
      return t;  // hits at exactly t are still reported: ties go to the lower index
    };
    cast(ray, v);
    return best;
  }

  bool any(const Ray& ray) const {
    bool hit = false;
    auto v = [&](Handle, double) {
      hit = true;
      return kStopRay;
    };
    cast(ray, v);
    return hit;
  }
};

RayCaster::RayCaster() : impl_(std::make_unique<Impl>()) {}
RayCaster::RayCaster(const Objects& objects) : RayCaster() { build(objects); }
RayCaster::~RayCaster() = default;
RayCaster::RayCaster(RayCaster&&) noexcept = default;
RayCaster& RayCaster::operator=(RayCaster&&) noexcept = default;

void RayCaster::build(const Objects& objects) {
  check_objects(objects);
  Impl& g = *impl_;
  g.objects = objects;
  g.boxes.resize(objects.count);
  for (std::size_t i = 0; i < objects.count; ++i)
    g.boxes[i] = bounds_f(detail::read_shape(objects, static_cast<std::uint32_t>(i)));
  g.grid.build(g.boxes, 8);
  g.levels.assign(g.grid.level_count(), MarchLevel{});
  for (std::size_t b = 0; b < g.levels.size(); ++b) {
    const detail::ArrayGrid::LevelShape s = g.grid.level_shape(b);
    MarchLevel& m = g.levels[b];
    m.inv = s.inv;
    bool fits = true;
    for (int a = 0; a < 3; ++a) {
      m.lo[a] = s.lo[a];
      const std::int64_t span = s.hi[a] - s.lo[a];
      fits = fits && span <= kMaxSpan;
      m.top[a] = static_cast<std::int32_t>(std::min(span, kMaxSpan));
      m.level.origin[a] = static_cast<double>(s.lo[a]) * s.h + s.h / 2;
      m.level.index_lo[a] = 0;
      m.level.index_hi[a] = m.top[a];
    }
    m.level.cell = s.h;
    m.half = s.h / 2;
    m.level.reach = s.h / 2;  // see MarchLevel::key
    // A march visits cells, a scan tests the level's objects culled by
    // their boxes first: about as dear one for one.
    m.budget = fits ? std::max<double>(64, s.count) : 0;
    g.grid.for_level(b, [&](const detail::GridEntry& e) {
      m.occupied.add(e.box);
      return true;
    });
  }
  g.order.resize(g.levels.size());
  for (std::uint32_t b = 0; b < g.order.size(); ++b) g.order[b] = b;
  auto weight = [&](std::uint32_t b) {
    const detail::ArrayGrid::LevelShape s = g.grid.level_shape(b);
    return static_cast<double>(s.count) * s.h * s.h;
  };
  std::stable_sort(g.order.begin(), g.order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return weight(a) > weight(b); });
}

std::uint64_t RayCaster::cast(const Ray& ray, const IndexRayVisitor& visitor) const {
  require_valid(ray);
  auto v = [&](Handle h, double t) { return visitor(h.index, t); };
  return impl_->cast(ray, v);
}

IndexHit RayCaster::closest(const Ray& ray) const {
  require_valid(ray);
  return impl_->closest(ray);
}

bool RayCaster::any(const Ray& ray) const {
  require_valid(ray);
  return impl_->any(ray);
}

void RayCaster::closest(std::span<const Ray> rays, std::span<IndexHit> out,
                        unsigned threads) const {
  if (out.size() != rays.size())
    throw std::invalid_argument("broadphase: RayCaster::closest: one result per ray");
  broadphase::detail::require_valid_rays(rays);
  broadphase::detail::run_shares(rays.size(), shares_of(threads),
                                 [&](std::size_t begin, std::size_t end, std::size_t) {
                                   for (std::size_t r = begin; r < end; ++r)
                                     out[r] = impl_->closest(rays[r]);
                                 });
}

void RayCaster::any(std::span<const Ray> rays, std::span<std::uint8_t> out,
                    unsigned threads) const {
  if (out.size() != rays.size())
    throw std::invalid_argument("broadphase: RayCaster::any: one result per ray");
  broadphase::detail::require_valid_rays(rays);
  broadphase::detail::run_shares(rays.size(), shares_of(threads),
                                 [&](std::size_t begin, std::size_t end, std::size_t) {
                                   for (std::size_t r = begin; r < end; ++r)
                                     out[r] = impl_->any(rays[r]) ? 1 : 0;
                                 });
}

void RayCaster::all(std::span<const Ray> rays, IndexHitRows& out, unsigned threads) const {
  broadphase::detail::require_valid_rays(rays);
  broadphase::detail::gather_hit_rows(
      rays.size(), shares_of(threads),
      [&](std::size_t r, std::vector<IndexHit>& hits) {
        auto v = [&](Handle h, double t) {
          hits.push_back({h.index, t});
          return kRayGoOn;
        };
        impl_->cast(rays[r], v);
      },
      [](const IndexHit& a, const IndexHit& b) {
        return a.t < b.t || (a.t == b.t && a.index < b.index);
      },
      out);
}

std::size_t RayCaster::size() const { return impl_->objects.count; }

std::size_t RayCaster::memory_bytes() const {
  return impl_->boxes.capacity() * sizeof(AabbF) + impl_->grid.memory_bytes() +
         impl_->levels.capacity() * sizeof(MarchLevel);
}

void cast_rays(const Objects& objects, std::span<const Ray> rays, std::span<IndexHit> closest,
               const ArrayOptions& options) {
  options.check();
  if (closest.size() != rays.size())
    throw std::invalid_argument("broadphase: cast_rays: one result per ray");
  broadphase::detail::require_valid_rays(rays);
  const RayCaster caster(objects);
  caster.closest(rays, closest, options.threads);
}

void cast_rays_all(const Objects& objects, std::span<const Ray> rays, IndexHitRows& out,
                   const ArrayOptions& options) {
  options.check();
  broadphase::detail::require_valid_rays(rays);
  const RayCaster caster(objects);
  caster.all(rays, out, options.threads);
}

}  // namespace broadphase::arrays
