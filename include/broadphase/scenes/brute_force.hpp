/// \file scenes/brute_force.hpp
/// The contract's frames by brute force: every pair and every (ray, object)
/// of a scene tested with the evaluations docs/scene-format.md writes out,
/// coded here from that text alone and not from the structures' predicates
/// (geometry.hpp, ray.hpp), so that it is an oracle independent of them.
/// O(n^2 + rays·n) a frame: for reference scenes and tests.
#pragma once

#include <broadphase/scenes/scene.hpp>

namespace broadphase {

/// One frame's pairs and hits.
struct BruteForceFrame {
  FrameDigest pairs;
  HitDigest hits;
};

/// The pairs of `scene`'s objects at their current positions: those that
/// overlap and whose filters pass; in a periodic world every (i, j, S),
/// O(27 n^2), hashed with the shift's code.
FrameDigest brute_force_pairs(const Scene& scene);
/// The hits of `scene`'s rays on its objects at their current positions
/// (no images in a periodic world: rays do not wrap).
HitDigest brute_force_hits(const Scene& scene);

/// Replays a scene by brute force: frame 0 as loaded, each later one after
/// the contract's motion step (`step`).
class BruteForceReplay {
 public:
  explicit BruteForceReplay(Scene scene) : scene_(std::move(scene)) {}
  /// Evaluates the next frame. Throws SceneError naming the frame and the
  /// object when a motion step makes a coordinate non-finite.
  BruteForceFrame next();
  const Scene& scene() const { return scene_; }

 private:
  Scene scene_;
  int frame_ = 0;
};

}  // namespace broadphase
