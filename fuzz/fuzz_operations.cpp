// Differential operation sequences: a fuzzed sequence of inserts, removes,
// updates, bulk updates (some with a bad move at a fuzzed place, which must
// change nothing), queries and all-pairs passes, on one structure of the
// library (chosen by the input's first byte) and the naive oracle, in a
// fuzzed world; every answer is compared and validate() runs after every
// mutation (fuzz/support.hpp). Shapes are spheres and boxes at nasty
// coordinates (0, +-subnormals, exact touching, identical centres, 1e7,
// +-1.8e308) with sizes up to 1e300.
#include <broadphase/registry.hpp>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "support.hpp"

namespace {

const broadphase::Registry& registry() {
  static const broadphase::Registry r = broadphase::Registry::library();
  return r;
}

const std::vector<std::string>& specs() {
  static const std::vector<std::string> s = [] {
    std::vector<std::string> out;
    for (const auto& e : registry().entries()) out.push_back(e.name);
    out.push_back("grid-verlet:threads=2,grain=1");
    return out;
  }();
  return s;
}

broadphase::Aabb world_of(std::uint8_t b) {
  constexpr double kMax = std::numeric_limits<double>::max();
  constexpr double kDenorm = std::numeric_limits<double>::denorm_min();
  switch (b % 6) {
    case 0:
      return {{0, 0, 0}, {1000, 1000, 1000}};
    case 1:
      return {{-1e308, -1e308, -1e308}, {1e308, 1e308, 1e308}};  // width overflows
    case 2:
      return {{0, 0, 0}, {kMax, kMax, kMax}};
    case 3:
      return {{0, 0, 0}, {4 * kDenorm, 4 * kDenorm, 4 * kDenorm}};
    case 4:
      return {{-1e300, -1e300, -1e300}, {1e300, 1e300, 1e300}};
    default:
      return {{1e7, 1e7, 1e7}, {1e7 + 10, 1e7 + 10, 1e7 + 10}};
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace broadphase;
  FuzzedDataProvider in(data, size);
  const std::string& spec = specs()[in.ConsumeIntegral<std::uint8_t>() % specs().size()];
  Config config;
  config.world = world_of(in.ConsumeIntegral<std::uint8_t>());
  // A world whose width overflows a double is refused as a configuration
  // (InvalidConfig): such inputs end here, every other one runs.
  std::unique_ptr<AnyBroadPhase> made;
  try {
    made = registry().make(spec, config);
  } catch (const InvalidConfig&) {
    return 0;
  }
  fuzz::Twin twin(std::move(made), spec);
  for (int step = 0; step < 200 && in.remaining_bytes() > 0; ++step) {
    const std::uint8_t op = in.ConsumeIntegral<std::uint8_t>() % 8;
    if (op <= 1 || twin.size() == 0) {
      if (twin.size() < 48) twin.insert(fuzz::nasty_shape(in));
    } else if (op == 2) {
      twin.remove(in.ConsumeIntegral<std::uint8_t>());
    } else if (op == 3) {
      const std::size_t k = in.ConsumeIntegral<std::uint8_t>();
      twin.update(k, fuzz::nasty_shape(in));
    } else if (op == 4) {
      std::vector<std::pair<std::size_t, Shape>> moves;
      const int n = in.ConsumeIntegralInRange(1, 16);
      for (int i = 0; i < n && in.remaining_bytes() > 0; ++i) {
        const std::size_t k = in.ConsumeIntegral<std::uint8_t>();
        moves.emplace_back(k, fuzz::nasty_shape(in));
      }
      // A bad move at a place in [0, moves] one time in three.
      const std::uint8_t b = in.ConsumeIntegral<std::uint8_t>();
      const std::size_t bad_at = b % 3 == 0 ? (b / 3) % (moves.size() + 1) : moves.size() + 1;
      const bool stale = in.ConsumeBool();
      twin.bulk(moves, bad_at, fuzz::bad_shape(in), stale);
    } else if (op == 5) {
      twin.query(fuzz::nasty_shape(in));
    } else if (op == 6) {
      twin.all_pairs();
    } else {
      twin.refused_single(fuzz::bad_shape(in));
    }
  }
  twin.all_pairs();
  return 0;
}
