// `broadphase run --arrays`: replays a scene through the lean path
// (PairTracker over the scene's objects held as the caller's arrays),
// printing the same `frame pairs hash` lines as any structure.
#include <broadphase/arrays.hpp>
#include <broadphase/lab/scene.hpp>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.hpp"

namespace broadphase::app {

void run_arrays(const std::string& path, int frames, bool json) {
  Scene scene = read_scene(path);
  const std::size_t n = scene.size();
  // The caller's arrays: struct of arrays in double, one kind byte per object.
  std::vector<double> x(n), y(n), z(n), hx(n), hy(n), hz(n);
  std::vector<std::uint8_t> kind(n);
  std::vector<std::uint32_t> movers;
  for (std::size_t i = 0; i < n; ++i) {
    const Shape& s = scene.objects[i];
    hx[i] = s.half.x, hy[i] = s.half.y, hz[i] = s.half.z;
    kind[i] = s.is_sphere() ? 0 : 1;
    if (scene.is_moving(i)) movers.push_back(static_cast<std::uint32_t>(i));
  }
  Objects objects;
  objects.count = n;
  objects.x = Column::of(x.data()), objects.y = Column::of(y.data());
  objects.z = Column::of(z.data());
  objects.radius = Column::of(hx.data());  // a sphere's radius is its half.x
  objects.half_x = Column::of(hx.data()), objects.half_y = Column::of(hy.data());
  objects.half_z = Column::of(hz.data());
  objects.kind = kind.data();

  PairTracker tracker;
  FrameDigest total;
  std::uint64_t tests = 0;
  double total_ms = 0;
  std::string out;
  for (int f = 0; f < frames; ++f) {
    if (f > 0) {
      step(scene);
      for (std::uint32_t i : movers)
        if (!is_valid(scene.objects[i])) {
          if (!json) std::fwrite(out.data(), 1, out.size(), stdout);
          throw SceneError("frame " + std::to_string(f) + ": object " + std::to_string(i) +
                           " moves beyond the range of doubles (its motion overflows)");
        }
    }
    // The caller moves its objects in place: every centre at frame 0, the
    // movers' after.
    auto place = [&](std::size_t i) {
      x[i] = scene.objects[i].center.x, y[i] = scene.objects[i].center.y;
      z[i] = scene.objects[i].center.z;
    };
    if (f == 0)
      for (std::size_t i = 0; i < n; ++i) place(i);
    else
      for (std::uint32_t i : movers) place(i);
    FrameDigest d;
    const auto t0 = std::chrono::steady_clock::now();
    const ArrayCallStats stats = tracker.find_pairs(
        objects,
        [&](std::span<const IndexPair> c) {
          for (const IndexPair& p : c) d.add(p.i, p.j);
          return true;
        },
        f == 0 ? Changes::everything() : Changes::only(movers));
    total_ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    tests += stats.tests;
    total.pairs += d.pairs;
    total.hash += d.hash;
    if (!json) {
      out += std::to_string(f) + ' ' + std::to_string(d.pairs) + ' ' + hex16(d.hash) + '\n';
      if (out.size() > (1u << 16)) {
        std::fwrite(out.data(), 1, out.size(), stdout);
        out.clear();
      }
    }
  }
  if (!json) {
    std::fwrite(out.data(), 1, out.size(), stdout);
    return;
  }
  nlohmann::ordered_json j;
  j["algo"] = "arrays";
  j["scene"] = path;
  j["n"] = n;
  j["frames"] = frames;
  j["pairs_total"] = total.pairs;
  j["hash_total"] = hex16(total.hash);
  j["tests_total"] = tests;
  j["total_ms"] = total_ms;
  j["memory_bytes"] = tracker.memory_bytes();
  std::printf("%s\n", j.dump(2).c_str());
}

}  // namespace broadphase::app
