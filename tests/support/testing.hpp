// Shared test support: reference scenes, and the model-based differential
// harness that drives any structure and the naive oracle side by side.
#pragma once

#include <broadphase/structure.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/lab/scene.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace broadphase::testing {

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
/// paths: fast-grid on three threads with every pass split from two movers
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
};
const char* to_string(World w);

/// Runs `steps` random operations (insert, remove, update, query, all pairs)
/// on structure `spec` and on the naive oracle, comparing every answer and
/// calling validate() after every mutation. Reports failures through
/// GoogleTest with the seed and step, and returns after the first one.
void differential(const std::string& spec, World world, std::uint64_t seed, int steps,
                  const Config& config = {});

}  // namespace broadphase::testing
