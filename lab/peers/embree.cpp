// Intel Embree 3 (Debian's libembree-dev, 3.13) as a ray peer: a ray
// tracing kernel with no pairs, so it is not a structure of the registry;
// the ray experiment takes it from ray_peers() (peers/ray_peers.hpp).
//
// Two ways, both on one Embree thread (the device's "threads=1": its scene
// build runs on every core otherwise, and the experiment compares one
// thread with one thread):
//   - `embree`: every object is user geometry: Embree's BVH over our bounds,
//     grown by a margin (below), gives the candidates, and the intersect
//     callback runs the contract's exact double test (`ray_hit`) and clips
//     the ray's tfar to the closest hit. Same answers as ours bit for bit.
//   - `embree-native`: spheres as Embree's own sphere primitive
//     (RTC_GEOMETRY_TYPE_SPHERE_POINT, float centre and radius, its own
//     float hit test), boxes as the user geometry above: Embree's raw speed,
//     whose answers differ from the contract's where float rounding moves a
//     grazing hit or a tie, and for rays starting inside a sphere (Embree
//     reports the exit, the contract t = 0).
//
// Precision: Embree works in float. The float ray deviates from the double
// one by a few float ulps of |origin| + |point|, and its traversal rounds
// the same way, so every user primitive's bounds are grown by 2^-16 (256
// float ulps) of the world's largest coordinate; rays whose origin lies
// beyond that scale, or that float cannot hold, are cast by testing every
// object, as is a world whose objects left it.
//
// Moving objects: their shapes are updated, the geometry committed again
// and the scene rebuilt with rtcCommitScene, which `move` times with the
// rest: a world that moves is made with Embree's advice for dynamic scenes
// (RTC_SCENE_FLAG_DYNAMIC, RTC_BUILD_QUALITY_LOW), a static one with its
// default quality (medium).
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "ray_peers.hpp"

namespace broadphase::app::peers {

namespace {

/// The lab's one Embree device, on one thread.
RTCDevice device() {
  static const std::unique_ptr<RTCDeviceTy, void (*)(RTCDevice)> d(rtcNewDevice("threads=1"),
                                                                   rtcReleaseDevice);
  if (!d) throw std::runtime_error("embree: rtcNewDevice failed");
  return d.get();
}

void check(const char* what) {
  const RTCError e = rtcGetDeviceError(device());
  if (e != RTC_ERROR_NONE)
    throw std::runtime_error(std::string("embree: ") + what + " failed (error " +
                             std::to_string(static_cast<int>(e)) + ")");
}

/// A float tfar that keeps every hit at exactly `t` (ties go to the smaller
/// id): `t` grown by 2^-16 and rounded up.
float tfar_above(double t) {
  const double grown = t * (1 + 0x1p-16);
  if (!(grown < std::numeric_limits<float>::max())) return std::numeric_limits<float>::infinity();
  return std::nextafter(static_cast<float>(grown), std::numeric_limits<float>::infinity());
}

double max_abs(const Vec3& v) { return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}); }

class EmbreeWorld;

/// What the intersect callback needs: Embree hands back the context, so the
/// double ray and the best hit so far ride along behind it.
struct Context {
  RTCIntersectContext base;  // first: the callback casts the pointer back
  const EmbreeWorld* world = nullptr;
  const Ray* ray = nullptr;
  PeerHit best;
};

class EmbreeWorld final : public RayWorld {
 public:
  EmbreeWorld(std::span<const Shape> objects, const Aabb& world, bool moving, bool native)
      : shapes_(objects.begin(), objects.end()), native_(native) {
    scale_ = std::max(max_abs(world.lo), max_abs(world.hi));
    for (const Shape& s : shapes_) {
      const AabbF b = bounds_f(s);
      for (int a = 0; a < 3; ++a)
        scale_ = std::max({scale_, double{std::fabs(b.lo[a])}, double{std::fabs(b.hi[a])}});
    }
    // Room for objects that move a little beyond where they started.
    scale_ *= 2;
    fallback_ = !(scale_ < std::numeric_limits<float>::max() / 4);
    margin_ = static_cast<float>(scale_ * 0x1p-16) + std::numeric_limits<float>::min();
    geom_of_.resize(shapes_.size());
    for (std::uint32_t i = 0; i < shapes_.size(); ++i) {
      const bool sphere = native_ && shapes_[i].kind == ShapeKind::sphere;
      std::vector<std::uint32_t>& ids = sphere ? sphere_ids_ : user_ids_;
      geom_of_[i] = static_cast<std::uint32_t>(ids.size());
      ids.push_back(i);
    }
    scene_ = rtcNewScene(device());
    if (moving) {
      rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC);
      rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_LOW);
    }
    if (!user_ids_.empty()) {
      RTCGeometry g = rtcNewGeometry(device(), RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryUserPrimitiveCount(g, static_cast<unsigned>(user_ids_.size()));
      rtcSetGeometryUserData(g, this);
      rtcSetGeometryBoundsFunction(g, &EmbreeWorld::bounds, this);
      rtcSetGeometryIntersectFunction(g, &EmbreeWorld::intersect);
      if (moving) rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_LOW);
      rtcCommitGeometry(g);
      user_geom_ = g;
      user_geom_id_ = rtcAttachGeometry(scene_, g);
    }
    if (!sphere_ids_.empty()) {
      RTCGeometry g = rtcNewGeometry(device(), RTC_GEOMETRY_TYPE_SPHERE_POINT);
      vertices_ = static_cast<float*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), sphere_ids_.size()));
      for (std::uint32_t k = 0; k < sphere_ids_.size(); ++k) set_vertex(k);
      if (moving) rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_LOW);
      rtcCommitGeometry(g);
      sphere_geom_ = g;
      sphere_geom_id_ = rtcAttachGeometry(scene_, g);
    }
    rtcCommitScene(scene_);
    check("building the scene");
  }
  ~EmbreeWorld() override {
    if (user_geom_ != nullptr) rtcReleaseGeometry(user_geom_);
    if (sphere_geom_ != nullptr) rtcReleaseGeometry(sphere_geom_);
    rtcReleaseScene(scene_);
  }
  EmbreeWorld(const EmbreeWorld&) = delete;
  EmbreeWorld& operator=(const EmbreeWorld&) = delete;

  void move(std::span<const std::uint32_t> ids, std::span<const Shape> shapes) override {
    bool user = false, spheres = false;
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const std::uint32_t i = ids[k];
      shapes_.at(i) = shapes[k];
      const AabbF b = bounds_f(shapes[k]);
      for (int a = 0; a < 3; ++a)
        fallback_ = fallback_ || !(std::fabs(b.lo[a]) <= scale_ && std::fabs(b.hi[a]) <= scale_);
      if (native_ && shapes[k].kind == ShapeKind::sphere) {
        set_vertex(geom_of_[i]);
        spheres = true;
      } else {
        user = true;
      }
    }
    if (user) rtcCommitGeometry(user_geom_);
    if (spheres) {
      rtcUpdateGeometryBuffer(sphere_geom_, RTC_BUFFER_TYPE_VERTEX, 0);
      rtcCommitGeometry(sphere_geom_);
    }
    rtcCommitScene(scene_);
    check("rebuilding the scene");
  }

  PeerHit closest_hit(const Ray& r) override {
    require_valid(r);
    if (fallback_ || !float_ray(r) || !(max_abs(r.origin) <= scale_)) return every_object(r);
    Context c;
    rtcInitIntersectContext(&c.base);
    c.world = this;
    c.ray = &r;
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(r.origin.x);
    rh.ray.org_y = static_cast<float>(r.origin.y);
    rh.ray.org_z = static_cast<float>(r.origin.z);
    rh.ray.dir_x = static_cast<float>(r.dir.x);
    rh.ray.dir_y = static_cast<float>(r.dir.y);
    rh.ray.dir_z = static_cast<float>(r.dir.z);
    rh.ray.tnear = 0;
    rh.ray.tfar = tfar_above(r.tmax);
    rh.ray.mask = 0xffffffffu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &c.base, &rh);
    if (sphere_geom_ != nullptr && rh.hit.geomID == sphere_geom_id_)
      return {sphere_ids_[rh.hit.primID], rh.ray.tfar};
    return c.best;
  }

 private:
  static void bounds(const RTCBoundsFunctionArguments* a) {
    const auto& w = *static_cast<const EmbreeWorld*>(a->geometryUserPtr);
    const AabbF b = bounds_f(w.shapes_[w.user_ids_[a->primID]]);
    RTCBounds& o = *a->bounds_o;
    o.lower_x = b.lo[0] - w.margin_;
    o.lower_y = b.lo[1] - w.margin_;
    o.lower_z = b.lo[2] - w.margin_;
    o.upper_x = b.hi[0] + w.margin_;
    o.upper_y = b.hi[1] + w.margin_;
    o.upper_z = b.hi[2] + w.margin_;
  }

  /// The exact test on a candidate; keeps the closest hit and clips tfar.
  static void intersect(const RTCIntersectFunctionNArguments* a) {
    if (!a->valid[0]) return;
    auto& c = *reinterpret_cast<Context*>(a->context);
    const EmbreeWorld& w = *c.world;
    const std::uint32_t id = w.user_ids_[a->primID];
    RTCRayN* ray = RTCRayHitN_RayN(a->rayhit, a->N);
    // A native sphere hit may have clipped tfar below our best.
    const double tmax = std::min(c.best.id >= 0 ? c.best.t : c.ray->tmax,
                                 static_cast<double>(RTCRayN_tfar(ray, a->N, 0)));
    double t;
    if (!ray_hit(c.ray->origin, c.ray->dir, tmax, w.shapes_[id], t)) return;
    if (c.best.id >= 0 && !(t < c.best.t || id < c.best.id)) return;
    c.best = {id, t};
    RTCRayN_tfar(ray, a->N, 0) = tfar_above(t);
    RTCHitN* hit = RTCRayHitN_HitN(a->rayhit, a->N);
    RTCHitN_geomID(hit, a->N, 0) = a->geomID;
    RTCHitN_primID(hit, a->N, 0) = a->primID;
  }

  void set_vertex(std::uint32_t k) {
    const Shape& s = shapes_[sphere_ids_[k]];
    vertices_[4 * k + 0] = static_cast<float>(s.center.x);
    vertices_[4 * k + 1] = static_cast<float>(s.center.y);
    vertices_[4 * k + 2] = static_cast<float>(s.center.z);
    vertices_[4 * k + 3] = static_cast<float>(s.half.x);
  }

  /// The contract's closest hit by testing every object.
  PeerHit every_object(const Ray& r) const { return closest_by_testing_all(shapes_, r); }

  std::vector<Shape> shapes_;
  bool native_;
  double scale_ = 0;
  float margin_ = 0;
  bool fallback_ = false;
  std::vector<std::uint32_t> user_ids_, sphere_ids_;  // Embree's primID -> our id
  std::vector<std::uint32_t> geom_of_;                // our id -> primID in its geometry
  RTCScene scene_ = nullptr;
  RTCGeometry user_geom_ = nullptr, sphere_geom_ = nullptr;
  unsigned user_geom_id_ = RTC_INVALID_GEOMETRY_ID, sphere_geom_id_ = RTC_INVALID_GEOMETRY_ID;
  float* vertices_ = nullptr;
};

}  // namespace

void add_embree(std::vector<RayPeer>& peers) {
  peers.push_back({"embree",
                   "Intel Embree 3 BVH over user geometry (our bounds grown for float), the exact "
                   "double test in its intersect callback: the contract's answers",
                   true, [](std::span<const Shape> objects, const Aabb& world, bool moving) {
                     return std::unique_ptr<RayWorld>(
                         std::make_unique<EmbreeWorld>(objects, world, moving, false));
                   }});
  peers.push_back({"embree-native",
                   "Intel Embree 3 with spheres as its own float sphere primitive (boxes as user "
                   "geometry): raw speed, float answers",
                   false, [](std::span<const Shape> objects, const Aabb& world, bool moving) {
                     return std::unique_ptr<RayWorld>(
                         std::make_unique<EmbreeWorld>(objects, world, moving, true));
                   }});
}

}  // namespace broadphase::app::peers
