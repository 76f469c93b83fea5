// Shared test support: reference scenes, and the model-based differential
// harness that drives any structure and the naive oracle side by side.
#pragma once

#include <broadphase/registry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace broadphase::testing {

// GCC says which sanitizer a build has by __SANITIZE_THREAD__ and
// __SANITIZE_ADDRESS__, clang by __has_feature.
#if defined(__has_feature)
#define BROADPHASE_TESTING_HAS(feature) __has_feature(feature)
#else
#define BROADPHASE_TESTING_HAS(feature) 0
#endif

/// True in a ThreadSanitizer build. Every memory access costs there many
/// times more, so tests that repeat a threaded call many times, or compare
/// tens of thousands of objects with an O(n^2) oracle, do fewer repeats
/// (a race shows in a few; the Release build runs them all).
#if defined(__SANITIZE_THREAD__) || BROADPHASE_TESTING_HAS(thread_sanitizer)
inline constexpr bool kThreadSanitizer = true;
#else
inline constexpr bool kThreadSanitizer = false;
#endif

/// True in an AddressSanitizer build (CI's ASan + UBSan stage), where the
/// lean path's randomized tests ran 6-8 times as long as in Release (the
/// stage's tests 648 s on a 2-core AMD EPYC VM, 95 s the longest).
#if defined(__SANITIZE_ADDRESS__) || BROADPHASE_TESTING_HAS(address_sanitizer)
inline constexpr bool kAddressSanitizer = true;
#else
inline constexpr bool kAddressSanitizer = false;
#endif

/// `n` repeats, or a tenth of them (at least one) under ThreadSanitizer or
/// AddressSanitizer: the seeds there run the paths the sanitizers watch;
/// the Release build runs them all. (A third under ASan took 1 340 s of CPU
/// for the stage's tests; a fifth 1 056 s, with CI over its 45 minutes.)
constexpr int repeats(int n) { return kThreadSanitizer || kAddressSanitizer ? (n + 9) / 10 : n; }

/// A reference scene and its expected per-frame results.
struct ReferenceScene {
  std::string name;
  std::string scene_path;
  std::vector<FrameDigest> expected;
};

/// Every `*.scene` under tests/data/scenes with its `.expected` file.
std::vector<ReferenceScene> reference_scenes();

/// The names of every library structure (what `broadphase list` shows).
std::vector<std::string> library_structures();

/// Every library structure, plus variants whose options take other code
/// paths: grid-verlet on three threads with every pass split from two movers
/// on (grain=1), so that small scenes run its threaded update and pairs.
std::vector<std::string> structure_specs();

/// Names a test instantiated over structure names: the name with every
/// character that is not a letter or digit made '_' (gtest's rule).
struct StructureParamName {
  template <class Info>
  std::string operator()(const Info& info) const {
    return identifier(info.param);
  }
  static std::string identifier(std::string name);
};

/// Replays `scene` through a fresh structure `spec` for `frames` frames.
std::vector<FrameDigest> replay(const std::string& spec, const Scene& scene, int frames,
                                bool validate_each_frame = false);

/// Fills a structure `spec` with `scene` (moving objects as dynamic), then
/// runs queries, all-pairs passes, validate and memory_bytes from two
/// threads at once, as the interface allows, and expects what one thread
/// gets (gtest expectations).
void const_calls_on_two_threads(const std::string& spec, const Scene& scene);

/// Brute-force digest of the objects' current positions.
FrameDigest brute_force(const std::vector<Shape>& objects);

/// The kinds of random worlds the differential test draws from.
enum class World {
  mixed,     ///< spheres and boxes, sizes over decades, some outside the world
  touching,  ///< exact touching and identical centres on a lattice
  crowded,   ///< thousands of objects in one small cell
  far,       ///< coordinates around 1e7 from the origin
  huge,      ///< a few objects larger than the world
  extreme,   ///< coordinates and sizes up to 1e300, where the predicate overflows
  tiny,      ///< coordinates and sizes down to subnormals, where its squares underflow
  outside,   ///< most objects far outside the world, some larger than it
  many,      ///< 2 600 ordinary objects (enough to outgrow a table sized for 100)
  shaped,    ///< poles, slabs (some of zero thickness), boxes of three half sides and
             ///< spheres, sizes over four decades, mostly near the ground, some touching
};
const char* to_string(World w);

/// Makes the structure under test from a Config.
using Factory = std::function<std::unique_ptr<AnyBroadPhase>(const Config&)>;

/// The collision filters a differential run draws (none: the defaults).
enum class Filters {
  none,      ///< every object keeps the default filter, no pair filter
  bits,      ///< random group and mask bits (about half the pairs pass)
  layers4,   ///< one group of 4 per object, its mask its own and the neighbouring groups
  layers16,  ///< as layers4 with 16 groups: most groups ignore each other
};
const char* to_string(Filters f);

/// What a differential run varies beyond the world and the seed.
struct DifferentialOptions {
  Config config;                ///< given to the factory
  bool small_moves = false;     ///< updates move a few units only: no jumps, no resizes
  std::size_t max_objects = 0;  ///< live objects to grow to (0: the world's default)
  /// With filters, objects are inserted with a drawn filter, steps also
  /// change filters and install or remove a random symmetric pair filter,
  /// and every pair answer is compared with a brute force over the
  /// harness's own record of the filters.
  Filters filters = Filters::none;
};

/// Runs `steps` random operations (insert, remove, single and bulk update,
/// query, all pairs, early stops, stale handles) on the structure `make`
/// builds and on the naive oracle, comparing every answer and calling
/// validate() after every mutation. Returns the first disagreement, naming
/// `name`, the world, the seed and the step; empty when all agreed.
std::string differential_run(const Factory& make, const std::string& name, World world,
                             std::uint64_t seed, int steps,
                             const DifferentialOptions& options = {});

/// differential_run on a library structure `spec`, reporting a
/// disagreement through GoogleTest.
void differential(const std::string& spec, World world, std::uint64_t seed, int steps,
                  const Config& config = {}, Filters filters = Filters::none);

}  // namespace broadphase::testing
