// A complete Bullet program on broadphase's broad phase: 216 boxes fall
// onto a plane, a ray looks down through the pile, a ghost object counts
// what it overlaps. The one line that differs from Bullet's own hello-world
// is marked; everything else is Bullet's API.
//
// Build: find_package(broadphase REQUIRED COMPONENTS bullet), link
// broadphase::bullet (float Bullet) or broadphase::bullet_double (Bullet
// built with BT_USE_DOUBLE_PRECISION).
#include <BulletCollision/CollisionDispatch/btGhostObject.h>
#include <btBulletDynamicsCommon.h>

#include <broadphase/bullet.hpp>
#include <cstdio>
#include <memory>
#include <vector>

int main() {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  // The one line: instead of `btDbvtBroadphase broadphase;`
  broadphase::BulletBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
  world.setGravity(btVector3(0, -10, 0));

  btStaticPlaneShape plane_shape(btVector3(0, 1, 0), 0);
  btBoxShape box_shape(btVector3(0.5f, 0.5f, 0.5f));
  std::vector<std::unique_ptr<btDefaultMotionState>> states;
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  auto add = [&](btCollisionShape* shape, btScalar mass, const btVector3& at) {
    btVector3 inertia(0, 0, 0);
    if (mass != 0) shape->calculateLocalInertia(mass, inertia);
    states.push_back(
        std::make_unique<btDefaultMotionState>(btTransform(btQuaternion::getIdentity(), at)));
    bodies.push_back(std::make_unique<btRigidBody>(
        btRigidBody::btRigidBodyConstructionInfo(mass, states.back().get(), shape, inertia)));
    world.addRigidBody(bodies.back().get());
  };
  add(&plane_shape, 0, btVector3(0, 0, 0));
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (int k = 0; k < 6; ++k)
        add(&box_shape, 1,
            btVector3(btScalar(i * 1.1 - 3), btScalar(1 + j * 1.5), btScalar(k * 1.1 - 3)));

  // A sensor: Bullet's ghost object, fed by the pair cache's ghost callback.
  btGhostPairCallback ghost_callback;
  world.getPairCache()->setInternalGhostPairCallback(&ghost_callback);
  btPairCachingGhostObject sensor;
  btBoxShape sensor_shape(btVector3(1, 1, 1));
  sensor.setCollisionShape(&sensor_shape);
  sensor.setCollisionFlags(sensor.getCollisionFlags() | btCollisionObject::CF_NO_CONTACT_RESPONSE);
  sensor.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, 1, 0)));
  world.addCollisionObject(&sensor, btBroadphaseProxy::SensorTrigger,
                           btBroadphaseProxy::AllFilter & ~btBroadphaseProxy::SensorTrigger);

  for (int step = 0; step < 300; ++step) world.stepSimulation(1.0f / 60, 0);

  int resting = 0;
  for (std::size_t i = 1; i < bodies.size(); ++i) {
    const btScalar y = bodies[i]->getWorldTransform().getOrigin().y();
    resting += y > 0 && y < 8;
  }
  btCollisionWorld::ClosestRayResultCallback ray(btVector3(0.2f, 20, 0.3f),
                                                 btVector3(0.2f, -1, 0.3f));
  world.rayTest(ray.m_rayFromWorld, ray.m_rayToWorld, ray);
  std::printf("boxes resting on the plane: %d of %zu\n", resting, bodies.size() - 1);
  std::printf("ray from above hits a box: %s\n",
              ray.hasHit() && ray.m_collisionObject != bodies[0].get() ? "yes" : "no");
  std::printf("sensor overlaps something: %s\n",
              sensor.getNumOverlappingObjects() > 0 ? "yes" : "no");
  world.removeCollisionObject(&sensor);
  for (auto& b : bodies) world.removeRigidBody(b.get());
  return 0;
}
