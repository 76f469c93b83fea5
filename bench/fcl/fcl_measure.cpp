#include "fcl_measure.hpp"

#include <fcl/broadphase/broadphase_SaP.h>
#include <fcl/broadphase/broadphase_bruteforce.h>
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/broadphase/broadphase_spatialhash.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/sphere.h>

#include <algorithm>
#include <broadphase/detail/thread_clock.hpp>
#include <broadphase/fcl.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace broadphase::engines {

namespace {

// The calling thread's CPU time, not the wall clock: on a 2-core host shared
// with other builds (load 20 and more) a wall-clock interval mostly measured
// the other processes' time slices; every manager here runs on the calling
// thread alone (grid-verlet with its default threads=1).
using Clock = broadphase::detail::ThreadClock;
double ms_since(double t0) { return broadphase::detail::thread_ms_since(t0); }

// Counts the pairs whose AABBs overlap: FCL's spatial hash hands the
// callback every pair sharing a cell without that test (docs/fcl.md), so a
// narrow phase behind it would test them first; every manager pays it here.
bool count_pair(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
  if (a->getAABB().overlap(b->getAABB())) ++*static_cast<std::size_t*>(data);
  return false;
}

// Collects the pairs in the order a manager hands them out.
using ObjectPairs = std::vector<std::pair<fcl::CollisionObjectd*, fcl::CollisionObjectd*>>;
bool collect_pair(fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
  static_cast<ObjectPairs*>(data)->emplace_back(a, b);
  return false;
}

struct Contender {
  FclManagerRun run;
  std::unique_ptr<fcl::BroadPhaseCollisionManagerd> manager;
};

}  // namespace

FclSizeRun measure_fcl(const FclPlan& plan) {
  if (plan.n < 1 || plan.frames < 1 || plan.warm < 0)
    throw std::invalid_argument("the FCL comparison needs at least one object and one frame");
  const std::string structure =
      plan.structure.empty() ? std::string(kFclDefaultStructure) : plan.structure;
  const std::size_t n = plan.n;
  Scene scene = generate(Distribution::scaled_even, n, plan.seed);
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
  auto add = [&cs](std::string name, std::unique_ptr<fcl::BroadPhaseCollisionManagerd> m) {
    Contender c;
    c.run.name = std::move(name);
    c.manager = std::move(m);
    cs.push_back(std::move(c));
  };
  add("broadphase (" + structure + ")",
      std::make_unique<FclCollisionManagerd>(
          structure, Config{.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}},
                            .expected_objects = n,
                            .options = {}}));
  if (plan.tree)
    add("fcl DynamicAABBTree", std::make_unique<fcl::DynamicAABBTreeCollisionManagerd>());
  if (plan.sap) add("fcl SaP", std::make_unique<fcl::SaPCollisionManagerd>());
  // The lab's cell for FCL's hash (lab/peers/fcl.cpp): the world's side over
  // the cube root of the object count, the table as large as the count.
  const double cell = scene.world / std::cbrt(static_cast<double>(n));
  if (plan.hash)
    add("fcl SpatialHashing",
        std::make_unique<fcl::SpatialHashingCollisionManager<double>>(
            cell, fcl::Vector3d(0, 0, 0), fcl::Vector3d(scene.world, scene.world, scene.world),
            static_cast<unsigned>(std::max<std::size_t>(n, 1000))));
  if (plan.naive) add("fcl Naive", std::make_unique<fcl::NaiveCollisionManagerd>());
  for (Contender& c : cs) {
    const auto t = Clock::now();
    c.manager->registerObjects(all);
    c.manager->setup();
    c.run.register_ms = ms_since(t);
  }

  FclSizeRun out;
  out.n = n;
  out.movers = movers.size();
  out.world = scene.world;
  for (int f = 0; f < plan.warm + plan.frames; ++f) {
    step(scene);
    for (std::size_t i = 0; i < scene.size(); ++i) {
      if (!scene.is_moving(i)) continue;
      const Vec3& c = scene.objects[i].center;
      objects[i]->setTranslation(fcl::Vector3d(c.x, c.y, c.z));
      objects[i]->computeAABB();
    }
    std::vector<std::size_t> pairs(cs.size());
    for (std::size_t k = 0; k < cs.size(); ++k) {
      const std::size_t at = (k + static_cast<std::size_t>(f)) % cs.size();
      Contender& c = cs[at];
      const auto t0 = Clock::now();
      c.manager->update(movers);
      const double u = ms_since(t0);
      const auto t1 = Clock::now();
      c.manager->collide(&pairs[at], count_pair);
      const double col = ms_since(t1);
      if (f >= plan.warm) {
        c.run.update_ms.push_back(u);
        c.run.collide_ms.push_back(col);
        c.run.total_ms.push_back(u + col);
        // The callback alone on the same pairs in the same order.
        ObjectPairs got;
        got.reserve(pairs[at] * 2 + 16);
        c.manager->collide(&got, collect_pair);
        std::size_t counted = 0;
        const auto t2 = Clock::now();
        for (const auto& [a, b] : got) count_pair(a, b, &counted);
        c.run.callback_ms.push_back(ms_since(t2));
        if (counted != pairs[at])
          throw std::runtime_error("n = " + std::to_string(n) + ", frame " + std::to_string(f) +
                                   ": " + c.run.name + " counted " + std::to_string(counted) +
                                   " pairs on its second pass, " + std::to_string(pairs[at]) +
                                   " on its first");
      }
    }
    for (std::size_t k = 1; k < cs.size(); ++k)
      if (pairs[k] != pairs[0])
        throw std::runtime_error("n = " + std::to_string(n) + ", frame " + std::to_string(f) +
                                 ": " + cs[k].run.name + " found " + std::to_string(pairs[k]) +
                                 " pairs, " + cs[0].run.name + " " + std::to_string(pairs[0]));
    if (f == plan.warm) out.pairs = pairs[0];
  }
  for (Contender& c : cs) {
    c.manager->clear();
    out.managers.push_back(std::move(c.run));
  }
  return out;
}

}  // namespace broadphase::engines
