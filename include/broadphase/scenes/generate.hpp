/// \file lab/generate.hpp
/// Counter-based scene generation: object i is drawn from (seed, i) alone,
/// so any range of a scene of N objects can be generated on its own (each
/// MPI rank its share, without a file), and object i is the same object
/// whatever the number of ranks. The workloads follow the study's kinds
/// (docs/scene-format.md) by expectation: each object is moving with
/// probability 0.2 (uneven: near the ground with probability 0.8) instead
/// of exactly 20% (80%), so these scenes differ from `generate()`'s.
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cstdint>
#include <vector>

namespace broadphase {

/// True for the kinds `generate_counter` knows: even, uneven, scaled-even,
/// scaled-uneven, decades, all-moving, flat, outside.
bool counter_supported(Distribution d);

/// The world side of a counter-generated scene of `n` objects (the scaled
/// kinds keep the study's density: 1000 * cbrt(n / 6400)).
double counter_world(Distribution d, std::uint64_t n);

/// Objects [begin, end) of the counter-generated scene of `n` objects,
/// appended to `shapes` and `velocity`. O(end - begin), no state. Throws
/// std::invalid_argument for an unsupported kind or a range past `n`.
void generate_counter_range(Distribution d, std::uint64_t n, std::uint64_t seed,
                            std::uint64_t begin, std::uint64_t end, std::vector<Shape>& shapes,
                            std::vector<Vec3>& velocity);

/// The whole counter-generated scene (small n: tests, files).
Scene generate_counter(Distribution d, std::uint64_t n, std::uint64_t seed);

}  // namespace broadphase
