// broadphase::FclCollisionManager against FCL's own managers, side by side
// in one process: the measuring code that fcl_bench and the engines' lab
// section (bench/engines/engines_lab.cpp) share. FCL's headers stay in
// fcl_measure.cpp, so a driver compiles without them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace broadphase::engines {

/// One size of the FCL comparison and the managers to run on it.
struct FclPlan {
  std::size_t n = 1000;  ///< objects
  int frames = 10;       ///< frames timed, after `warm` frames not timed
  int warm = 2;
  std::uint64_t seed = 1;  ///< the scene's seed
  std::string structure;   ///< ours: a registry spec (empty: kFclDefaultStructure)
  bool tree = true;        ///< FCL's DynamicAABBTreeCollisionManager
  bool sap = true;         ///< FCL's SaPCollisionManager
  bool hash = true;        ///< FCL's SpatialHashingCollisionManager
  bool naive = false;      ///< FCL's NaiveCollisionManager (every pair tested)
};

/// One manager's frames: the thread's CPU time of its update and collide.
struct FclManagerRun {
  std::string name;        ///< "broadphase (SPEC)", "fcl DynamicAABBTree", "fcl SaP", ...
  double register_ms = 0;  ///< registerObjects + setup
  std::vector<double> update_ms, collide_ms, total_ms;  ///< per timed frame
  /// Per timed frame: the callback alone, called on the frame's pairs as
  /// this manager handed them out (collected by a second, untimed collide):
  /// the part of `collide_ms` that no broad phase behind FCL's callback
  /// contract can save, the callback's reads of the two FCL objects.
  std::vector<double> callback_ms;
};

/// One size's result: ours first, then FCL's managers in the order above.
struct FclSizeRun {
  std::size_t n = 0, movers = 0;
  double world = 0;       ///< side of the scene's cube
  std::size_t pairs = 0;  ///< pairs of the first timed frame, the same for every manager
  std::vector<FclManagerRun> managers;
};

/// The study's scaled-even scene of `plan.n` objects (docs/scene-format.md:
/// density 6400 per km^3, radii 0.5 to 50, a fifth moving at 0.1 to 2 per
/// frame), every other sphere made an FCL box of the same half side; the
/// same FCL objects registered in every manager and moved once per frame;
/// then each manager's update(moved objects) and collide(callback) timed in
/// turn (the order rotating each frame, so that a busy neighbour on a
/// shared host does not always hit the same one), as the calling thread's
/// CPU time, and the callback alone on each manager's pairs in its order
/// (FclManagerRun::callback_ms). The callback counts the pairs whose AABBs overlap; the counts
/// must agree every frame, else std::runtime_error names the frame and the
/// managers. Throws std::invalid_argument for n or frames below 1.
FclSizeRun measure_fcl(const FclPlan& plan);

}  // namespace broadphase::engines
