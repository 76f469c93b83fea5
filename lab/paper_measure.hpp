// The study's measurements on one structure and one scene: the six tests,
// memory, and the frame an engine runs, with the pair hash of every frame.
#pragma once

#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace broadphase::app {

/// Median and spread of repeated measurements.
struct Stat {
  double median = 0, min = 0, max = 0, q1 = 0, q3 = 0;
  int reps = 0;
};

/// Summarizes samples (quartiles by linear interpolation). Empty: all zero.
Stat summarize(std::vector<double> samples);

/// One result: a structure, a test, a size and a placement.
struct Row {
  std::string structure;
  bool peer = false;
  std::string
      test;  ///< query_time, query_tests, insert_time, remove_time, memory, frame_time, build_time
  int study_test = 0;     ///< the study's test number (1-6), 0 for the tests beyond it
  std::string placement;  ///< even | uneven
  std::string dist;       ///< the generator's distribution (even, scaled-even, ...)
  std::size_t n = 0;
  double world = 0;  ///< side of the world cube
  std::string unit;  ///< ns, tests, bytes, ms
  Stat stat;
  std::string note;
};

/// One scene the study runs every structure on.
struct PaperScene {
  std::size_t n = 0;
  bool even = true;
  Distribution dist = Distribution::even;
  std::uint64_t seed = 0;
  Scene scene;
  std::size_t moving = 0;
};

/// Makes the scene of size `n` (scaled beyond the study's 6400 objects).
PaperScene make_paper_scene(std::size_t n, bool even, bool scaled, std::uint64_t seed);

/// How hard to measure.
struct MeasureOptions {
  int reps = 3;                   ///< moved frames, query passes and churn rounds
  double min_rep_seconds = 2e-3;  ///< a timed loop repeats until it has run this long
  double cell_cap_seconds = 60;   ///< stop repeating (after one rep) past 1.5 times this
  std::uint64_t seed = 1;
  bool churn = true;  ///< Tests 5 and 6 (the study runs them on even placement)
};

/// Wall-clock costs of one scene's measurement, used to project larger sizes.
struct CellCosts {
  double build = 0;  ///< inserting the scene
  double frame = 0;  ///< one frame, digest included
  double pass = 0;   ///< one query per moving object
  double churn = 0;  ///< one batch of removals and re-insertions
  double total = 0;  ///< everything, wall clock
  CellCosts& operator+=(const CellCosts& o);
};

/// What one structure did on one scene.
struct SceneResult {
  std::vector<Row> rows;
  std::vector<FrameDigest> digests;       ///< per frame, frame 0 first
  std::vector<std::uint64_t> query_hits;  ///< per query pass: objects reported
  CellCosts costs;
  std::string note;  ///< why fewer reps were run, when they were
};

/// Runs every measurement of `structure` (a registry spec) on `ps`.
/// `tick` is called between steps with a short description of the step.
/// Throws what the structure throws.
SceneResult measure_scene(const Registry& registry, const std::string& structure, bool peer,
                          const PaperScene& ps, const MeasureOptions& options,
                          const std::function<void(const std::string&)>& tick);

/// The name of the lean path's series (arrays.hpp: a PairTracker over the
/// caller's arrays) in the tables and figures. It is not a registry name:
/// the handle API's measurements never make it.
inline constexpr const char* kArraysSeries = "arrays";

/// The lean path on `ps`, as its caller runs it (ArrayCaller: the scene as
/// columns the caller owns). Frame 0 builds the tracker (Changes::everything,
/// the `build_time` row, not a frame); then `options.reps` frames, each
/// moving the movers (not timed, as the replay's motion is not) and timing
/// one PairTracker call told Changes::only(movers), pairs appended to a
/// vector as the handle structures' find_pairs does. Rows `frame_time`,
/// `build_time`, `memory` (the tracker's own bytes) and `memory_with_arrays`
/// (plus the caller's arrays it reads); digests per frame, frame 0 first,
/// comparable with measure_scene's. Throws when a motion overflows.
SceneResult measure_arrays(const PaperScene& ps, const MeasureOptions& options,
                           const std::function<void(const std::string&)>& tick);

/// The batch size of Tests 5 and 6 at `n` objects: 5% of n, in [1, 1024].
std::size_t churn_batch(std::size_t n);

}  // namespace broadphase::app
