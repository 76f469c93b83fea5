// broadphase::FclCollisionManager against FCL's own managers, side by side in
// one process: the same FCL objects registered in every manager, moved once
// per frame, then each manager's update(moved objects) and collide(callback)
// timed in turn (the order rotating each frame, so that a busy neighbour on
// a shared host does not always hit the same one). The world is the study's
// scaled-even scene (docs/scene-format.md: density 6400 objects per km^3,
// radii 0.5 to 50, a fifth moving at 0.1 to 2 per frame) with every other
// sphere made a box of the same half side. Every manager's pair count is
// checked against the others every frame.
//
//   fcl_bench [--sizes 1000,10000,100000] [--frames 10] [--seed 1]
//             [--structure grid-verlet] [--skip-sap-above N] [--skip-hash-above N]
#include <fcl/broadphase/broadphase_SaP.h>
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/broadphase/broadphase_spatialhash.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/sphere.h>
#include <time.h>

#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <broadphase/detail/thread_clock.hpp>
#include <broadphase/fcl.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace {

// The calling thread's CPU time, not the wall clock: on a 2-core host shared
// with other builds (load 20 and more) a wall-clock interval mostly measured
// the other processes' time slices; every manager here runs on the calling
// thread alone (grid-verlet with its default threads=1).
using Clock = broadphase::detail::ThreadClock;
double ms_since(double t0) { return broadphase::detail::thread_ms_since(t0); }

using broadphase::detail::median;

// Counts the pairs whose AABBs overlap: FCL's spatial hash hands the
// callback every pair sharing a cell without that test (docs/fcl.md), so a
// narrow phase behind it would test them first; every manager pays it here.
bool count_pair(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
  if (a->getAABB().overlap(b->getAABB())) ++*static_cast<std::size_t*>(data);
  return false;
}

struct Contender {
  Contender(std::string n, std::unique_ptr<fcl::BroadPhaseCollisionManagerd> m)
      : name(std::move(n)), manager(std::move(m)) {}
  std::string name;
  std::unique_ptr<fcl::BroadPhaseCollisionManagerd> manager;
  double register_ms = 0;
  std::vector<double> update_ms, collide_ms, total_ms;
};

std::vector<std::size_t> parse_sizes(const std::string& text) {
  std::vector<std::size_t> sizes;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || v == 0 || v > 10000000)
      throw std::invalid_argument("--sizes: '" + item + "' is not a count in [1, 10^7]");
    sizes.push_back(static_cast<std::size_t>(v));
  }
  return sizes;
}

int positive(const char* flag, const char* text) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (*text == '\0' || *end != '\0' || v < 1 || v > 100000)
    throw std::invalid_argument(std::string(flag) + ": '" + text + "' is not in [1, 100000]");
  return static_cast<int>(v);
}

void run(std::size_t n, int frames, std::uint64_t seed, const std::string& structure,
         std::size_t skip_sap_above, std::size_t skip_hash_above) {
  using namespace broadphase;
  Scene scene = generate(Distribution::scaled_even, n, seed);
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  std::vector<fcl::CollisionObjectd*> all, movers;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const Shape& s = scene.objects[i];
    std::shared_ptr<fcl::CollisionGeometryd> g;
    if (i % 2 == 0)
      g = std::make_shared<fcl::Sphered>(s.radius());
    else
      g = std::make_shared<fcl::Boxd>(2 * s.half.x, 2 * s.half.y, 2 * s.half.z);
    auto o = std::make_unique<fcl::CollisionObjectd>(g);
    o->setTranslation(fcl::Vector3d(s.center.x, s.center.y, s.center.z));
    o->computeAABB();
    all.push_back(o.get());
    if (scene.is_moving(i)) movers.push_back(o.get());
    objects.push_back(std::move(o));
  }

  std::vector<Contender> cs;
  cs.emplace_back(
      "broadphase (" + structure + ")",
      std::make_unique<FclCollisionManagerd>(
          structure, Config{.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}},
                            .expected_objects = n,
                            .options = {}}));
  cs.emplace_back("fcl DynamicAABBTree", std::make_unique<fcl::DynamicAABBTreeCollisionManagerd>());
  if (n <= skip_sap_above)
    cs.emplace_back("fcl SaP", std::make_unique<fcl::SaPCollisionManagerd>());
  // The lab's cell for FCL's hash (lab/peers/fcl.cpp): the world's side over
  // the cube root of the object count, the table as large as the count.
  const double cell = scene.world / std::cbrt(static_cast<double>(n));
  if (n <= skip_hash_above)
    cs.emplace_back(
        "fcl SpatialHashing",
        std::make_unique<fcl::SpatialHashingCollisionManager<double>>(
            cell, fcl::Vector3d(0, 0, 0), fcl::Vector3d(scene.world, scene.world, scene.world),
            static_cast<unsigned>(std::max<std::size_t>(n, 1000))));
  for (Contender& c : cs) {
    const auto t = Clock::now();
    c.manager->registerObjects(all);
    c.manager->setup();
    c.register_ms = ms_since(t);
  }

  const int warm = 2;
  for (int f = 0; f < warm + frames; ++f) {
    step(scene);
    for (std::size_t i = 0; i < scene.size(); ++i) {
      if (!scene.is_moving(i)) continue;
      const Vec3& c = scene.objects[i].center;
      objects[i]->setTranslation(fcl::Vector3d(c.x, c.y, c.z));
      objects[i]->computeAABB();
    }
    std::vector<std::size_t> pairs(cs.size());
    for (std::size_t k = 0; k < cs.size(); ++k) {
      Contender& c = cs[(k + static_cast<std::size_t>(f)) % cs.size()];
      std::size_t& count = pairs[(k + static_cast<std::size_t>(f)) % cs.size()];
      const auto t0 = Clock::now();
      c.manager->update(movers);
      const double u = ms_since(t0);
      const auto t1 = Clock::now();
      c.manager->collide(&count, count_pair);
      const double col = ms_since(t1);
      if (f >= warm) {
        c.update_ms.push_back(u);
        c.collide_ms.push_back(col);
        c.total_ms.push_back(u + col);
      }
    }
    for (std::size_t k = 1; k < cs.size(); ++k)
      if (pairs[k] != pairs[0]) {
        std::fprintf(stderr, "fcl_bench: frame %d: %s found %zu pairs, %s %zu\n", f,
                     cs[k].name.c_str(), pairs[k], cs[0].name.c_str(), pairs[0]);
        std::exit(1);
      }
    if (f == warm)
      std::printf("n=%zu world %.1f: %zu movers, %zu pairs per frame (all managers agree)\n", n,
                  scene.world, movers.size(), pairs[0]);
  }
  const double ours = median(cs[0].total_ms);
  std::printf("%-34s %11s %10s %11s %12s %12s\n", "manager", "register ms", "update ms",
              "collide ms", "upd+col ms", "vs ours");
  for (const Contender& c : cs)
    std::printf("%-34s %11.2f %10.3f %11.3f %12.3f %11.2fx\n", c.name.c_str(), c.register_ms,
                median(c.update_ms), median(c.collide_ms), median(c.total_ms),
                median(c.total_ms) / ours);
  std::printf("\n");
  for (Contender& c : cs) c.manager->clear();
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::vector<std::size_t> sizes{1000, 10000, 100000};
    int frames = 10;
    std::uint64_t seed = 1;
    std::string structure(broadphase::kFclDefaultStructure);
    std::size_t skip_sap_above = 10000000, skip_hash_above = 10000000;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (i + 1 >= argc) throw std::invalid_argument(a + ": missing value (or unknown option)");
      const char* v = argv[++i];
      if (a == "--sizes")
        sizes = parse_sizes(v);
      else if (a == "--frames")
        frames = positive("--frames", v);
      else if (a == "--seed")
        seed = static_cast<std::uint64_t>(positive("--seed", v));
      else if (a == "--structure")
        structure = v;
      else if (a == "--skip-sap-above")
        skip_sap_above = static_cast<std::size_t>(positive("--skip-sap-above", v));
      else if (a == "--skip-hash-above")
        skip_hash_above = static_cast<std::size_t>(positive("--skip-hash-above", v));
      else
        throw std::invalid_argument("unknown option '" + a + "'");
    }
    std::printf(
        "fcl_bench: %d frames after 2 warm-up frames, medians of thread CPU time; seed %llu\n\n",
        frames, static_cast<unsigned long long>(seed));
    for (std::size_t n : sizes) run(n, frames, seed, structure, skip_sap_above, skip_hash_above);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fcl_bench: %s\n", e.what());
    return 2;
  }
  return 0;
}
