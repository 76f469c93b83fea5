/// \file config_error.hpp
/// The one error type for a bad configuration, and the checks every
/// structure's constructor runs on its Config and on its typed options.
///
/// Every structure throws InvalidConfig from its constructor, whether it is
/// built directly (`Octree{config, OctreeOptions{.split = 16}}`) or through
/// the registry (`make_structure("octree:split=16")`). An unknown structure
/// name is a bad configuration too: registry.hpp's UnknownStructure derives
/// from InvalidConfig, so `catch (const InvalidConfig&)` catches every error
/// a spec can cause.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace broadphase {

struct Config;

/// A configuration no scene can use: a bad option value (NaN, infinite,
/// subnormal, out of its documented range, not one of its choices), an
/// unknown option key, or a bad Config (see check_config). The message names
/// the structure, the option and what it must be.
class InvalidConfig : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Checks the fields of Config common to every structure and returns `c`
/// (so that it can be called in a constructor's member initializers).
///
/// The rule, the same for every structure: each axis of `world` has finite
/// corners, lo < hi, and a finite width hi - lo. A world of side up to the
/// largest double is valid ([0, 1.7976931348623157e308]^3 is a scene
/// format's world, and each structure must stay exact over it); a world whose
/// width overflows ([-1e308, 1e308]^3) is refused, since no scene file
/// describes it (a scene's world is [0, L]^3 with L finite) and no cell size
/// or octree side can be derived from an infinite width. `expected_objects`
/// must be at most Handle::kNullIndex (the objects a handle can name).
/// `c.options`, the string map, must be empty: a constructor that takes typed
/// options refuses to be given options twice (the constructors that take a
/// Config alone read the map first, then clear it).
/// Throws InvalidConfig naming `structure`.
const Config& check_config(const Config& c, std::string_view structure);

/// A copy of `c` without its string options (what a Config-only constructor
/// passes on after reading them into typed options).
Config without_options(const Config& c);

namespace detail {

/// Throws InvalidConfig unless `v` is a finite number in [lo, hi] that is
/// not subnormal (`zero_ok`: 0 is allowed too, meaning "automatic").
void check_number(std::string_view structure, std::string_view key, double v, double lo, double hi,
                  bool zero_ok = false);
/// Throws InvalidConfig unless `v` is in [lo, hi].
void check_integer(std::string_view structure, std::string_view key, std::uint64_t v,
                   std::uint64_t lo, std::uint64_t hi);

}  // namespace detail
}  // namespace broadphase
