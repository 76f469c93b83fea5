// Compiled once per side, with -DSIDE=A or B, -Dbroadphase=bpA or bpB and
// that side's include directory (ab.sh).
#include "runner.hpp"

#include <broadphase/registry.hpp>
// The scene headers where the side has them: scenes/, or lab/ in a commit
// from before they were named so, or the top level before that.
#if __has_include(<broadphase/scenes/replay.hpp>)
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#elif __has_include(<broadphase/lab/replay.hpp>)
#include <broadphase/lab/replay.hpp>
#include <broadphase/lab/scene.hpp>
#else
#include <broadphase/replay.hpp>
#include <broadphase/scene.hpp>
#endif

#define AB_CAT2(a, b) a##b
#define AB_CAT(a, b) AB_CAT2(a, b)

namespace {

struct Replayed : Runner {
  std::unique_ptr<broadphase::AnyBroadPhase> structure;
  std::unique_ptr<broadphase::Replay> replay;
  std::uint64_t last = 0;

  Replayed(const std::string& path, const std::string& spec) {
    const broadphase::Scene scene = broadphase::read_scene(path);
    broadphase::Config config;
    config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    config.expected_objects = scene.size();
    structure = broadphase::make_structure(spec, config);
    replay = std::make_unique<broadphase::Replay>(*structure, scene);
  }
  double frame() override {
    const broadphase::FrameResult r = replay->next();
    last = r.digest.hash;
    return r.seconds() * 1e3;
  }
  std::uint64_t hash() const override { return last; }
};

}  // namespace

std::unique_ptr<Runner> AB_CAT(make_runner_, SIDE)(const std::string& scene,
                                                   const std::string& spec) {
  return std::make_unique<Replayed>(scene, spec);
}
