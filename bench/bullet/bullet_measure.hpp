// Bullet's step with its own broad phases and with ours, side by side in
// one process: the measuring code that bullet_bench and the engines' lab
// section (bench/engines/engines_lab.cpp) share. Bullet's headers stay in
// bullet_measure.cpp, so a driver compiles without them.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace broadphase::engines {

/// What to step: a world of tests/bullet/bullet_worlds.hpp, and the broad
/// phases to step it with.
struct BulletPlan {
  std::string scene = "falling";        ///< falling, pyramid, mixed, groups or ghost
  int bodies = 3000;                    ///< about this many bodies (the worlds' own rounding)
  int steps = 1000;                     ///< steps of 1/60 s, one substep each
  std::uint64_t seed = 1;               ///< the worlds' jitter
  bool sweep = true;                    ///< bt32BitAxisSweep3 beside btDbvtBroadphase
  std::vector<std::string> structures;  ///< ours: one BulletBroadphase per registry spec
};

/// One broad phase's run of a scene: the thread's CPU time of every step.
struct BulletRun {
  std::string name;              ///< "btDbvtBroadphase", "bt32BitAxisSweep3", "ours (SPEC)"
  std::string structure;         ///< SPEC for ours, empty for Bullet's own
  std::vector<double> step_ms;   ///< each step (stepSimulation), ms
  std::vector<double> broad_ms;  ///< of which updateAabbs + computeOverlappingPairs, ms
  double aabbs_ms = 0;           ///< updateAabbs alone, summed over the steps
  int pairs = 0;                 ///< overlapping pairs in Bullet's cache after the last step
};

/// BulletBroadphase's default structure (BulletOptions{}.structure).
std::string bullet_default_structure();

/// The scene names `BulletPlan::scene` takes.
const std::vector<std::string>& bullet_scenes();

/// Steps the scene under btDbvtBroadphase (always first), bt32BitAxisSweep3
/// (when `plan.sweep`) and ours over each structure, the runs interleaved
/// step by step so that the machine's load falls on all alike. Times are the
/// calling thread's CPU time (detail/thread_clock.hpp). `on_step(done,
/// total)`, when given, is called after each step of every run. Throws
/// std::invalid_argument for an unknown scene, bodies or steps below 1, and
/// UnknownStructure for a spec the registry does not know.
std::vector<BulletRun> measure_bullet(const BulletPlan& plan,
                                      const std::function<void(int, int)>& on_step = {});

}  // namespace broadphase::engines
