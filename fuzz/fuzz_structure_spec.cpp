// Fuzzes structure specs and configurations: Registry::make with a fuzzed
// spec string (`name:key=value,...`), world box and expected object count.
// Any spec either makes a structure or is refused with an exception that
// names the problem; a structure that is made then holds a few nasty
// objects exactly as the naive oracle does.
#include <broadphase/registry.hpp>
#include <cstddef>
#include <cstdint>
#include <new>
#include <stdexcept>
#include <string>

#include "support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace broadphase;
  static const Registry registry = Registry::library();
  FuzzedDataProvider in(data, size);
  Config config;
  // World corners: nasty values or raw doubles (NaN, infinities, any bits).
  const bool raw = in.ConsumeBool();
  double corner[6];
  for (double& c : corner) c = raw ? in.ConsumeFloatingPoint<double>() : fuzz::nasty_coordinate(in);
  config.world = {{corner[0], corner[1], corner[2]}, {corner[3], corner[4], corner[5]}};
  config.expected_objects = in.ConsumeIntegralInRange<std::size_t>(0, 4096);
  // A registered name (most inputs) or free text, then fuzzed options.
  std::string spec;
  const std::uint8_t pick = in.ConsumeIntegral<std::uint8_t>();
  if (pick < 224)
    spec = registry.entries()[pick % registry.entries().size()].name;
  else
    spec = in.ConsumeRandomLengthString(24);
  spec += in.ConsumeRandomLengthString(64);
  std::unique_ptr<AnyBroadPhase> made;
  try {
    made = registry.make(spec, config);
  } catch (const std::bad_alloc&) {
    return 0;  // an option asked for more memory than the sanitizer allows
  } catch (const std::exception& e) {
    if (std::string(e.what()).empty()) fuzz::finding("a refusal without a message");
    return 0;
  }
  fuzz::Twin twin(std::move(made), spec);
  const int objects = in.ConsumeIntegralInRange(0, 12);
  for (int i = 0; i < objects && in.remaining_bytes() > 0; ++i) twin.insert(fuzz::nasty_shape(in));
  twin.all_pairs();
  twin.query(fuzz::nasty_shape(in));
  return 0;
}
