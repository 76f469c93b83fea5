// Bullet's step with its own broad phases and with ours, side by side in
// one process: btDbvtBroadphase, bt32BitAxisSweep3 and BulletBroadphase
// over the structures named, on the same worlds (tests/bullet/
// bullet_worlds.hpp), the runs of one scene interleaved step by step so
// that the machine's load falls on all alike.
//
// The broad phase's time is what btCollisionWorld spends in updateAabbs
// (every object's box computed and handed to setAabb: the dbvt's tree and
// the sweep's edges move there) and computeOverlappingPairs (the pair
// pass), timed around those two virtual calls: no per-call timer.
//
//   bullet_bench [--scene falling|pyramid|mixed|groups|ghost] [--bodies N]
//                [--steps S] [--structures 'spec;spec'] [--no-sweep]
//
// Specs are separated by ';' (a spec's options use commas). Default: 3 000
// falling boxes, 1 000 steps, our default structure.
#include <time.h>

#include <algorithm>
#include <broadphase/bullet.hpp>
#include <broadphase/detail/median.hpp>
#include <broadphase/detail/thread_clock.hpp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "../../tests/bullet/bullet_worlds.hpp"

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

struct Run {
  std::string name;
  std::unique_ptr<World> world;
  TimedWorld* timed = nullptr;
  std::vector<double> step_ms, broad_ms;
};

using broadphase::detail::median;
double sum(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

/// A world of `kind` like make_world's, in a TimedWorld over `bp`.
std::unique_ptr<World> timed_world(WorldKind kind, int n, btBroadphaseInterface* bp,
                                   TimedWorld*& timed) {
  auto w = std::make_unique<World>();
  w->config = std::make_unique<btDefaultCollisionConfiguration>();
  w->dispatcher = std::make_unique<btCollisionDispatcher>(w->config.get());
  w->broadphase.reset(bp);
  w->solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  auto* tw =
      new TimedWorld(w->dispatcher.get(), w->broadphase.get(), w->solver.get(), w->config.get());
  w->world.reset(tw);
  timed = tw;
  populate(*w, kind, n, 1);
  return w;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene = "falling";
  int bodies = 3000, steps = 1000;
  std::vector<std::string> structures = {broadphase::BulletOptions{}.structure};
  bool sweep = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bullet_bench: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--scene") {
      scene = next();
    } else if (a == "--bodies") {
      bodies = std::atoi(next().c_str());
    } else if (a == "--steps") {
      steps = std::atoi(next().c_str());
    } else if (a == "--structures") {
      structures.clear();
      std::string list = next();
      for (std::size_t p = 0; p <= list.size();) {
        const std::size_t q = std::min(list.find(';', p), list.size());
        structures.push_back(list.substr(p, q - p));
        p = q + 1;
      }
    } else if (a == "--no-sweep") {
      sweep = false;
    } else {
      std::fprintf(stderr, "bullet_bench: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  WorldKind kind = WorldKind::falling;
  for (WorldKind k : {WorldKind::falling, WorldKind::pyramid, WorldKind::mixed, WorldKind::groups,
                      WorldKind::ghost})
    if (scene == name_of(k)) kind = k;
  if (scene != name_of(kind) || bodies <= 0 || steps <= 0) {
    std::fprintf(stderr, "bullet_bench: bad --scene, --bodies or --steps\n");
    return 2;
  }

  std::vector<Run> runs;
  auto add = [&](const std::string& name, btBroadphaseInterface* bp) {
    Run r;
    r.name = name;
    r.world = timed_world(kind, bodies, bp, r.timed);
    runs.push_back(std::move(r));
  };
  add("btDbvtBroadphase", new btDbvtBroadphase());
  if (sweep) {
    btVector3 lo, hi;
    world_box(kind, bodies, lo, hi);
    add("bt32BitAxisSweep3", new bt32BitAxisSweep3(lo, hi, static_cast<unsigned>(bodies + 64)));
  }
  for (const std::string& s : structures)
    add("ours (" + s + ")",
        new broadphase::BulletBroadphase(nullptr, broadphase::BulletOptions{s, {}}));

  for (int step = 0; step < steps; ++step) {
    for (Run& r : runs) {
      const double before = r.timed->aabbs_ms + r.timed->pairs_ms;
      const auto t = Clock::now();
      r.world->step();
      r.step_ms.push_back(ms_since(t));
      r.broad_ms.push_back(r.timed->aabbs_ms + r.timed->pairs_ms - before);
    }
  }

  std::printf(
      "scene %s, %d bodies, %d steps (thread CPU time: medians per step in ms, totals in s)\n",
      scene.c_str(), bodies, steps);
  std::printf("%-28s %10s %10s %10s %8s %10s %10s %10s\n", "broad phase", "step", "broad", "aabbs+",
              "share", "step tot", "broad tot", "pairs");
  const Run& ref = runs.front();
  for (const Run& r : runs) {
    const int pairs = r.world->world->getPairCache()->getNumOverlappingPairs();
    std::printf("%-28s %10.3f %10.3f %10.3f %7.1f%% %10.2f %10.2f %10d\n", r.name.c_str(),
                median(r.step_ms), median(r.broad_ms), r.timed->aabbs_ms / steps,
                100 * sum(r.broad_ms) / sum(r.step_ms), sum(r.step_ms) / 1000,
                sum(r.broad_ms) / 1000, pairs);
  }
  for (const Run& r : runs) {
    if (&r == &ref) continue;
    std::printf(
        "dbvt / %-21s broad phase %.2fx (median), %.2fx (total); step %.2fx (median), %.2fx "
        "(total)\n",
        r.name.c_str(), median(ref.broad_ms) / median(r.broad_ms),
        sum(ref.broad_ms) / sum(r.broad_ms), median(ref.step_ms) / median(r.step_ms),
        sum(ref.step_ms) / sum(r.step_ms));
  }
  return 0;
}
