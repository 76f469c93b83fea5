// Bullet worlds built with Bullet's API alone, for the adapter's tests and
// its benchmark: boxes falling onto a plane, a box pyramid, spheres and
// boxes with kinematic movers, bodies in four collision groups, and a
// ghost object sweeping through a pile.
#pragma once

#include <BulletCollision/CollisionDispatch/btGhostObject.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace broadphase::bullet_testing {

/// The kinds of world.
enum class WorldKind { falling, pyramid, mixed, groups, ghost };

inline const char* name_of(WorldKind k) {
  switch (k) {
    case WorldKind::falling:
      return "falling";
    case WorldKind::pyramid:
      return "pyramid";
    case WorldKind::mixed:
      return "mixed";
    case WorldKind::groups:
      return "groups";
    case WorldKind::ghost:
      return "ghost";
  }
  return "?";
}

/// One Bullet world and everything it owns. The broad phase is made by the
/// caller (Bullet's or ours) and owned here.
struct World {
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btBroadphaseInterface> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btDiscreteDynamicsWorld> world;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btDefaultMotionState>> motion_states;
  std::vector<std::unique_ptr<btCollisionObject>> objects;  // bodies and the ghost
  std::vector<btRigidBody*> kinematic;
  btPairCachingGhostObject* ghost = nullptr;
  std::unique_ptr<btGhostPairCallback> ghost_callback;
  int steps_done = 0;

  World() = default;
  World(const World&) = delete;
  World& operator=(const World&) = delete;
  ~World() {
    if (world) {
      for (int i = world->getNumCollisionObjects() - 1; i >= 0; --i)
        world->removeCollisionObject(world->getCollisionObjectArray()[i]);
    }
  }

  btRigidBody* add_body(btCollisionShape* shape, btScalar mass, const btVector3& at, int group = 0,
                        int mask = 0, bool use_filter = false) {
    btVector3 inertia(0, 0, 0);
    if (mass != 0) shape->calculateLocalInertia(mass, inertia);
    btTransform t;
    t.setIdentity();
    t.setOrigin(at);
    motion_states.push_back(std::make_unique<btDefaultMotionState>(t));
    btRigidBody::btRigidBodyConstructionInfo info(mass, motion_states.back().get(), shape, inertia);
    auto body = std::make_unique<btRigidBody>(info);
    btRigidBody* b = body.get();
    objects.push_back(std::move(body));
    if (use_filter) {
      world->addRigidBody(b, group, mask);
    } else {
      world->addRigidBody(b);
    }
    return b;
  }
  btCollisionShape* keep(btCollisionShape* s) {
    shapes.emplace_back(s);
    return s;
  }
  /// One step of 1/60 s (one substep), after moving the kinematic bodies
  /// and the ghost along their paths.
  void step() {
    const double time = steps_done / 60.0;
    for (std::size_t i = 0; i < kinematic.size(); ++i) {
      const double phase = time * 1.5 + static_cast<double>(i) * 1.7;
      btTransform t;
      t.setIdentity();
      const double r = 6 + 2 * static_cast<double>(i);
      t.setOrigin(btVector3(static_cast<btScalar>(r * std::cos(phase)), btScalar(1.5),
                            static_cast<btScalar>(r * std::sin(phase))));
      kinematic[i]->getMotionState()->setWorldTransform(t);
    }
    if (ghost != nullptr) {
      btTransform t;
      t.setIdentity();
      t.setOrigin(btVector3(static_cast<btScalar>(12 * std::sin(time * 0.8)), btScalar(2),
                            static_cast<btScalar>(4 * std::cos(time * 0.5))));
      ghost->setWorldTransform(t);
    }
    world->stepSimulation(btScalar(1) / 60, 0);
    ++steps_done;
  }
};

/// The columns' side for `n` bodies: 10 bodies a column.
inline int columns_side(int n) {
  return std::max(1, static_cast<int>(std::ceil(std::sqrt(n / 10.0))));
}

/// Adds the scene of `kind`, about `n` bodies seeded by `seed`, to the empty
/// world `w` (its `world` made).
inline void populate(World& world, WorldKind kind, int n, std::uint64_t seed) {
  World* w = &world;
  w->world->setGravity(btVector3(0, -10, 0));
  std::mt19937_64 rng(seed);
  auto uniform = [&](double lo, double hi) {
    return static_cast<btScalar>(lo + (hi - lo) * (static_cast<double>(rng() >> 11) * 0x1p-53));
  };
  btCollisionShape* plane = w->keep(new btStaticPlaneShape(btVector3(0, 1, 0), 0));
  w->add_body(plane, 0, btVector3(0, 0, 0));
  btCollisionShape* box =
      w->keep(new btBoxShape(btVector3(btScalar(0.5), btScalar(0.5), btScalar(0.5))));
  btCollisionShape* sphere = w->keep(new btSphereShape(btScalar(0.5)));
  const int side = columns_side(n);
  switch (kind) {
    case WorldKind::falling:
    case WorldKind::groups:
    case WorldKind::ghost: {
      // Columns of boxes over a square, 10 high, each jittered a little so
      // that the pile is not a lattice.
      for (int i = 0; i < n; ++i) {
        const int col = i % (side * side);
        const int level = i / (side * side);
        const btVector3 at(
            static_cast<btScalar>((col % side) * 1.2 - side * 0.6) + uniform(-0.1, 0.1),
            static_cast<btScalar>(1 + level * 1.3) + uniform(0, 0.2),
            static_cast<btScalar>((col / side) * 1.2 - side * 0.6) + uniform(-0.1, 0.1));
        if (kind == WorldKind::groups) {
          // Group k pairs with k, k+1 and k-1 (mod 4) and with the static
          // plane, not with k+2: neighbours along z (and diagonal ones
          // across levels) fall through each other.
          const int k = ((col % side) + 2 * (col / side) + level) % 4;
          const int group = 1 << (k + 6);
          const int mask = (1 << (k + 6)) | (1 << (((k + 1) % 4) + 6)) |
                           (1 << (((k + 3) % 4) + 6)) | btBroadphaseProxy::StaticFilter;
          w->add_body(box, 1, at, group, mask, true);
        } else {
          w->add_body(box, 1, at);
        }
      }
      if (kind == WorldKind::ghost) {
        w->ghost_callback = std::make_unique<btGhostPairCallback>();
        w->world->getPairCache()->setInternalGhostPairCallback(w->ghost_callback.get());
        auto ghost = std::make_unique<btPairCachingGhostObject>();
        ghost->setCollisionShape(w->keep(new btBoxShape(btVector3(2, 2, 2))));
        ghost->setCollisionFlags(ghost->getCollisionFlags() |
                                 btCollisionObject::CF_NO_CONTACT_RESPONSE);
        w->ghost = ghost.get();
        w->world->addCollisionObject(
            ghost.get(), btBroadphaseProxy::SensorTrigger,
            btBroadphaseProxy::AllFilter & ~btBroadphaseProxy::SensorTrigger);
        w->objects.push_back(std::move(ghost));
      }
      break;
    }
    case WorldKind::pyramid: {
      // Square layers, each one box narrower, touching.
      int placed = 0;
      int base = 1;
      while (base * (base + 1) * (2 * base + 1) / 6 < n) ++base;
      for (int layer = 0; layer < base && placed < n; ++layer) {
        const int width = base - layer;
        for (int i = 0; i < width && placed < n; ++i)
          for (int j = 0; j < width && placed < n; ++j, ++placed)
            w->add_body(box, 1,
                        btVector3(static_cast<btScalar>(i - width * 0.5 + 0.5),
                                  static_cast<btScalar>(0.5 + layer),
                                  static_cast<btScalar>(j - width * 0.5 + 0.5)));
      }
      break;
    }
    case WorldKind::mixed: {
      for (int i = 0; i < n; ++i) {
        const btVector3 at(uniform(-10, 10), uniform(1, 12), uniform(-10, 10));
        w->add_body(i % 2 == 0 ? sphere : box, 1, at);
      }
      btCollisionShape* mover = w->keep(new btBoxShape(btVector3(1, btScalar(1.5), 1)));
      for (int i = 0; i < 4; ++i) {
        // Where step() puts it at time 0: the movers never coincide.
        const double phase = i * 1.7, r = 6 + 2 * i;
        btRigidBody* k =
            w->add_body(mover, 0,
                        btVector3(static_cast<btScalar>(r * std::cos(phase)), btScalar(1.5),
                                  static_cast<btScalar>(r * std::sin(phase))));
        k->setCollisionFlags(k->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
        k->setActivationState(DISABLE_DEACTIVATION);
        w->kinematic.push_back(k);
      }
      break;
    }
  }
}

/// A box around everything a world of `kind` with `n` bodies holds while
/// it runs (for btAxisSweep3's quantisation).
inline void world_box(WorldKind kind, int n, btVector3& lo, btVector3& hi) {
  const btScalar half = static_cast<btScalar>(columns_side(n) * 0.6 + 20);
  const btScalar top =
      static_cast<btScalar>(kind == WorldKind::pyramid ? columns_side(n) * 3 + 20 : 40);
  lo = btVector3(-half, -10, -half);
  hi = btVector3(half, top, half);
}

/// Makes a world of `kind` with about `n` bodies, seeded by `seed`, over the
/// broad phase `broadphase` (taken over).
inline std::unique_ptr<World> make_world(WorldKind kind, int n, std::uint64_t seed,
                                         btBroadphaseInterface* broadphase) {
  auto w = std::make_unique<World>();
  w->config = std::make_unique<btDefaultCollisionConfiguration>();
  w->dispatcher = std::make_unique<btCollisionDispatcher>(w->config.get());
  w->broadphase.reset(broadphase);
  w->solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  w->world = std::make_unique<btDiscreteDynamicsWorld>(w->dispatcher.get(), w->broadphase.get(),
                                                       w->solver.get(), w->config.get());
  populate(*w, kind, n, seed);
  return w;
}

}  // namespace broadphase::bullet_testing
