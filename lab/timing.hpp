// Timing of structures on a scene, shared by `advise` and the lab's
// performance experiment: frames within a time budget, a few micro-timings
// (one query, one insert, one remove), and the per-frame digests so that
// the callers can check that every structure found the same pairs.
#pragma once

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/detail/median.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/array_caller.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cstdint>
#include <exception>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace broadphase::app {

/// What timing one structure on one scene measured.
struct StructureTiming {
  std::string spec;
  double build_ms = 0;
  std::vector<double> frame_ms;      ///< wall time of update + find_pairs, per frame after warm-up
  std::vector<double> warm_ms;       ///< the same for the warm-up frames left out of frame_ms
  std::vector<FrameDigest> digests;  ///< per frame
  double query_us = 0;               ///< one exact overlap query (median of batches)
  double insert_us = 0;              ///< one insert (median of batches)
  double remove_us = 0;              ///< one remove (median of batches)
  std::size_t memory_bytes = 0;      ///< after the frames
  std::size_t caller_bytes = 0;      ///< the caller's arrays a borrowed path reads (0: none)
  std::string error;                 ///< non-empty when the structure failed

  double median_frame_ms() const { return median(frame_ms); }
  /// The mean: what a run of these frames costs per frame, including the
  /// occasional frame that renews or rebuilds much more than the median one.
  double mean_frame_ms() const {
    if (frame_ms.empty()) return 0;
    double sum = 0;
    for (double v : frame_ms) sum += v;
    return sum / static_cast<double>(frame_ms.size());
  }
  /// The mean of the first `k` frames run, warm-up included (of fewer
  /// when fewer ran): what a short run costs a frame. `build_ms` (the
  /// inserts; for the lean path, its first call, frame 0) is not added.
  double first_frames_ms(std::size_t k) const {
    double sum = 0;
    std::size_t n = 0;
    for (const std::vector<double>* v : {&warm_ms, &frame_ms})
      for (std::size_t f = 0; f < v->size() && n < k; ++f, ++n) sum += (*v)[f];
    return n > 0 ? sum / static_cast<double>(n) : 0;
  }
  static double median(std::vector<double> v) { return detail::median(std::move(v)); }
};

/// How long to run a structure.
struct TimingLimits {
  int max_frames = 100;       ///< frames at most
  int min_frames = 3;         ///< frames at least (unless a frame alone exceeds the budget)
  double budget_seconds = 2;  ///< measured frames stop once this much time has gone
  double warmup_seconds =
      0;              ///< a warm-up frame longer than this ends the run (0: twice the budget)
  bool micro = true;  ///< also time query, insert and remove
};

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Runs `frame(f)`, which returns the frame's seconds and digest, for
/// f = 0, 1, ... within `limits`, recording each in `t`, then leaves the
/// warm-up out. Frame 0 has no update, and frame 1 carries the first bulk
/// update after the inserts (where structures that defer work sort
/// everything into place): both are warm-up, left out when later frames
/// exist. The budget counts from the end of the warm-up, so that a
/// structure whose warm-up is long (a pair cache built at a million
/// objects) still gets its measured frames; a warm-up frame alone over
/// `warmup_seconds` ends the run (the structure is too slow for this size).
template <class Frame>
void run_frames(const TimingLimits& limits, StructureTiming& t, Frame&& frame) {
  constexpr int kWarmFrames = 2;
  auto start = std::chrono::steady_clock::now();
  for (int f = 0; f < limits.max_frames; ++f) {
    const auto [seconds, digest] = frame(f);
    t.frame_ms.push_back(seconds * 1e3);
    t.digests.push_back(digest);
    if (f < kWarmFrames) {
      const double warm_cap =
          limits.warmup_seconds > 0 ? limits.warmup_seconds : 2 * limits.budget_seconds;
      if (seconds > warm_cap) break;
      if (f + 1 == kWarmFrames) start = std::chrono::steady_clock::now();
      continue;
    }
    const double spent = seconds_since(start);
    if (f + 1 >= limits.min_frames && spent > limits.budget_seconds) break;
    if (spent > 2 * limits.budget_seconds) break;  // the frames are too slow for min_frames
  }
  const std::size_t warm = t.frame_ms.size() > 2 ? 2 : (t.frame_ms.size() > 1 ? 1 : 0);
  t.warm_ms.assign(t.frame_ms.begin(), t.frame_ms.begin() + static_cast<std::ptrdiff_t>(warm));
  t.frame_ms.erase(t.frame_ms.begin(), t.frame_ms.begin() + static_cast<std::ptrdiff_t>(warm));
}

/// Builds `spec` from `registry` for `scene`, replays frames within the
/// limits, then times queries, inserts and removes. Never throws: a failure
/// is reported in `error`.
inline StructureTiming time_structure(const Registry& registry, const std::string& spec,
                                      const Scene& scene, const TimingLimits& limits) {
  StructureTiming t;
  t.spec = spec;
  try {
    Config config;
    config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
    config.expected_objects = scene.size();
    auto bp = registry.make(spec, config);
    Replay replay(*bp, scene);
    t.build_ms = replay.build_seconds() * 1e3;
    run_frames(limits, t, [&](int) {
      const FrameResult r = replay.next();
      return std::pair{r.seconds(), r.digest};
    });
    t.memory_bytes = bp->memory_bytes();
    if (limits.micro && scene.size() > 0) {
      // Each batch's shapes are drawn before its clock starts: drawing one
      // (a random index, a scene object far from the last one in memory)
      // costs about as much as a fast structure's insert, and inside the
      // timed loop its latency added to every operation timed.
      Rng rng(12345);
      constexpr int kBatch = 200;
      constexpr int kRounds = 7;
      std::vector<double> q, ins, rem;
      std::vector<Handle> added;
      std::vector<Shape> batch(kBatch);
      auto draw = [&](double dx) {
        for (Shape& s : batch) {
          s = replay.scene().objects[rng.below(scene.size())];
          s.center.x += dx;
        }
      };
      for (int round = 0; round < kRounds; ++round) {
        std::uint64_t found = 0;
        draw(0);
        auto t0 = std::chrono::steady_clock::now();
        for (const Shape& s : batch)
          bp->query(s, [&found](Handle) {
            ++found;
            return true;
          });
        q.push_back(seconds_since(t0) * 1e6 / kBatch);
        if (found < kBatch) throw std::logic_error(spec + ": a query missed the object it copied");
        draw(0.5);
        added.clear();
        added.reserve(kBatch);
        t0 = std::chrono::steady_clock::now();
        for (int k = 0; k < kBatch; ++k)
          added.push_back(bp->insert(batch[static_cast<std::size_t>(k)],
                                     scene.size() + static_cast<std::size_t>(k)));
        ins.push_back(seconds_since(t0) * 1e6 / kBatch);
        t0 = std::chrono::steady_clock::now();
        for (Handle h : added) bp->remove(h);
        rem.push_back(seconds_since(t0) * 1e6 / kBatch);
      }
      t.query_us = StructureTiming::median(q);
      t.insert_us = StructureTiming::median(ins);
      t.remove_us = StructureTiming::median(rem);
    }
  } catch (const std::exception& e) {
    t.error = e.what();
  }
  return t;
}

/// The lean path (arrays.hpp) on `scene` as its caller would run it: the
/// scene's objects as the caller's arrays (`ArrayCaller`), the movers moved
/// in place, then one `PairTracker` call told which objects moved, per
/// frame; frames, warm-up and budget as in `time_structure`, with the same
/// per-frame digests. `spec` names it in the tables (`arrays`, or
/// `arrays:threads=2`). Never throws: a failure is reported in `error`.
inline StructureTiming time_arrays(const std::string& spec, const Scene& scene,
                                   const TimingLimits& limits, unsigned threads = 1) {
  StructureTiming t;
  t.spec = spec;
  try {
    ArrayCaller caller(scene);
    ArrayOptions options;
    options.threads = threads;
    PairTracker tracker(options);
    const Objects objects = caller.objects();
    run_frames(limits, t, [&](int f) {
      const auto t0 = std::chrono::steady_clock::now();
      if (f > 0 && caller.step() != SIZE_MAX)
        throw std::runtime_error("frame " + std::to_string(f) + ": a motion overflows a double");
      FrameDigest d;
      tracker.find_pairs(
          objects,
          [&d](std::span<const IndexPair> c) {
            for (const IndexPair& p : c) d.add(p.i, p.j);
            return true;
          },
          f == 0 ? Changes::everything() : Changes::only(caller.movers()));
      const double seconds = seconds_since(t0);
      if (f == 0) t.build_ms = seconds * 1e3;
      return std::pair{seconds, d};
    });
    t.memory_bytes = tracker.memory_bytes();
    t.caller_bytes = caller.bytes();
  } catch (const std::exception& e) {
    t.error = e.what();
  }
  return t;
}

/// Index of the first frame where two timings disagree, or -1 when they
/// agree on every frame both ran.
inline int first_disagreement(const StructureTiming& a, const StructureTiming& b) {
  const std::size_t n = std::min(a.digests.size(), b.digests.size());
  for (std::size_t f = 0; f < n; ++f)
    if (!(a.digests[f] == b.digests[f])) return static_cast<int>(f);
  return -1;
}

/// What `advise` measured on a scene: every candidate's timing, which of
/// them agree on the pairs with the reference (the one that ran the most
/// frames; none when no candidate ran), and the fastest of those (`best`;
/// results.size() when none agrees).
struct Advice {
  std::vector<StructureTiming> results;
  std::vector<bool> agrees;
  std::size_t ref = 0, best = 0;
  std::size_t agreeing() const {
    return static_cast<std::size_t>(std::count(agrees.begin(), agrees.end(), true));
  }
};

/// `advise`'s candidates on a scene of `n` objects: every structure of
/// `registry`, the peers too with `peers`, the quadratic oracle only up to
/// 3 000 objects (worth timing only there).
inline std::vector<std::string> advise_candidates(const Registry& registry, std::size_t n,
                                                  bool peers) {
  std::vector<std::string> specs;
  for (const StructureInfo& e : registry.entries())
    if ((peers || !e.peer) && !(e.name == "naive" && n > 3000)) specs.push_back(e.name);
  return specs;
}

/// The limits `advise` gives each of `count` candidates within about
/// `seconds` in all: at most `frames` frames, two warm-up frames and then
/// at least six, and about half the time for the frames (building and the
/// micro-timings take the rest).
inline TimingLimits advise_limits(int frames, double seconds, std::size_t count) {
  TimingLimits limits;
  limits.max_frames = frames;
  limits.min_frames = std::min(8, frames);
  limits.budget_seconds = 0.5 * seconds / static_cast<double>(std::max<std::size_t>(count, 1));
  return limits;
}

/// Times `specs` on `scene` within `limits`, one after another, calling
/// `report(k, timing)` after each, and chooses as `advise` does.
template <class Report>
Advice advise_on(const Registry& registry, const std::vector<std::string>& specs,
                 const Scene& scene, const TimingLimits& limits, Report&& report) {
  Advice a;
  for (std::size_t k = 0; k < specs.size(); ++k) {
    a.results.push_back(time_structure(registry, specs[k], scene, limits));
    report(k, a.results.back());
  }
  const std::size_t none = a.results.size();
  a.ref = none;
  for (std::size_t k = 0; k < none; ++k)
    if (a.results[k].error.empty() &&
        (a.ref == none || a.results[k].digests.size() > a.results[a.ref].digests.size()))
      a.ref = k;
  a.agrees.assign(none, false);
  for (std::size_t k = 0; k < none; ++k)
    a.agrees[k] = a.ref < none && a.results[k].error.empty() &&
                  first_disagreement(a.results[k], a.results[a.ref]) < 0;
  a.best = none;
  for (std::size_t k = 0; k < none; ++k)
    if (a.agrees[k] &&
        (a.best == none || a.results[k].median_frame_ms() < a.results[a.best].median_frame_ms()))
      a.best = k;
  return a;
}

}  // namespace broadphase::app
