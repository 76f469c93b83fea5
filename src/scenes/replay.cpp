#include <broadphase/scenes/replay.hpp>
#include <chrono>
#include <string>

namespace broadphase {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

Replay::Replay(AnyBroadPhase& structure, Scene scene) : bp_(structure), scene_(std::move(scene)) {
  handles_.reserve(scene_.size());
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < scene_.size(); ++i) {
    const bool moving = scene_.is_moving(i);
    handles_.push_back(bp_.insert(scene_.objects[i], i, moving ? Motion::dynamic : Motion::fixed,
                                  scene_.filter(i)));
  }
  build_seconds_ = since(t0);
  for (std::size_t i = 0; i < scene_.size(); ++i)
    if (scene_.is_moving(i)) moving_.push_back(static_cast<std::uint32_t>(i));
  moves_.reserve(moving_.size());
}

FrameResult Replay::next() {
  FrameResult r;
  if (frame_ > 0) {
    step(scene_);
    moves_.clear();
    for (std::uint32_t i : moving_) moves_.push_back({handles_[i], scene_.objects[i]});
    const auto t0 = std::chrono::steady_clock::now();
    try {
      bp_.update(moves_);  // checks every move, and changes nothing if one is bad
    } catch (const InvalidShape&) {
      // Only the motion can make a valid scene's shape invalid: name it.
      for (std::uint32_t i : moving_)
        if (!is_valid(scene_.objects[i]))
          throw SceneError("frame " + std::to_string(frame_) + ": object " + std::to_string(i) +
                           " moves beyond the range of doubles (its motion overflows)");
      throw;
    }
    r.update_seconds = since(t0);
  }
  pairs_.clear();
  const auto t1 = std::chrono::steady_clock::now();
  r.tests = bp_.find_pairs(pairs_).tests;
  r.pairs_seconds = since(t1);
  for (const HandlePair& p : pairs_)
    r.digest.add(static_cast<std::uint32_t>(bp_.user_data(p.a)),
                 static_cast<std::uint32_t>(bp_.user_data(p.b)));
  if (!scene_.rays.empty()) {
    const auto t2 = std::chrono::steady_clock::now();
    for (std::size_t k = 0; k < scene_.rays.size(); ++k) {
      RayHits hits(static_cast<std::uint32_t>(k));
      bp_.cast_ray(scene_.rays[k], [&](Handle h, double t) {
        hits.add(static_cast<std::uint32_t>(bp_.user_data(h)), t);
        return kRayGoOn;  // every hit, not only the closest
      });
      hits.add_to(r.hits);
    }
    r.rays_seconds = since(t2);
  }
  ++frame_;
  return r;
}

std::string frame_line(int frame, const FrameResult& r, bool rays) {
  return frame_line(frame, r.digest, rays ? &r.hits : nullptr);
}

}  // namespace broadphase
