// The oracle: docs/scene-format.md's overlap, filter and ray evaluations,
// and its periodic pairs, written out here as the contract states them (double, left to right, no
// fused multiply-add: the target compiles with -ffp-contract=off).
#include <broadphase/scenes/brute_force.hpp>
#include <cmath>
#include <string>

namespace broadphase {

namespace {

bool spheres_overlap(const Shape& a, const Shape& b) {
  const double dx = a.center.x - b.center.x;
  const double dy = a.center.y - b.center.y;
  const double dz = a.center.z - b.center.z;
  const double d2 = dx * dx + dy * dy + dz * dz;
  const double s = a.half.x + b.half.x;
  return d2 <= s * s;
}

bool boxes_overlap(const Shape& a, const Shape& b) {
  return std::fabs(a.center.x - b.center.x) <= a.half.x + b.half.x &&
         std::fabs(a.center.y - b.center.y) <= a.half.y + b.half.y &&
         std::fabs(a.center.z - b.center.z) <= a.half.z + b.half.z;
}

bool sphere_box_overlap(const Shape& sphere, const Shape& box) {
  double d2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double e = std::fabs(sphere.center[a] - box.center[a]) - box.half[a];
    d2 += e > 0 ? e * e : 0;
  }
  const double r = sphere.half.x;
  return d2 <= r * r;
}

bool overlap(const Shape& a, const Shape& b) {
  if (a.kind == ShapeKind::sphere && b.kind == ShapeKind::sphere) return spheres_overlap(a, b);
  if (a.kind == ShapeKind::box && b.kind == ShapeKind::box) return boxes_overlap(a, b);
  return a.kind == ShapeKind::sphere ? sphere_box_overlap(a, b) : sphere_box_overlap(b, a);
}

bool sphere_hit(const Ray& ray, const Shape& s, double& t) {
  const Vec3& o = ray.origin;
  const Vec3& d = ray.dir;
  const double r = s.half.x;
  const double mx = o.x - s.center.x;
  const double my = o.y - s.center.y;
  const double mz = o.z - s.center.z;
  const double c2 = (mx * mx + my * my + mz * mz) - r * r;
  if (c2 <= 0) {
    t = 0;
    return true;
  }
  const double b = mx * d.x + my * d.y + mz * d.z;
  if (!(b < 0)) return false;
  const double a = d.x * d.x + d.y * d.y + d.z * d.z;
  const double f = b / a;
  const double qx = mx - f * d.x;
  const double qy = my - f * d.y;
  const double qz = mz - f * d.z;
  const double h2 = r * r - (qx * qx + qy * qy + qz * qz);
  if (!(h2 >= 0)) return false;
  t = -f - std::sqrt(h2 / a);
  if (t < 0) t = 0;
  return t <= ray.tmax;
}

bool box_hit(const Ray& ray, const Shape& s, double& t) {
  double tn = 0;
  double tf = ray.tmax;
  for (int a = 0; a < 3; ++a) {
    const double lo = (s.center[a] - s.half[a]) - ray.origin[a];
    const double hi = (s.center[a] + s.half[a]) - ray.origin[a];
    const double da = ray.dir[a];
    if (da == 0) {
      if (lo > 0 || hi < 0) return false;
      continue;
    }
    double t1 = lo / da;
    double t2 = hi / da;
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > tn) tn = t1;
    if (t2 < tf) tf = t2;
  }
  t = tn;
  return tn <= tf;
}

}  // namespace

namespace {

// A periodic world: every shift S in {-1, 0, 1}^3 (0 on the axes that are
// not periodic) of every pair, j's centre moved by S·L in double.
FrameDigest brute_force_periodic_pairs(const Scene& scene) {
  FrameDigest d;
  const std::size_t n = scene.size();
  const double L = scene.world;
  int lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = scene.periodic[a] ? -1 : 0;
    hi[a] = scene.periodic[a] ? 1 : 0;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Filter fi = scene.filter(i);
    for (std::size_t j = i + 1; j < n; ++j) {
      const Filter fj = scene.filter(j);
      if ((fi.group & fj.mask) == 0 || (fj.group & fi.mask) == 0) continue;
      for (int sz = lo[2]; sz <= hi[2]; ++sz)
        for (int sy = lo[1]; sy <= hi[1]; ++sy)
          for (int sx = lo[0]; sx <= hi[0]; ++sx) {
            Shape moved = scene.objects[j];
            moved.center.x = moved.center.x + sx * L;
            moved.center.y = moved.center.y + sy * L;
            moved.center.z = moved.center.z + sz * L;
            if (!overlap(scene.objects[i], moved)) continue;
            const std::uint64_t key = (std::uint64_t(i) << 32) | j;
            ++d.pairs;
            d.hash += sx == 0 && sy == 0 && sz == 0
                          ? splitmix64(key)
                          : splitmix64(splitmix64(key) ^
                                       std::uint64_t((sx + 1) + 3 * (sy + 1) + 9 * (sz + 1)));
          }
    }
  }
  return d;
}

}  // namespace

FrameDigest brute_force_pairs(const Scene& scene) {
  if (scene.is_periodic()) return brute_force_periodic_pairs(scene);
  FrameDigest d;
  const std::size_t n = scene.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Filter fi = scene.filter(i);
    for (std::size_t j = i + 1; j < n; ++j) {
      const Filter fj = scene.filter(j);
      if ((fi.group & fj.mask) == 0 || (fj.group & fi.mask) == 0) continue;
      if (overlap(scene.objects[i], scene.objects[j]))
        d.add(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j));
    }
  }
  return d;
}

HitDigest brute_force_hits(const Scene& scene) {
  HitDigest d;
  for (std::size_t k = 0; k < scene.rays.size(); ++k) {
    const Ray& ray = scene.rays[k];
    RayHits hits(static_cast<std::uint32_t>(k));
    for (std::size_t i = 0; i < scene.size(); ++i) {
      if ((scene.filter(i).group & ray.mask) == 0) continue;
      const Shape& s = scene.objects[i];
      double t = 0;
      if (s.kind == ShapeKind::sphere ? sphere_hit(ray, s, t) : box_hit(ray, s, t))
        hits.add(static_cast<std::uint32_t>(i), t);
    }
    hits.add_to(d);
  }
  return d;
}

BruteForceFrame BruteForceReplay::next() {
  if (frame_ > 0) {
    step(scene_);
    for (std::size_t i = 0; i < scene_.size(); ++i) {
      const Vec3& c = scene_.objects[i].center;
      if (!(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z)))
        throw SceneError("frame " + std::to_string(frame_) + ": object " + std::to_string(i) +
                         " moves beyond the range of doubles (its motion overflows)");
    }
  }
  ++frame_;
  return {brute_force_pairs(scene_), brute_force_hits(scene_)};
}

}  // namespace broadphase
