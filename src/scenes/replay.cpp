#include <algorithm>
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
  if (scene_.is_periodic()) {
    periodic_ = std::make_unique<PeriodicBroadPhase>(bp_, scene_.cell());
    // The reach of the image rule, once, for the scene's largest objects.
    Vec3 largest{0, 0, 0};
    for (const Shape& s : scene_.objects)
      for (int a = 0; a < 3; ++a) largest[a] = std::max(largest[a], s.half[a]);
    periodic_->reserve_reach(largest);
  }
  for (std::size_t i = 0; i < scene_.size(); ++i) {
    const Motion m = scene_.is_moving(i) ? Motion::dynamic : Motion::fixed;
    handles_.push_back(periodic_ ? periodic_->insert(scene_.objects[i], i, m, scene_.filter(i))
                                 : bp_.insert(scene_.objects[i], i, m, scene_.filter(i)));
  }
  build_seconds_ = since(t0);
  for (std::size_t i = 0; i < scene_.size(); ++i)
    if (scene_.is_moving(i)) moving_.push_back(static_cast<std::uint32_t>(i));
  moves_.reserve(moving_.size());
}

Replay::~Replay() = default;

FrameResult Replay::next() {
  FrameResult r;
  if (frame_ > 0) {
    step(scene_);
    moves_.clear();
    for (std::uint32_t i : moving_) moves_.push_back({handles_[i], scene_.objects[i]});
    const auto t0 = std::chrono::steady_clock::now();
    try {
      // Checks every move, and changes nothing if one is bad.
      if (periodic_)
        periodic_->update(moves_);
      else
        bp_.update(moves_);
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
  const auto t1 = std::chrono::steady_clock::now();
  if (periodic_) {
    periodic_pairs_.clear();
    r.tests = periodic_->find_pairs(periodic_pairs_).tests;
    r.pairs_seconds = since(t1);
    // a is the object with the smaller user data, the id: the contract's i.
    for (const PeriodicPair& p : periodic_pairs_)
      r.digest.add(static_cast<std::uint32_t>(periodic_->user_data(p.a)),
                   static_cast<std::uint32_t>(periodic_->user_data(p.b)), p.shift);
  } else {
    pairs_.clear();
    r.tests = bp_.find_pairs(pairs_).tests;
    r.pairs_seconds = since(t1);
    for (const HandlePair& p : pairs_)
      r.digest.add(static_cast<std::uint32_t>(bp_.user_data(p.a)),
                   static_cast<std::uint32_t>(bp_.user_data(p.b)));
  }
  if (!scene_.rays.empty()) {
    const auto t2 = std::chrono::steady_clock::now();
    for (std::size_t k = 0; k < scene_.rays.size(); ++k) {
      RayHits hits(static_cast<std::uint32_t>(k));
      // A periodic scene's rays see the originals only (rays do not wrap).
      const AnyBroadPhase& bp = bp_;
      auto add = [&](Handle h, double t) {
        hits.add(static_cast<std::uint32_t>(periodic_ ? periodic_->user_data(h) : bp.user_data(h)),
                 t);
        return kRayGoOn;  // every hit, not only the closest
      };
      if (periodic_)
        periodic_->cast_ray(scene_.rays[k], add);
      else
        bp_.cast_ray(scene_.rays[k], add);
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
