/// \file rays.hpp
/// Many rays in one call (a lidar's sweep, a frame's line-of-sight checks):
/// the closest hit of each ray, or all of its hits in compressed rows, over
/// any structure, split among threads.
///
/// Results never depend on the thread count: each ray is cast alone, by
/// the same walk, into its own place of the output; the rays are cut into
/// contiguous shares by index, and all-hits rows are joined in ray order,
/// each row sorted by (t, slot index).
#pragma once

#include <algorithm>
#include <broadphase/ray.hpp>
#include <broadphase/structure.hpp>
#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace broadphase {

/// Every hit of every ray in compressed rows: the hits of ray i are
/// `hits[offsets[i]]` to `hits[offsets[i + 1] - 1]`, sorted by t, then by
/// slot index (the closest hit first). `offsets` has one entry per ray plus
/// one.
struct RayHitRows {
  std::vector<std::size_t> offsets;
  std::vector<RayHit> hits;
};

namespace detail {

/// Runs job(begin, end, share) over `threads` contiguous shares of [0, n)
/// (the calling thread takes the first); at most one share per 64 items,
/// since starting a thread costs about as much as casting a few dozen rays.
template <class Job>
void run_shares(std::size_t n, unsigned threads, Job&& job) {
  const std::size_t shares =
      std::max<std::size_t>(1, std::min<std::size_t>(threads == 0 ? 1 : threads, n / 64));
  std::vector<std::thread> pool;
  pool.reserve(shares - 1);
  auto bounds = [&](std::size_t k) { return n * k / shares; };
  for (std::size_t k = 1; k < shares; ++k)
    pool.emplace_back([&, k] { job(bounds(k), bounds(k + 1), k); });
  job(bounds(0), bounds(1), std::size_t{0});
  for (std::thread& t : pool) t.join();
}

/// Casts rays 0 to n - 1 into compressed rows (RayHitRows, or the lean
/// path's IndexHitRows), replacing `out`'s content: cast(i, hits) appends
/// ray i's hits to `hits` in any order; each row is then sorted by `less`,
/// and the threads' shares are joined in ray order, so the rows never
/// depend on the thread count.
template <class Rows, class Cast, class Less>
void gather_hit_rows(std::size_t n, unsigned threads, Cast&& cast, Less less, Rows& out) {
  using Hit = typename decltype(out.hits)::value_type;
  std::vector<std::vector<Hit>> part(std::max(1u, threads));
  std::vector<std::size_t> count(n);
  run_shares(n, threads, [&](std::size_t begin, std::size_t end, std::size_t k) {
    std::vector<Hit>& hits = part[k];
    for (std::size_t i = begin; i < end; ++i) {
      const std::size_t first = hits.size();
      cast(i, hits);
      std::sort(hits.begin() + static_cast<std::ptrdiff_t>(first), hits.end(), less);
      count[i] = hits.size() - first;
    }
  });
  out.offsets.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) out.offsets[i + 1] = out.offsets[i] + count[i];
  out.hits.clear();
  out.hits.reserve(out.offsets.back());
  for (const std::vector<Hit>& p : part) out.hits.insert(out.hits.end(), p.begin(), p.end());
}

}  // namespace detail

/// The closest hit of each ray: `closest[i]` is closest_hit(s, rays[i]) (a
/// null handle and t = +inf where the ray hits nothing). `closest` must be
/// as long as `rays` (std::invalid_argument). Throws InvalidRay, naming the
/// first invalid ray, before casting any. `threads` >= 1 threads share the
/// rays (0 counts as 1); the structure's const calls must be safe to run
/// concurrently, as every structure of the library's are.
template <HasRayCast S>
void cast_rays(const S& s, std::span<const Ray> rays, std::span<RayHit> closest,
               unsigned threads = 1) {
  detail::require_valid_batch(rays, closest.size(), "cast_rays");
  detail::run_shares(rays.size(), threads, [&](std::size_t begin, std::size_t end, std::size_t) {
    const std::span<const Ray> part = rays.subspan(begin, end - begin);
    const std::span<RayHit> hits = closest.subspan(begin, end - begin);
    // A structure's own batch walk when it has one (several rays at once).
    if constexpr (requires { s.closest_hits(part, hits); })
      s.closest_hits(part, hits);
    else
      for (std::size_t i = 0; i < part.size(); ++i) hits[i] = closest_hit(s, part[i]);
  });
}

/// Every hit of each ray, in rows (RayHitRows), replacing `out`'s content.
/// Throws InvalidRay, naming the first invalid ray, before casting any.
template <HasRayCast S>
void cast_rays_all(const S& s, std::span<const Ray> rays, RayHitRows& out, unsigned threads = 1) {
  detail::require_valid_rays(rays);
  detail::gather_hit_rows(
      rays.size(), threads,
      [&](std::size_t i, std::vector<RayHit>& hits) {
        s.cast_ray(rays[i], [&](Handle h, double t) {
          hits.push_back({h, t});
          return kRayGoOn;
        });
      },
      closer, out);
}

/// As the templates, over the type-erased face (one virtual call per ray).
void cast_rays(const AnyBroadPhase& s, std::span<const Ray> rays, std::span<RayHit> closest,
               unsigned threads = 1);
void cast_rays_all(const AnyBroadPhase& s, std::span<const Ray> rays, RayHitRows& out,
                   unsigned threads = 1);

}  // namespace broadphase
