// An FCL program whose broad phase is one of broadphase's structures: boxes
// and spheres in a room, a tenth of them moving each step, collided and
// measured through FCL's own callbacks. The only line that differs from the
// same program on FCL's dynamic AABB tree is the one that makes the manager.
// With an argument `fcl` it runs on FCL's tree instead and prints the same.
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/broadphase/default_broadphase_callbacks.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/sphere.h>

#include <broadphase/fcl.hpp>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

int main(int argc, char** argv) {
  const bool fcl_tree = argc > 1 && std::strcmp(argv[1], "fcl") == 0;
  std::unique_ptr<fcl::BroadPhaseCollisionManagerd> manager;
  if (fcl_tree)
    manager = std::make_unique<fcl::DynamicAABBTreeCollisionManagerd>();
  else
    manager = std::make_unique<broadphase::FclCollisionManagerd>();  // the one-line change

  // 1 000 objects on a jittered lattice: boxes and spheres alternately.
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  for (int i = 0; i < 1000; ++i) {
    std::shared_ptr<fcl::CollisionGeometryd> shape;
    if (i % 2 == 0)
      shape = std::make_shared<fcl::Boxd>(1.0, 0.5 + (i % 3) * 0.25, 0.8);
    else
      shape = std::make_shared<fcl::Sphered>(0.3 + (i % 5) * 0.1);
    auto o = std::make_unique<fcl::CollisionObjectd>(shape);
    o->setTranslation(fcl::Vector3d(i % 10 * 1.5 + (i % 7) * 0.05, i / 10 % 10 * 1.5,
                                    i / 100 * 1.5 + (i % 3) * 0.1));
    o->computeAABB();
    objects.push_back(std::move(o));
  }
  std::vector<fcl::CollisionObjectd*> pointers;
  for (auto& o : objects) pointers.push_back(o.get());
  manager->registerObjects(pointers);
  manager->setup();

  for (int step = 0; step < 5; ++step) {
    // Move every tenth object, then tell the manager (FCL's usual loop).
    std::vector<fcl::CollisionObjectd*> moved;
    for (std::size_t i = static_cast<std::size_t>(step); i < objects.size(); i += 10) {
      fcl::CollisionObjectd& o = *objects[i];
      o.setTranslation(o.getTranslation() + fcl::Vector3d(0.1, 0.05 * step, -0.07));
      o.computeAABB();
      moved.push_back(&o);
    }
    manager->update(moved);

    // Every pair in contact, with FCL's default callback.
    fcl::DefaultCollisionData<double> collision;
    collision.request.num_max_contacts = 100000;
    manager->collide(&collision, fcl::DefaultCollisionFunction<double>);
    std::printf("step %d: %zu contacts\n", step, collision.result.numContacts());
  }

  // The nearest object to a probe outside the lattice, and whether the
  // probe touches anything.
  fcl::CollisionObjectd probe(std::make_shared<fcl::Sphered>(0.5));
  probe.setTranslation(fcl::Vector3d(-3, 2, 2));
  probe.computeAABB();
  fcl::DefaultDistanceData<double> nearest;
  manager->distance(&probe, &nearest, fcl::DefaultDistanceFunction<double>);
  std::printf("probe: nearest object at %.6f\n", nearest.result.min_distance);
  return 0;
}
