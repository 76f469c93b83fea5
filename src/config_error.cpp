#include <array>
#include <broadphase/config_error.hpp>
#include <broadphase/structure.hpp>
#include <charconv>
#include <cmath>
#include <limits>

namespace broadphase {

namespace {

// The shortest text that reads back as `v` (bounds such as 2^24 in full).
std::string text_of(double v) {
  std::array<char, 32> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc{} ? std::string(buf.data(), end) : std::string("?");
}

[[noreturn]] void refuse(std::string_view structure, const std::string& what) {
  throw InvalidConfig(std::string(structure) + ": " + what);
}

}  // namespace

const Config& check_config(const Config& c, std::string_view structure) {
  static constexpr char kAxis[] = "xyz";
  for (int a = 0; a < 3; ++a) {
    const double lo = c.world.lo[a], hi = c.world.hi[a];
    const std::string axis(1, kAxis[a]);
    if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi))
      refuse(structure, "the world box must be finite and non-empty; along " + axis + " it is [" +
                            text_of(lo) + ", " + text_of(hi) + "]");
    if (!std::isfinite(hi - lo))
      refuse(structure, "the world box's width along " + axis + " ([" + text_of(lo) + ", " +
                            text_of(hi) + "]) overflows a double; a world may be at most " +
                            text_of(std::numeric_limits<double>::max()) + " wide");
  }
  if (c.expected_objects > Handle::kNullIndex)
    refuse(structure, "expected_objects " + std::to_string(c.expected_objects) +
                          " is more than the " + std::to_string(Handle::kNullIndex) +
                          " objects a handle can name");
  if (!c.options.empty())
    refuse(structure, "options given both as Config::options ('" + c.options.begin()->first +
                          "') and as typed options; give them one way");
  return c;
}

Config without_options(const Config& c) {
  Config out;
  out.world = c.world;
  out.expected_objects = c.expected_objects;
  return out;
}

namespace detail {

void check_number(std::string_view structure, std::string_view key, double v, double lo, double hi,
                  bool zero_ok) {
  const bool ok = (zero_ok && v == 0) ||
                  (std::isfinite(v) && v >= lo && v <= hi && (v == 0 || std::isnormal(v)));
  if (!ok)
    refuse(structure, "option '" + std::string(key) + "' must be a number in [" + text_of(lo) +
                          ", " + text_of(hi) + "]" + (zero_ok ? " (or 0: automatic)" : "") +
                          ", neither NaN, infinite nor subnormal; got " + text_of(v));
}

void check_integer(std::string_view structure, std::string_view key, std::uint64_t v,
                   std::uint64_t lo, std::uint64_t hi) {
  if (v < lo || v > hi)
    refuse(structure, "option '" + std::string(key) + "' must be an integer in [" +
                          std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                          std::to_string(v));
}

}  // namespace detail
}  // namespace broadphase
