// Rays per second of the lean path's RayCaster (arrays/rays.hpp) against the
// k-d tree, both on one thread, on a generated scene's spheres as the
// caller's arrays, with random rays (origins uniform in the world,
// directions uniform, no tmax): the closest hit of each. Checks that both
// report the same closest hits (index and t bit for bit).
//
//   rays_bench [DIST] [N] [RAYS] [--seed S] [--repeats K]
//
// Defaults: scaled-even, 100 000 spheres, 100 000 rays, 3 repeats
// alternated; prints each build and batch time and the medians.
#include <algorithm>
#include <bit>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/arrays/rays.hpp>
#include <broadphase/rays.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using namespace broadphase;  // NOLINT(google-build-using-namespace)
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::string dist = "scaled-even";
  std::size_t n = 100000, ray_count = 100000;
  std::uint64_t seed = 1;
  int repeats = 3;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seed" && i + 1 < argc) {
      seed = std::stoull(argv[++i]);
    } else if (a == "--repeats" && i + 1 < argc) {
      repeats = std::max(1, std::atoi(argv[++i]));
    } else if (positional == 0) {
      dist = a;
      ++positional;
    } else if (positional == 1) {
      n = std::stoull(a);
      ++positional;
    } else if (positional == 2) {
      ray_count = std::stoull(a);
      ++positional;
    } else {
      std::fprintf(stderr, "rays_bench: unexpected argument '%s'\n", a.c_str());
      return 2;
    }
  }
  const Scene scene = generate(parse_distribution(dist), n, seed);
  std::vector<double> xyz, radius;
  for (const Shape& s : scene.objects) {
    xyz.insert(xyz.end(), {s.center.x, s.center.y, s.center.z});
    radius.push_back(s.half.x);
  }
  const arrays::Objects objects = arrays::Objects::spheres(xyz.data(), radius.data(), n);
  Rng rng(seed * 7 + 1);
  std::vector<Ray> rays(ray_count);
  for (Ray& r : rays) {
    r.origin = {rng.uniform(0, scene.world), rng.uniform(0, scene.world),
                rng.uniform(0, scene.world)};
    r.dir = rng.direction();
  }

  std::vector<double> lean_build, lean_cast, tree_build, tree_cast;
  std::vector<arrays::IndexHit> lean(ray_count);
  std::vector<RayHit> tree(ray_count);
  std::size_t memory_lean = 0, memory_tree = 0;
  for (int k = 0; k < repeats; ++k) {
    auto t0 = Clock::now();
    arrays::RayCaster caster(objects);
    lean_build.push_back(ms_since(t0));
    t0 = Clock::now();
    caster.closest(rays, lean, 1);
    lean_cast.push_back(ms_since(t0));
    memory_lean = caster.memory_bytes();

    Config config;
    config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    config.expected_objects = n;
    t0 = Clock::now();
    auto kd = make_structure("kdtree", config);
    for (std::size_t i = 0; i < n; ++i) kd->insert(scene.objects[i], i, Motion::fixed);
    kd->settle();
    tree_build.push_back(ms_since(t0));
    t0 = Clock::now();
    cast_rays(*kd, rays, tree, 1);
    tree_cast.push_back(ms_since(t0));
    memory_tree = kd->memory_bytes();
    std::printf("repeat %d: lean build %.1f ms, cast %.1f ms; kdtree build %.1f ms, cast %.1f ms\n",
                k, lean_build.back(), lean_cast.back(), tree_build.back(), tree_cast.back());
    for (std::size_t r = 0; r < ray_count; ++r) {
      const bool th = !tree[r].handle.is_null();
      const std::uint32_t ti = th ? static_cast<std::uint32_t>(kd->user_data(tree[r].handle)) : 0;
      if (th != lean[r].hit() ||
          (th && (ti != lean[r].index || std::bit_cast<std::uint64_t>(tree[r].t) !=
                                             std::bit_cast<std::uint64_t>(lean[r].t)))) {
        std::fprintf(stderr, "rays_bench: ray %zu differs between the lean path and kdtree\n", r);
        return 1;
      }
    }
  }
  // Exact tests a ray, a closest-hit cast (the visitor clips at each hit).
  std::uint64_t tests = 0;
  {
    const arrays::RayCaster caster(objects);
    for (const Ray& r : rays) {
      double best = r.tmax;
      tests += caster.cast(r, [&](std::uint32_t, double t) { return best = std::min(best, t); });
    }
  }
  const double lc = median(lean_cast), tc = median(tree_cast);
  std::printf("%s %zu spheres, %zu random rays, one thread, medians of %d\n", dist.c_str(), n,
              ray_count, repeats);
  std::printf("lean:   build %.1f ms, %.0f rays/s, %.1f B/object\n", median(lean_build),
              1e3 * static_cast<double>(ray_count) / lc,
              static_cast<double>(memory_lean) / static_cast<double>(n));
  std::printf("kdtree: build %.1f ms, %.0f rays/s, %.1f B/object\n", median(tree_build),
              1e3 * static_cast<double>(ray_count) / tc,
              static_cast<double>(memory_tree) / static_cast<double>(n));
  std::printf("lean / kdtree rays/s: %.2f; lean exact tests a ray: %.1f\n", tc / lc,
              static_cast<double>(tests) / static_cast<double>(ray_count));
  return 0;
}
