// `broadphase run --arrays`: replays a scene through the lean path
// (PairTracker over the scene's objects held as the caller's arrays, with
// their filter columns, and its RayCaster for the scene's rays; in a
// periodic world the PeriodicPairTracker, the caller wrapping its objects),
// printing the same lines as any structure.
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/arrays/periodic.hpp>
#include <broadphase/arrays/rays.hpp>
#include <broadphase/detail/median.hpp>
#include <broadphase/scenes/array_caller.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"

namespace broadphase::app {

void run_arrays(const std::string& path, int frames, bool json) {
  const Scene scene = read_scene(path);
  const std::vector<Ray>& rays = scene.rays;
  ArrayCaller caller(scene);
  const std::size_t n = caller.size();
  const Objects objects = caller.objects();
  const std::vector<std::uint32_t>& movers = caller.movers();

  PairTracker tracker;
  std::optional<PeriodicPairTracker> periodic;
  if (scene.is_periodic()) periodic.emplace(scene.cell());
  FrameDigest total;
  std::uint64_t tests = 0;
  std::vector<double> call_ms;
  double total_ms = 0, rays_ms = 0;
  HitDigest hits_total;
  arrays::IndexHitRows rows;
  std::string out;
  for (int f = 0; f < frames; ++f) {
    // The caller moves its objects in place (the movers), then calls.
    if (f > 0) {
      const std::size_t bad = caller.step();
      if (bad != SIZE_MAX) {
        if (!json) std::fwrite(out.data(), 1, out.size(), stdout);
        throw SceneError("frame " + std::to_string(f) + ": object " + std::to_string(bad) +
                         " moves beyond the range of doubles (its motion overflows)");
      }
    }
    FrameDigest d;
    const auto t0 = std::chrono::steady_clock::now();
    const Changes changes = f == 0 ? Changes::everything() : Changes::only(movers);
    const ArrayCallStats stats = periodic ? periodic->find_pairs(
                                                objects,
                                                [&](std::span<const ShiftedPair> c) {
                                                  for (const ShiftedPair& p : c)
                                                    d.add(p.i, p.j, p.shift);
                                                  return true;
                                                },
                                                changes)
                                          : tracker.find_pairs(
                                                objects,
                                                [&](std::span<const IndexPair> c) {
                                                  for (const IndexPair& p : c) d.add(p.i, p.j);
                                                  return true;
                                                },
                                                changes);
    call_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    total_ms += call_ms.back();
    tests += stats.tests;
    total.pairs += d.pairs;
    total.hash += d.hash;
    // Every hit of every ray, each row sorted by t then index: its first
    // is the ray's closest.
    HitDigest h;
    if (!rays.empty()) {
      const auto r0 = std::chrono::steady_clock::now();
      // Rays do not wrap: a periodic world's are cast at the objects as
      // they lie, by a caster of the frame.
      if (periodic)
        arrays::RayCaster(objects).all(rays, rows);
      else
        tracker.ray_caster(objects).all(rays, rows);
      rays_ms +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - r0).count();
      for (std::size_t r = 0; r < rays.size(); ++r) {
        RayHits ray(static_cast<std::uint32_t>(r));
        for (std::size_t k = rows.offsets[r]; k < rows.offsets[r + 1]; ++k)
          ray.add(rows.hits[k].index, rows.hits[k].t);
        ray.add_to(h);
      }
      hits_total.hits += h.hits;
      hits_total.hash += h.hash;
      hits_total.closest += h.closest;
    }
    if (!json) {
      out += frame_line(f, d, rays.empty() ? nullptr : &h) + '\n';
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
  if (!rays.empty()) {
    j["rays"] = rays.size();
    j["hits_total"] = hits_total.hits;
    j["hits_hash_total"] = hex16(hits_total.hash);
    j["closest_hash_total"] = hex16(hits_total.closest);
  }
  j["tests_total"] = tests;
  j["median_frame_ms"] = detail::median(call_ms);  // the calls, as `run` gives a structure's frames
  j["total_ms"] = total_ms;
  if (!rays.empty()) j["rays_total_ms"] = rays_ms;
  j["memory_bytes"] = periodic ? periodic->memory_bytes() : tracker.memory_bytes();
  std::printf("%s\n", j.dump(2).c_str());
}

}  // namespace broadphase::app
