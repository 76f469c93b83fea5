/// \file lab/replay.hpp
/// Replays a scene through any structure, frame by frame, as the contract
/// says: frame 0 at the file's positions, then move, update, find pairs.
#pragma once

#include <broadphase/periodic.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace broadphase {

/// What one frame found and cost.
struct FrameResult {
  FrameDigest digest;
  HitDigest hits;             ///< the rays' hits (zero when the scene has no rays)
  std::uint64_t tests = 0;    ///< narrow-phase tests performed
  double update_seconds = 0;  ///< the structure's update of the moved objects
  double pairs_seconds = 0;   ///< finding all pairs
  double rays_seconds = 0;    ///< casting the scene's rays (0 without rays)
  /// The structure's update and pairs (the rays are timed apart).
  double seconds() const { return update_seconds + pairs_seconds; }
};

/// The line `run` prints for frame `frame` (frame_line): with the hits when
/// the scene has rays.
std::string frame_line(int frame, const FrameResult& r, bool rays);

/// Holds a scene and a structure filled with its objects (object id i has
/// user data i and the scene's filter of object i; moving objects are
/// inserted as Motion::dynamic, the others as Motion::fixed). Each `next()`
/// evaluates one frame: the contract's motion, the pairs, then every ray
/// of the scene cast through `cast_ray`, all hits collected. A periodic
/// scene runs through a PeriodicBroadPhase over the structure (periodic.hpp):
/// the structure then holds the images too, and the frame's pairs are the
/// contract's (i, j, S), hashed with their shift.
class Replay {
 public:
  /// Inserts every object of `scene` into `structure` (which should be empty).
  Replay(AnyBroadPhase& structure, Scene scene);
  ~Replay();
  Replay(const Replay&) = delete;
  Replay& operator=(const Replay&) = delete;

  /// Evaluates the next frame: frame 0 as loaded, each later one after the
  /// contract's motion step. The time covers the structure's work only.
  FrameResult next();

  const Scene& scene() const { return scene_; }
  int frames_done() const { return frame_; }
  /// Seconds spent inserting the scene's objects.
  double build_seconds() const { return build_seconds_; }
  /// The handle of object id `i`.
  Handle handle(std::size_t i) const { return handles_[i]; }
  /// The adapter of a periodic scene (nullptr otherwise).
  const PeriodicBroadPhase* periodic() const { return periodic_.get(); }

 private:
  AnyBroadPhase& bp_;
  std::unique_ptr<PeriodicBroadPhase> periodic_;
  std::vector<PeriodicPair> periodic_pairs_;
  Scene scene_;
  std::vector<Handle> handles_;
  std::vector<std::uint32_t> moving_;  // ids of moving objects
  std::vector<Move> moves_;
  std::vector<HandlePair> pairs_;
  int frame_ = 0;
  double build_seconds_ = 0;
};

}  // namespace broadphase
