// The broad phase's time is what btCollisionWorld spends in updateAabbs
// (every object's box computed and handed to setAabb: the dbvt's tree and
// the sweep's edges move there) and computeOverlappingPairs (the pair
// pass), timed around those two virtual calls: no per-call timer.
#include "bullet_measure.hpp"

#include <broadphase/bullet.hpp>
#include <broadphase/detail/thread_clock.hpp>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "../../tests/bullet/bullet_worlds.hpp"

namespace broadphase::engines {

namespace {

using namespace broadphase::bullet_testing;
// The thread's CPU time, not the wall clock: on the shared 2-core hosts
// (load 10-17 while this was written) the wall clock charged whichever run
// was descheduled; CPU time of one thread is what a step costs.
using Clock = broadphase::detail::ThreadClock;
double ms_since(double t0) { return broadphase::detail::thread_ms_since(t0); }

/// btDiscreteDynamicsWorld with timers around the broad phase's two calls.
class TimedWorld final : public btDiscreteDynamicsWorld {
 public:
  using btDiscreteDynamicsWorld::btDiscreteDynamicsWorld;
  void updateAabbs() override {
    const auto t = Clock::now();
    btDiscreteDynamicsWorld::updateAabbs();
    aabbs_ms += ms_since(t);
  }
  void computeOverlappingPairs() override {
    const auto t = Clock::now();
    btDiscreteDynamicsWorld::computeOverlappingPairs();
    pairs_ms += ms_since(t);
  }
  double aabbs_ms = 0, pairs_ms = 0;
};

/// A world of `kind` like make_world's, in a TimedWorld over `bp`.
std::unique_ptr<World> timed_world(WorldKind kind, int n, std::uint64_t seed,
                                   btBroadphaseInterface* bp, TimedWorld*& timed) {
  auto w = std::make_unique<World>();
  w->config = std::make_unique<btDefaultCollisionConfiguration>();
  w->dispatcher = std::make_unique<btCollisionDispatcher>(w->config.get());
  w->broadphase.reset(bp);
  w->solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  auto* tw =
      new TimedWorld(w->dispatcher.get(), w->broadphase.get(), w->solver.get(), w->config.get());
  w->world.reset(tw);
  timed = tw;
  populate(*w, kind, n, seed);
  return w;
}

struct Live {
  BulletRun result;
  std::unique_ptr<World> world;
  TimedWorld* timed = nullptr;
};

}  // namespace

std::string bullet_default_structure() { return broadphase::BulletOptions{}.structure; }

const std::vector<std::string>& bullet_scenes() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (WorldKind k : {WorldKind::falling, WorldKind::pyramid, WorldKind::mixed, WorldKind::groups,
                        WorldKind::ghost})
      v.emplace_back(name_of(k));
    return v;
  }();
  return names;
}

std::vector<BulletRun> measure_bullet(const BulletPlan& plan,
                                      const std::function<void(int, int)>& on_step) {
  WorldKind kind = WorldKind::falling;
  bool known = false;
  for (WorldKind k : {WorldKind::falling, WorldKind::pyramid, WorldKind::mixed, WorldKind::groups,
                      WorldKind::ghost})
    if (plan.scene == name_of(k)) {
      kind = k;
      known = true;
    }
  if (!known) throw std::invalid_argument("unknown Bullet scene '" + plan.scene + "'");
  if (plan.bodies < 1 || plan.steps < 1)
    throw std::invalid_argument("a Bullet scene needs at least one body and one step");

  std::vector<Live> runs;
  auto add = [&](const std::string& name, const std::string& structure, btBroadphaseInterface* bp) {
    Live r;
    r.result.name = name;
    r.result.structure = structure;
    r.world = timed_world(kind, plan.bodies, plan.seed, bp, r.timed);
    runs.push_back(std::move(r));
  };
  add("btDbvtBroadphase", "", new btDbvtBroadphase());
  if (plan.sweep) {
    btVector3 lo, hi;
    world_box(kind, plan.bodies, lo, hi);
    add("bt32BitAxisSweep3", "",
        new bt32BitAxisSweep3(lo, hi, static_cast<unsigned>(plan.bodies + 64)));
  }
  for (const std::string& s : plan.structures)
    add("ours (" + s + ")", s,
        new broadphase::BulletBroadphase(nullptr, broadphase::BulletOptions{s, {}}));

  const int total = plan.steps * static_cast<int>(runs.size());
  int done = 0;
  for (int step = 0; step < plan.steps; ++step) {
    for (Live& r : runs) {
      const double before = r.timed->aabbs_ms + r.timed->pairs_ms;
      const auto t = Clock::now();
      r.world->step();
      r.result.step_ms.push_back(ms_since(t));
      r.result.broad_ms.push_back(r.timed->aabbs_ms + r.timed->pairs_ms - before);
      if (on_step) on_step(++done, total);
    }
  }
  std::vector<BulletRun> out;
  for (Live& r : runs) {
    r.result.aabbs_ms = r.timed->aabbs_ms;
    r.result.pairs = r.world->world->getPairCache()->getNumOverlappingPairs();
    out.push_back(std::move(r.result));
  }
  return out;
}

}  // namespace broadphase::engines
