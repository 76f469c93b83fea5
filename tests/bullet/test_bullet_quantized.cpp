// QuantizedSweep (src/bullet/quantized_sweep.hpp) against Bullet's own
// btAxisSweep3 (16-bit grid) and bt32BitAxisSweep3 (32-bit grid):
//   - worlds built with Bullet's API alone, stepped once over Bullet's
//     sweep and once over ours: every body's transform and velocities are
//     the same bits after every step, and so are the pair cache's arrays
//     (the same pairs in the same order, with the same proxy numbers);
//   - random boxes created, moved and destroyed through the interface, both
//     sweeps side by side: after every call the same end points on each
//     axis and the same pair array, with a hashed cache and with a sorted
//     (deferred) one;
//   - the errors of the constructor and of createProxy.
#include <gtest/gtest.h>

#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/config_error.hpp>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "bullet_checks.hpp"
#include "bullet_worlds.hpp"
#include "quantized_sweep.hpp"
#include "testing.hpp"

namespace {

using broadphase::bullet_detail::QuantizedSweep;
using namespace broadphase::bullet_testing;

/// Bullet's sweep with its end points readable (they are protected).
template <class Sweep>
class OpenSweep final : public Sweep {
 public:
  using Sweep::Sweep;
  std::uint32_t end_point_count() const { return 2u * this->m_numHandles + 2; }
  QuantizedSweep::EndPoint end_point(int axis, std::uint32_t i) const {
    return {this->m_pEdges[axis][i].m_pos, this->m_pEdges[axis][i].m_handle};
  }
  std::uint32_t end_point_index(const btBroadphaseProxy* p, int axis, bool high) const {
    auto* h = static_cast<const typename Sweep::Handle*>(p);
    return high ? h->m_maxEdges[axis] : h->m_minEdges[axis];
  }
};
using Open16 = OpenSweep<btAxisSweep3>;
using Open32 = OpenSweep<bt32BitAxisSweep3>;

/// Bullet's sweep of `bits` bits with the ray accelerator off (ours has
/// none; the pairs do not depend on it).
btBroadphaseInterface* bullet_sweep(int bits, const btVector3& lo, const btVector3& hi,
                                    std::uint32_t max_proxies, btOverlappingPairCache* cache) {
  if (bits == 16) return new Open16(lo, hi, static_cast<unsigned short>(max_proxies), cache, true);
  return new Open32(lo, hi, max_proxies, cache, true);
}

/// The end points of Bullet's sweep on `axis`.
std::vector<std::pair<std::uint32_t, std::uint32_t>> end_points(btBroadphaseInterface& bullet,
                                                                int bits, int axis) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  auto read = [&](const auto& s) {
    for (std::uint32_t i = 0; i < s.end_point_count(); ++i) {
      const QuantizedSweep::EndPoint e = s.end_point(axis, i);
      out.emplace_back(e.position, e.proxy);
    }
  };
  if (bits == 16) {
    read(static_cast<Open16&>(bullet));
  } else {
    read(static_cast<Open32&>(bullet));
  }
  return out;
}
std::vector<std::pair<std::uint32_t, std::uint32_t>> end_points(const QuantizedSweep& ours,
                                                                int axis) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  for (std::uint32_t i = 0; i < ours.end_point_count(); ++i) {
    const QuantizedSweep::EndPoint e = ours.end_point(axis, i);
    out.emplace_back(e.position, e.proxy);
  }
  return out;
}

/// One entry of a pair array: the proxies' numbers, their clients (as
/// `client_id` names them), and whether the pair has an algorithm.
using PairEntry = std::tuple<int, int, long, long, bool>;

template <class ClientId>
std::vector<PairEntry> pair_array(btOverlappingPairCache& cache, ClientId client_id) {
  std::vector<PairEntry> out;
  btBroadphasePairArray& pairs = cache.getOverlappingPairArray();
  for (int i = 0; i < pairs.size(); ++i) {
    const btBroadphasePair& p = pairs[i];
    auto uid = [](const btBroadphaseProxy* q) { return q == nullptr ? -1 : q->m_uniqueId; };
    auto client = [&](const btBroadphaseProxy* q) {
      return q == nullptr ? -1L : client_id(q->m_clientObject);
    };
    out.emplace_back(uid(p.m_pProxy0), uid(p.m_pProxy1), client(p.m_pProxy0), client(p.m_pProxy1),
                     p.m_algorithm != nullptr);
  }
  return out;
}

// ---------------------------------------------------------------- worlds

bool same_bits(const btVector3& a, const btVector3& b) {
  return std::memcmp(&a.x(), &b.x(), 3 * sizeof(btScalar)) == 0;
}
bool same_bits(const btTransform& a, const btTransform& b) {
  return same_bits(a.getOrigin(), b.getOrigin()) && same_bits(a.getBasis()[0], b.getBasis()[0]) &&
         same_bits(a.getBasis()[1], b.getBasis()[1]) && same_bits(a.getBasis()[2], b.getBasis()[2]);
}

/// The first object whose transform or velocities differ in a bit, or -1.
int first_difference(btCollisionWorld& a, btCollisionWorld& b) {
  for (int i = 0; i < a.getNumCollisionObjects(); ++i) {
    const btCollisionObject* p = a.getCollisionObjectArray()[i];
    const btCollisionObject* q = b.getCollisionObjectArray()[i];
    if (!same_bits(p->getWorldTransform(), q->getWorldTransform())) return i;
    const btRigidBody* r = btRigidBody::upcast(p);
    const btRigidBody* s = btRigidBody::upcast(q);
    if (r == nullptr) continue;
    if (!same_bits(r->getLinearVelocity(), s->getLinearVelocity()) ||
        !same_bits(r->getAngularVelocity(), s->getAngularVelocity()))
      return i;
  }
  return -1;
}

long world_index(const void* client) {
  return static_cast<const btCollisionObject*>(client)->getWorldArrayIndex();
}

/// The manifolds: their bodies' indices and contact counts, in order.
std::vector<std::tuple<long, long, int>> manifolds(btDispatcher& d) {
  std::vector<std::tuple<long, long, int>> out;
  for (int m = 0; m < d.getNumManifolds(); ++m) {
    const btPersistentManifold* man = d.getManifoldByIndexInternal(m);
    out.emplace_back(world_index(man->getBody0()), world_index(man->getBody1()),
                     man->getNumContacts());
  }
  return out;
}

struct WorldCase {
  WorldKind kind;
  int bodies;
  int steps;
  bool sorted_cache;  // a btSortedOverlappingPairCache (deferred removal) for both
};

/// Steps the world of `c` over Bullet's sweep of `bits` bits and over ours,
/// comparing after every step; returns how many steps were compared.
/// Prints what the grid adds to the exact pairs: the pairs of boxes that do
/// not overlap (a cell or two apart), how many steps have any, and the
/// widest gap, in grid cells.
void compare_world(const WorldCase& c, int bits) {
  const std::uint64_t seed = 21;
  SCOPED_TRACE(std::string("world ") + name_of(c.kind) + ", " + std::to_string(c.bodies) +
               " bodies, " + std::to_string(bits) + "-bit grid" +
               (c.sorted_cache ? ", sorted cache" : ", hashed cache"));
  btVector3 lo, hi;
  world_box(c.kind, c.bodies, lo, hi);
  const std::uint32_t max_proxies = static_cast<std::uint32_t>(c.bodies) + 64;
  std::unique_ptr<btOverlappingPairCache> bullet_cache, our_cache;
  if (c.sorted_cache) {
    bullet_cache = std::make_unique<btSortedOverlappingPairCache>();
    our_cache = std::make_unique<btSortedOverlappingPairCache>();
  }
  // Ours as a user gets it: BulletBroadphase with the quantized option.
  broadphase::BulletOptions options;
  options.quantized_bits = bits;
  options.world_min = lo;
  options.world_max = hi;
  options.max_proxies = max_proxies;
  auto* our_sweep = new broadphase::BulletBroadphase(our_cache.get(), options);
  auto bullet = make_world(c.kind, c.bodies, seed,
                           bullet_sweep(bits, lo, hi, max_proxies, bullet_cache.get()));
  auto ours = make_world(c.kind, c.bodies, seed, our_sweep);
  bullet->world->getDispatchInfo().m_deterministicOverlappingPairs = true;
  ours->world->getDispatchInfo().m_deterministicOverlappingPairs = true;
  ASSERT_EQ(pair_array(*bullet->world->getPairCache(), world_index),
            pair_array(*ours->world->getPairCache(), world_index))
      << "after the world is built";

  btVector3 cells_per_unit =
      btVector3(1, 1, 1) * static_cast<btScalar>(bits == 16 ? 0xffff : 0x7fffffff) / (hi - lo);
  auto inside = [&](const btBroadphaseProxy& p) {
    for (int axis = 0; axis < 3; ++axis)
      if (!(p.m_aabbMin[axis] >= lo[axis] && p.m_aabbMax[axis] <= hi[axis])) return false;
    return true;
  };
  std::size_t pairs_seen = 0, apart_pairs = 0, clamped_pairs = 0;
  int steps_with_apart = 0;
  double widest_gap = 0;  // in grid cells
  for (int s = 0; s < c.steps; ++s) {
    bullet->step();
    ours->step();
    const int body = first_difference(*bullet->world, *ours->world);
    ASSERT_EQ(body, -1) << "step " << s << ": body " << body << " differs";
    const auto pairs = pair_array(*ours->world->getPairCache(), world_index);
    ASSERT_EQ(pair_array(*bullet->world->getPairCache(), world_index), pairs) << "step " << s;
    ASSERT_EQ(manifolds(*bullet->dispatcher), manifolds(*ours->dispatcher)) << "step " << s;

    // The exact test's view of the same step: every pair of overlapping
    // boxes that the filters pass is in the cache; the others in the cache
    // are boxes less than 3 cells apart (each grid box reaches under 2
    // cells below its box and 1 above).
    btBroadphasePairArray& array = ours->world->getPairCache()->getOverlappingPairArray();
    bool any_apart = false;
    for (int i = 0; i < array.size(); ++i) {
      const btBroadphaseProxy& a = *array[i].m_pProxy0;
      const btBroadphaseProxy& b = *array[i].m_pProxy1;
      ++pairs_seen;
      if (boxes_overlap(a, b)) continue;
      if (!inside(a) || !inside(b)) {
        // Clamped to the world box's side, where boxes far apart meet (a
        // body thrown out of the world box; Bullet's sweep pairs them too).
        ++clamped_pairs;
        continue;
      }
      any_apart = true;
      ++apart_pairs;
      double gap = 0;
      for (int axis = 0; axis < 3; ++axis) {
        const double apart = std::max(static_cast<double>(a.m_aabbMin[axis]) - b.m_aabbMax[axis],
                                      static_cast<double>(b.m_aabbMin[axis]) - a.m_aabbMax[axis]);
        gap = std::max(gap, apart * cells_per_unit[axis]);
      }
      // On the 32-bit grid a float box's own rounding is many cells wide.
      if (bits == 16 || sizeof(btScalar) == 8) {
        ASSERT_LT(gap, 3.01) << "step " << s << ": a pair " << gap << " cells apart";
      }
      widest_gap = std::max(widest_gap, gap);
    }
    steps_with_apart += any_apart;
    if (!c.sorted_cache) {
      std::vector<btBroadphaseProxy*> proxies;
      for (int i = 0; i < ours->world->getNumCollisionObjects(); ++i)
        proxies.push_back(ours->world->getCollisionObjectArray()[i]->getBroadphaseHandle());
      const std::set<Pair> exact = brute_pairs(proxies, groups_pass);
      const std::set<Pair> cached = cache_pairs(*ours->world->getPairCache(), true);
      ASSERT_EQ(exact, cached) << "step " << s;
    }
  }
  EXPECT_GT(pairs_seen, 0u);
  std::printf(
      "%s, %d bodies, %d-bit grid, %s cache: %d steps bit-identical; %zu pairs seen, %zu of "
      "them (on %d steps) of boxes apart, the widest gap %.2f cells; %zu of boxes outside the "
      "world box\n",
      name_of(c.kind), c.bodies, bits, c.sorted_cache ? "sorted" : "hashed", c.steps, pairs_seen,
      apart_pairs, steps_with_apart, widest_gap, clamped_pairs);
}

// The long run: boxes falling onto a plane and settling, 1 000 steps (a
// tenth under the sanitizers), on both grids.
TEST(BulletQuantized, FallingWorldIsBitIdenticalOver1000Steps) {
  const int steps = broadphase::testing::repeats(1000);
  for (int bits : {32, 16}) compare_world({WorldKind::falling, 300, steps, false}, bits);
}

// The other worlds, shorter: a pyramid, spheres and boxes with kinematic
// movers, four collision groups, a ghost object sweeping a pile.
TEST(BulletQuantized, EveryWorldKindIsBitIdentical) {
  const int steps = std::max(30, broadphase::testing::repeats(300));
  for (WorldKind kind : {WorldKind::pyramid, WorldKind::mixed, WorldKind::groups, WorldKind::ghost})
    for (int bits : {32, 16}) compare_world({kind, 300, steps, false}, bits);
}

// A cache with deferred removal (btSortedOverlappingPairCache): pairs are
// added, duplicated and cleaned up in calculateOverlappingPairs.
TEST(BulletQuantized, SortedCacheWorldIsBitIdentical) {
  const int steps = std::max(30, broadphase::testing::repeats(300));
  for (int bits : {32, 16}) compare_world({WorldKind::mixed, 200, steps, true}, bits);
}

// ------------------------------------------------------- the model test

/// Records the proxies a ray or box query visits.
struct Visits final : btBroadphaseRayCallback {  // (an aabb callback too)
  std::vector<int> seen;
  bool process(const btBroadphaseProxy* p) override {
    seen.push_back(p->m_uniqueId);
    return true;
  }
};

/// Logs the pair events a sweep gives its second receiver
/// (set_pair_callback, Bullet's setOverlappingPairUserCallback): +a,b for
/// an add, -a,b for a removal, by proxy numbers in the order given.
struct EventLog final : btOverlappingPairCallback {
  std::vector<std::string> events;
  btBroadphasePair* addOverlappingPair(btBroadphaseProxy* a, btBroadphaseProxy* b) override {
    events.push_back("+" + std::to_string(a->m_uniqueId) + "," + std::to_string(b->m_uniqueId));
    return nullptr;
  }
  void* removeOverlappingPair(btBroadphaseProxy* a, btBroadphaseProxy* b, btDispatcher*) override {
    events.push_back("-" + std::to_string(a->m_uniqueId) + "," + std::to_string(b->m_uniqueId));
    return nullptr;
  }
  void removeOverlappingPairsContainingProxy(btBroadphaseProxy* a, btDispatcher*) override {
    events.push_back("x" + std::to_string(a->m_uniqueId));
  }
};

std::string text(const btVector3& lo, const btVector3& hi) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "[%g %g %g]-[%g %g %g]", static_cast<double>(lo.x()),
                static_cast<double>(lo.y()), static_cast<double>(lo.z()),
                static_cast<double>(hi.x()), static_cast<double>(hi.y()),
                static_cast<double>(hi.z()));
  return buf;
}

/// Random boxes for the model tests, in and a little around `world`:
/// coordinates on a coarse lattice half the time, so that end points tie
/// on the grid; some boxes flat, now and then a NaN; inverted boxes (min >
/// max on an axis) only when `inverted` (Bullet's sweep walks an end point
/// by a stale index after one, and its edge indices go wrong: they are left
/// out of the comparison with it).
struct RandomBoxes {
  std::mt19937_64 rng;
  btVector3 world_lo, world_hi;
  bool inverted;

  double uniform(double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(rng() >> 11) * 0x1p-53);
  }
  bool chance(double p) { return uniform(0, 1) < p; }
  double coordinate(int axis) {
    double v = uniform(world_lo[axis] * 1.2, world_hi[axis] * 1.2);
    if (chance(0.5)) v = std::round(v * 4) / 4;
    return v;
  }
  void fresh(btVector3& lo, btVector3& hi) {
    for (int a = 0; a < 3; ++a) {
      const double c = coordinate(a);
      double half =
          chance(0.1) ? 0 : (chance(0.5) ? 0.5 * static_cast<double>(rng() % 6) : uniform(0, 3));
      if (inverted && chance(0.03)) half = -0.3;
      lo[a] = static_cast<btScalar>(c - half);
      hi[a] = static_cast<btScalar>(c + half);
    }
    if (chance(0.005)) lo[static_cast<int>(rng() % 3)] = std::numeric_limits<btScalar>::quiet_NaN();
  }
  /// A move of the box [lo, hi], in place: a jump elsewhere, or on each
  /// axis a small shift, a step of the lattice, or one end moved.
  void move(btVector3& lo, btVector3& hi) {
    if (chance(0.2) || std::isnan(lo.x() + lo.y() + lo.z() + hi.x() + hi.y() + hi.z()))
      return fresh(lo, hi);
    for (int a = 0; a < 3; ++a) {
      const double r = uniform(0, 1);
      const btScalar d =
          static_cast<btScalar>(r < 0.4 ? uniform(-0.05, 0.05) : (r < 0.7 ? 0.25 : -0.25));
      if (r < 0.8) {
        lo[a] += d;
        hi[a] += d;
      } else if (r < 0.9) {
        lo[a] += d;
      } else {
        hi[a] -= d;
      }
      if (!inverted && lo[a] > hi[a]) hi[a] = lo[a];
    }
  }
  /// Groups and masks from three bits, so that some pairs are filtered.
  void filter(int& group, int& mask) {
    group = 1 << (rng() % 3);
    mask = chance(0.7) ? -1 : static_cast<int>(rng() % 8);
  }
};

/// Random calls on Bullet's sweep and ours side by side, compared after
/// each (the end points on each axis, each proxy's end-point indices, the
/// pair array, the events of the second receiver, the proxies a query
/// visits): `ops` calls from `seed`, with
/// a hashed or a sorted cache.
void run_against_bullet(int bits, bool sorted, std::uint64_t seed, int ops) {
  std::printf("model test against Bullet: %d-bit grid, %s cache, seed %" PRIu64 "\n", bits,
              sorted ? "sorted" : "hashed", seed);
  SCOPED_TRACE("seed " + std::to_string(seed) + ", " + std::to_string(bits) + "-bit grid, " +
               (sorted ? "sorted" : "hashed") + " cache");
  const btVector3 world_lo(-10, -5, -8), world_hi(10, 5, 8);
  RandomBoxes boxes{std::mt19937_64(seed), world_lo, world_hi, false};
  const std::uint32_t max_proxies = 60;
  std::unique_ptr<btOverlappingPairCache> bullet_cache, our_cache;
  if (sorted) {
    bullet_cache = std::make_unique<btSortedOverlappingPairCache>();
    our_cache = std::make_unique<btSortedOverlappingPairCache>();
  } else {
    bullet_cache = std::make_unique<btHashedOverlappingPairCache>();
    our_cache = std::make_unique<btHashedOverlappingPairCache>();
  }
  std::unique_ptr<btBroadphaseInterface> bullet(
      bullet_sweep(bits, world_lo, world_hi, max_proxies, bullet_cache.get()));
  QuantizedSweep ours(world_lo, world_hi, max_proxies, bits, our_cache.get());
  EventLog bullet_events, our_events;
  if (bits == 16) {
    static_cast<Open16&>(*bullet).setOverlappingPairUserCallback(&bullet_events);
  } else {
    static_cast<Open32&>(*bullet).setOverlappingPairUserCallback(&bullet_events);
  }
  ours.set_pair_callback(&our_events);
  auto bullet_index = [&](const btBroadphaseProxy* p, int axis, bool high) {
    return bits == 16 ? static_cast<Open16&>(*bullet).end_point_index(p, axis, high)
                      : static_cast<Open32&>(*bullet).end_point_index(p, axis, high);
  };

  // Clients: the same fake pointers on both sides, named by their index.
  std::vector<char> clients(max_proxies);
  auto client_id = [&](const void* c) { return static_cast<const char*>(c) - clients.data(); };
  struct Live {
    btBroadphaseProxy* bullet;
    btBroadphaseProxy* ours;
  };
  std::vector<Live> live;

  std::size_t events_seen = 0;
  auto check = [&](int op, const std::string& what) {
    ASSERT_EQ(ours.end_point_count(), 2 * live.size() + 2) << "op " << op << " (" << what << ")";
    for (int axis = 0; axis < 3; ++axis)
      ASSERT_EQ(end_points(*bullet, bits, axis), end_points(ours, axis))
          << "op " << op << " (" << what << "), axis " << axis;
    for (const Live& l : live)
      for (int axis = 0; axis < 3; ++axis)
        for (bool high : {false, true})
          ASSERT_EQ(bullet_index(l.bullet, axis, high), ours.end_point_index(l.ours, axis, high))
              << "op " << op << " (" << what << "), proxy " << l.ours->m_uniqueId << ", axis "
              << axis << (high ? ", high end" : ", low end");
    ASSERT_EQ(pair_array(*bullet_cache, client_id), pair_array(*our_cache, client_id))
        << "op " << op << " (" << what << ")";
    ASSERT_EQ(bullet_events.events, our_events.events) << "op " << op << " (" << what << ")";
    events_seen += our_events.events.size();
    bullet_events.events.clear();
    our_events.events.clear();
  };

  int creates = 0, moves = 0, destroys = 0, passes = 0, queries = 0;
  std::size_t most_pairs = 0;
  for (int op = 0; op < ops; ++op) {
    const double r = boxes.uniform(0, 1);
    const bool full = live.size() == max_proxies;
    if (live.empty() || (!full && r < 0.12)) {
      btVector3 lo, hi;
      boxes.fresh(lo, hi);
      std::size_t slot = 0;  // a client no live proxy has
      for (; slot < clients.size(); ++slot) {
        bool used = false;
        for (const Live& l : live) used = used || l.ours->m_clientObject == &clients[slot];
        if (!used) break;
      }
      int group, mask;
      boxes.filter(group, mask);
      Live l;
      l.bullet = bullet->createProxy(lo, hi, 0, &clients[slot], group, mask, nullptr);
      l.ours = ours.createProxy(lo, hi, 0, &clients[slot], group, mask, nullptr);
      ASSERT_EQ(l.bullet->m_uniqueId, l.ours->m_uniqueId) << "op " << op;
      // Bullet leaves a new proxy's box unset until setAabb; so does a
      // world, and so does this test.
      bullet->setAabb(l.bullet, lo, hi, nullptr);
      ours.setAabb(l.ours, lo, hi, nullptr);
      live.push_back(l);
      ++creates;
      check(op, "create " + std::to_string(l.ours->m_uniqueId) + " at " + text(lo, hi));
    } else if (r < 0.2 || (full && r < 0.3)) {
      const std::size_t i = boxes.rng() % live.size();
      const std::string what = "destroy " + std::to_string(live[i].ours->m_uniqueId);
      bullet->destroyProxy(live[i].bullet, nullptr);
      ours.destroyProxy(live[i].ours, nullptr);
      live[i] = live.back();
      live.pop_back();
      ++destroys;
      check(op, what);
    } else if (r < 0.25) {
      bullet->calculateOverlappingPairs(nullptr);
      ours.calculateOverlappingPairs(nullptr);
      ++passes;
      check(op, "calculateOverlappingPairs");
    } else if (r < 0.27) {
      btVector3 lo, hi;
      boxes.fresh(lo, hi);
      Visits a, b, c, d;
      bullet->rayTest(lo, hi, a);
      ours.rayTest(lo, hi, b);
      ASSERT_EQ(a.seen, b.seen) << "op " << op << " (rayTest)";
      bullet->aabbTest(lo, hi, c);
      ours.aabbTest(lo, hi, d);
      ASSERT_EQ(c.seen, d.seen) << "op " << op << " (aabbTest)";
      ++queries;
    } else {
      const std::size_t i = boxes.rng() % live.size();
      btVector3 lo = live[i].ours->m_aabbMin, hi = live[i].ours->m_aabbMax;
      boxes.move(lo, hi);
      const std::string what = "setAabb of " + std::to_string(live[i].ours->m_uniqueId) + " from " +
                               text(live[i].ours->m_aabbMin, live[i].ours->m_aabbMax) + " to " +
                               text(lo, hi);
      bullet->setAabb(live[i].bullet, lo, hi, nullptr);
      ours.setAabb(live[i].ours, lo, hi, nullptr);
      ++moves;
      check(op, what);
    }
    if (::testing::Test::HasFatalFailure()) return;
    most_pairs = std::max<std::size_t>(most_pairs, our_cache->getNumOverlappingPairs());
  }
  // Empty both, then start again from number 1 after resetPool.
  for (const Live& l : live) {
    bullet->destroyProxy(l.bullet, nullptr);
    ours.destroyProxy(l.ours, nullptr);
  }
  live.clear();
  bullet->calculateOverlappingPairs(nullptr);
  ours.calculateOverlappingPairs(nullptr);
  check(ops, "all destroyed");
  bullet->resetPool(nullptr);
  ours.resetPool(nullptr);
  btBroadphaseProxy* p = bullet->createProxy(world_lo, world_hi, 0, &clients[0], 1, -1, nullptr);
  btBroadphaseProxy* q = ours.createProxy(world_lo, world_hi, 0, &clients[0], 1, -1, nullptr);
  EXPECT_EQ(p->m_uniqueId, 1);
  EXPECT_EQ(q->m_uniqueId, 1);
  live.push_back({p, q});
  check(ops + 1, "after resetPool");
  EXPECT_GT(most_pairs, 10u);
  EXPECT_GT(destroys, ops / 20);
  EXPECT_GT(events_seen, static_cast<std::size_t>(ops / 10));
  std::printf(
      "  %d creates, %d moves, %d destroys, %d passes, %d queries, up to %zu pairs, %zu pair "
      "events\n",
      creates, moves, destroys, passes, queries, most_pairs, events_seen);
}

TEST(BulletQuantized, RandomCallsMatchBulletsSweep) {
  // BROADPHASE_TEST_SEED=n replays the seeds n, n + 1, ... printed by a
  // failed run.
  const char* fixed = std::getenv("BROADPHASE_TEST_SEED");
  const std::uint64_t base =
      fixed != nullptr ? std::strtoull(fixed, nullptr, 10) : std::random_device{}();
  const int seeds = broadphase::testing::repeats(6);
  for (int k = 0; k < seeds; ++k)
    for (int bits : {16, 32})
      for (bool sorted : {false, true}) {
        run_against_bullet(bits, sorted, base + static_cast<std::uint64_t>(k), 10000);
        if (::testing::Test::HasFatalFailure()) return;
      }
}

/// The pairs of overlapping grid boxes among the live proxies whose
/// filters pass, by proxy numbers, from the end points alone.
std::set<std::pair<int, int>> grid_pairs(const QuantizedSweep& sweep,
                                         const std::vector<btBroadphaseProxy*>& live) {
  std::set<std::pair<int, int>> out;
  auto position = [&](const btBroadphaseProxy* p, int axis, bool high) {
    return sweep.end_point(axis, sweep.end_point_index(p, axis, high)).position;
  };
  for (std::size_t i = 0; i < live.size(); ++i)
    for (std::size_t j = i + 1; j < live.size(); ++j) {
      bool meet = groups_pass(*live[i], *live[j]);
      for (int axis = 0; axis < 3 && meet; ++axis)
        meet = position(live[i], axis, false) <= position(live[j], axis, true) &&
               position(live[j], axis, false) <= position(live[i], axis, true);
      if (meet)
        out.emplace(std::min(live[i]->m_uniqueId, live[j]->m_uniqueId),
                    std::max(live[i]->m_uniqueId, live[j]->m_uniqueId));
    }
  return out;
}

// Ours alone, inverted boxes too (taken as flat at their min, where
// Bullet's bookkeeping breaks): after every call each axis is sorted by
// position, each proxy's end points are where it says, and the hashed
// cache holds exactly the pairs of overlapping grid boxes.
TEST(BulletQuantized, RandomCallsKeepTheSweepConsistent) {
  const char* fixed = std::getenv("BROADPHASE_TEST_SEED");
  const std::uint64_t seed =
      fixed != nullptr ? std::strtoull(fixed, nullptr, 10) : std::random_device{}();
  for (int bits : {16, 32}) {
    std::printf("model test alone: %d-bit grid, seed %" PRIu64 "\n", bits, seed);
    SCOPED_TRACE("seed " + std::to_string(seed) + ", " + std::to_string(bits) + "-bit grid");
    const btVector3 world_lo(-10, -5, -8), world_hi(10, 5, 8);
    RandomBoxes boxes{std::mt19937_64(seed), world_lo, world_hi, true};
    QuantizedSweep sweep(world_lo, world_hi, 60, bits);
    std::vector<btBroadphaseProxy*> live;
    int inverted = 0;
    const int ops = broadphase::testing::repeats(20000);
    for (int op = 0; op < ops; ++op) {
      const double r = boxes.uniform(0, 1);
      btVector3 lo, hi;
      if (live.empty() || (live.size() < 60 && r < 0.12)) {
        boxes.fresh(lo, hi);
        int group, mask;
        boxes.filter(group, mask);
        live.push_back(sweep.createProxy(lo, hi, 0, nullptr, group, mask, nullptr));
      } else if (r < 0.2 || (live.size() == 60 && r < 0.3)) {
        const std::size_t i = boxes.rng() % live.size();
        sweep.destroyProxy(live[i], nullptr);
        live[i] = live.back();
        live.pop_back();
        continue;
      } else {
        btBroadphaseProxy* p = live[boxes.rng() % live.size()];
        lo = p->m_aabbMin;
        hi = p->m_aabbMax;
        boxes.move(lo, hi);
        sweep.setAabb(p, lo, hi, nullptr);
      }
      inverted += lo.x() > hi.x() || lo.y() > hi.y() || lo.z() > hi.z();
      for (int axis = 0; axis < 3; ++axis) {
        for (std::uint32_t i = 1; i < sweep.end_point_count(); ++i)
          ASSERT_LE(sweep.end_point(axis, i - 1).position, sweep.end_point(axis, i).position)
              << "op " << op << ", axis " << axis << ", index " << i;
        for (const btBroadphaseProxy* p : live)
          for (bool high : {false, true}) {
            const QuantizedSweep::EndPoint e =
                sweep.end_point(axis, sweep.end_point_index(p, axis, high));
            ASSERT_EQ(e.proxy, static_cast<std::uint32_t>(p->m_uniqueId)) << "op " << op;
            ASSERT_EQ(e.position & 1, high ? 1u : 0u) << "op " << op;
          }
      }
      std::set<std::pair<int, int>> cached;
      btBroadphasePairArray& pairs = sweep.getOverlappingPairCache()->getOverlappingPairArray();
      for (int i = 0; i < pairs.size(); ++i)
        cached.emplace(pairs[i].m_pProxy0->m_uniqueId, pairs[i].m_pProxy1->m_uniqueId);
      ASSERT_EQ(cached, grid_pairs(sweep, live)) << "op " << op;
    }
    EXPECT_GT(inverted, ops / 1000);
    std::printf("  %d calls, %d with an inverted box\n", ops, inverted);
  }
}

// ----------------------------------------------------------------- errors

TEST(BulletQuantized, RefusesBadConfigurations) {
  using broadphase::InvalidConfig;
  const btVector3 lo(-1, -1, -1), hi(1, 1, 1);
  const btScalar inf = std::numeric_limits<btScalar>::infinity();
  const btScalar nan = std::numeric_limits<btScalar>::quiet_NaN();
  EXPECT_THROW(QuantizedSweep(lo, hi, 10, 8), InvalidConfig);
  EXPECT_THROW(QuantizedSweep(lo, hi, 10, 64), InvalidConfig);
  EXPECT_THROW(QuantizedSweep(hi, lo, 10, 16), InvalidConfig);                   // inverted
  EXPECT_THROW(QuantizedSweep(lo, btVector3(1, -1, 1), 10, 32), InvalidConfig);  // empty
  EXPECT_THROW(QuantizedSweep(lo, btVector3(1, inf, 1), 10, 32), InvalidConfig);
  EXPECT_THROW(QuantizedSweep(btVector3(nan, -1, -1), hi, 10, 32), InvalidConfig);
  const btScalar big = std::numeric_limits<btScalar>::max();
  EXPECT_THROW(QuantizedSweep(btVector3(-big, -1, -1), btVector3(big, 1, 1), 10, 32),
               InvalidConfig);  // a width that overflows
  EXPECT_THROW(QuantizedSweep(lo, hi, 0, 32), InvalidConfig);
  EXPECT_THROW(QuantizedSweep(lo, hi, 32767, 16), InvalidConfig);
  EXPECT_NO_THROW(QuantizedSweep(lo, hi, 32766, 16));
  EXPECT_NO_THROW(QuantizedSweep(lo, hi, 1, 32));
}

// One proxy too many is refused with nothing changed: the others keep
// their pairs, and a destroyed proxy's number is taken again.
// The adapter's option names what is wrong, and with a good one forwards
// to the sweep (proxies numbered from 1, pairs in the caller's cache).
TEST(BulletQuantized, AdapterOptionIsCheckedAndForwards) {
  broadphase::BulletOptions o;
  o.quantized_bits = 24;
  try {
    broadphase::BulletBroadphase bp(nullptr, o);
    ADD_FAILURE() << "24 bits accepted";
  } catch (const broadphase::InvalidConfig& e) {
    EXPECT_NE(std::string(e.what()).find("quantized_bits"), std::string::npos) << e.what();
  }
  o.quantized_bits = 16;
  o.world_min = btVector3(1, 1, 1);
  o.world_max = btVector3(-1, 2, 2);
  EXPECT_THROW(broadphase::BulletBroadphase(nullptr, o), broadphase::InvalidConfig);
  o.world_min = btVector3(-10, -10, -10);
  o.world_max = btVector3(10, 10, 10);
  o.max_proxies = 4;
  btHashedOverlappingPairCache cache;
  broadphase::BulletBroadphase bp(&cache, o);
  btBroadphaseProxy* a = bp.createProxy(btVector3(0, 0, 0), btVector3(1, 1, 1), BOX_SHAPE_PROXYTYPE,
                                        nullptr, 1, -1, nullptr);
  btBroadphaseProxy* b = bp.createProxy(btVector3(1, 1, 1), btVector3(2, 2, 2), BOX_SHAPE_PROXYTYPE,
                                        nullptr, 1, -1, nullptr);
  bp.calculateOverlappingPairs(nullptr);
  EXPECT_EQ(a->m_uniqueId, 1);
  EXPECT_EQ(b->m_uniqueId, 2);
  EXPECT_EQ(bp.proxy_count(), 2u);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 1);
  EXPECT_EQ(bp.getOverlappingPairCache(), &cache);
  bp.destroyProxy(a, nullptr);
  bp.destroyProxy(b, nullptr);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 0);
}

TEST(BulletQuantized, RefusesAProxyBeyondMax) {
  QuantizedSweep sweep(btVector3(-10, -10, -10), btVector3(10, 10, 10), 3, 16);
  const btVector3 lo(-1, -1, -1), hi(1, 1, 1);
  btBroadphaseProxy* p[3];
  for (auto& q : p) q = sweep.createProxy(lo, hi, 0, nullptr, 1, -1, nullptr);
  EXPECT_EQ(sweep.getOverlappingPairCache()->getNumOverlappingPairs(), 3);
  EXPECT_THROW(sweep.createProxy(lo, hi, 0, nullptr, 1, -1, nullptr), broadphase::InvalidConfig);
  EXPECT_EQ(sweep.proxy_count(), 3u);
  EXPECT_EQ(sweep.getOverlappingPairCache()->getNumOverlappingPairs(), 3);
  sweep.destroyProxy(p[1], nullptr);
  EXPECT_EQ(sweep.getOverlappingPairCache()->getNumOverlappingPairs(), 1);
  btBroadphaseProxy* again = sweep.createProxy(lo, hi, 0, nullptr, 1, -1, nullptr);
  EXPECT_EQ(again->m_uniqueId, 2);
  EXPECT_EQ(sweep.getOverlappingPairCache()->getNumOverlappingPairs(), 3);
}

// The grid's reach, on a world whose grid cells are world units (so the
// cases are exact in float): boxes up to 2 cells apart can pair, boxes a
// tenth of a cell apart need not (the grid's cells are fixed, not centred
// on the boxes); Bullet's sweep agrees. The exact test pairs only the
// touching ones.
TEST(BulletQuantized, NearlyTouchingBoxesPairOnTheGrid) {
  struct Case {
    double a_hi, b_lo;
    bool pair;
  };
  // a's high end in cell 100 reaches position 101; b's low end in cell 101
  // starts at 100, in cell 102 at 102; a's in cell 101 reaches 101.
  const Case cases[] = {{100, 100, true},
                        {100, 101.5, true},
                        {100, 101.99, true},
                        {100, 102, false},
                        {101.9, 102, false}};
  for (int bits : {16, 32}) {
    const btScalar top = static_cast<btScalar>(bits == 16 ? 0xffff : 0x7fffffff);
    const btVector3 world_lo(0, 0, 0), world_hi(top, top, top);
    for (const Case& c : cases) {
      SCOPED_TRACE(std::to_string(bits) + "-bit grid, a's top " + std::to_string(c.a_hi) +
                   ", b's bottom " + std::to_string(c.b_lo));
      QuantizedSweep ours(world_lo, world_hi, 4, bits);
      std::unique_ptr<btBroadphaseInterface> bullet(
          bullet_sweep(bits, world_lo, world_hi, 4, nullptr));
      const btVector3 a0(10, 10, 10), a1(static_cast<btScalar>(c.a_hi), 20, 20);
      const btVector3 b0(static_cast<btScalar>(c.b_lo), 10, 10), b1(200, 20, 20);
      for (btBroadphaseInterface* s : {static_cast<btBroadphaseInterface*>(&ours), bullet.get()}) {
        s->createProxy(a0, a1, 0, nullptr, 1, -1, nullptr);
        s->createProxy(b0, b1, 0, nullptr, 1, -1, nullptr);
      }
      EXPECT_EQ(ours.getOverlappingPairCache()->getNumOverlappingPairs(), c.pair ? 1 : 0);
      EXPECT_EQ(bullet->getOverlappingPairCache()->getNumOverlappingPairs(), c.pair ? 1 : 0);
    }
  }
}

}  // namespace
