// peers_check: drives every peer adapter and the naive oracle side by side
// through the shared differential harness (tests/support/testing.hpp: random
// inserts, removals, single and bulk updates, queries, all-pairs passes,
// early stops and stale handles, validate() after every mutation), in the
// worlds that stress the adapters: mixed sizes and boxes, exact touching and
// coincident centres, a crowded cell, coordinates near 1e7, objects larger
// than or far outside the world, and enough objects to outgrow Bullet's
// axis sweep; then with collision filters (random bits, 16 layers) and a
// pair filter changing between steps.
// Usage: peers_check [--small-moves] [name...]   (default: every peer). Exit
// status 1 on the first disagreement of each peer, printed with the world,
// seed and step.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "structures.hpp"
#include "testing.hpp"

int main(int argc, char** argv) {
  using namespace broadphase;
  using testing::World;
  std::vector<std::string> wanted(argv + 1, argv + argc);
  testing::DifferentialOptions options;
  // --small-moves: objects only move a few units per update (no jumps), for
  // peers whose incremental update is documented to fail on large jumps.
  const auto flag = std::find(wanted.begin(), wanted.end(), "--small-moves");
  options.small_moves = flag != wanted.end();
  if (options.small_moves) wanted.erase(flag);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // one line at a time, also into a pipe
  int failures = 0;
  for (const StructureInfo& info : app::registry().entries()) {
    if (!info.peer) continue;
    if (!wanted.empty() && std::find(wanted.begin(), wanted.end(), info.name) == wanted.end())
      continue;
    bool ok = true;
    for (const World w :
         {World::mixed, World::touching, World::crowded, World::far, World::outside, World::many}) {
      // 100 expected objects among 2 600 lets Bullet's sweep outgrow its handles.
      options.config.expected_objects = w == World::many ? 100 : 0;
      // 250 live objects elsewhere (as many as a peer's slowest pass
      // against the oracle affords within peers_test.sh's time limit).
      options.max_objects = w == World::many ? 2600 : 250;
      const int steps = w == World::many ? 3000 : 600;
      for (std::uint64_t seed = 1; seed <= 2 && ok; ++seed) {
        const std::string failure =
            testing::differential_run(info.make, info.name, w, seed, steps, options);
        if (!failure.empty()) std::printf("FAIL %s\n", failure.c_str());
        ok = failure.empty();
      }
    }
    // Filters (random bits, 16 layers) changing between steps, and a pair
    // filter coming and going, against brute force.
    for (const testing::Filters f : {testing::Filters::bits, testing::Filters::layers16})
      for (const World w : {World::mixed, World::touching}) {
        if (!ok) break;
        testing::DifferentialOptions filtered = options;
        filtered.config.expected_objects = 0;
        filtered.max_objects = 250;
        filtered.filters = f;
        const std::string failure = testing::differential_run(
            info.make, info.name, w, 3 + static_cast<std::uint64_t>(f), 600, filtered);
        if (!failure.empty()) std::printf("FAIL %s\n", failure.c_str());
        ok = failure.empty();
      }
    std::printf("%s %s\n", ok ? "ok  " : "FAIL", info.name.c_str());
    failures += !ok;
  }
  return failures == 0 ? 0 : 1;
}
