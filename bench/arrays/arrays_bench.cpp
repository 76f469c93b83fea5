// Measures the lean path (arrays.hpp) on a generated scene held in memory,
// as a caller would: SoA double columns the caller owns, its movers moved
// by the replay motion, then one PairTracker call per frame.
//
//   arrays_bench DIST N [FRAMES] [--threads T] [--skin S] [--all]
//                [--compare ALGO] [--seed S]
//
// Prints per frame: frame, pairs, hash, the call's ms (wall and CPU),
// rebuilt or compacted, the objects renewed alone, the quiet objects, the
// exact tests made, own bytes per object; then the medians, the tracker's
// own bytes per object, and the process's VmRSS and VmHWM (kB, from
// /proc/self/status). `--compare ALGO` replays the same scene through a
// handle structure (e.g. grid-verlet) in the same process, checks that every
// frame's count and hash agree, and prints its median.
// `--all` tells the tracker that everything may have changed (it then
// finds the movers itself) instead of passing the movers' indices.
// `--periodic AXES` makes the scene periodic on AXES as `gen --periodic`
// does and measures the PeriodicPairTracker (arrays/periodic.hpp), its
// `--compare ALGO` the periodic adapter over ALGO; `--static` stops every
// object (a frame then changes nothing).
#include <algorithm>
#include <array>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/arrays/periodic.hpp>
#include <broadphase/detail/median.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/array_caller.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <numeric>
#include <string>
#include <vector>

namespace {

using namespace broadphase;
using Clock = std::chrono::steady_clock;

long status_kb(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::size_t len = std::strlen(key);
  while (std::getline(in, line))
    if (line.compare(0, len, key) == 0) return std::atol(line.c_str() + len + 1);
  return -1;
}

// CPU time of the process in ms: on a shared host the wall clock also
// counts the time other processes held the cores.
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

using broadphase::detail::median;

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(
        stderr,
        "usage: arrays_bench DIST N [FRAMES] [--threads T] [--skin S] [--spare BYTES] [--all] "
        "[--compare ALGO] [--seed S] [--quiet] [--one-shot] [--periodic AXES] [--static]\n");
    return 2;
  }
  const Distribution dist = parse_distribution(argv[1]);
  const std::size_t n = std::strtoull(argv[2], nullptr, 10);
  int frames = 20;
  int argi = 3;
  if (argc > 3 && argv[3][0] != '-') frames = std::atoi(argv[argi++]);
  ArrayOptions opt;
  bool tell_all = false, quiet = false, one_shot = false, still = false;
  std::array<bool, 3> periodic{false, false, false};
  std::string compare;
  std::uint64_t seed = 1;
  for (; argi < argc; ++argi) {
    const std::string a = argv[argi];
    if (a == "--threads" && argi + 1 < argc)
      opt.threads = std::atoi(argv[++argi]);
    else if (a == "--skin" && argi + 1 < argc)
      opt.skin = std::atof(argv[++argi]);
    else if (a == "--spare" && argi + 1 < argc)  // ArrayOptions::spare_bytes
      opt.spare_bytes = std::strtoull(argv[++argi], nullptr, 10);
    else if (a == "--all")
      tell_all = true;
    else if (a == "--quiet")
      quiet = true;
    else if (a == "--one-shot")  // find_pairs afresh every frame, no tracker
      one_shot = true;
    else if (a == "--compare" && argi + 1 < argc)
      compare = argv[++argi];
    else if (a == "--seed" && argi + 1 < argc)
      seed = std::strtoull(argv[++argi], nullptr, 10);
    else if (a == "--periodic" && argi + 1 < argc)
      periodic = parse_periodic_axes(argv[++argi]);
    else if (a == "--static")
      still = true;
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }

  const bool wraps = periodic[0] || periodic[1] || periodic[2];
  // The scene as `gen` makes it with --periodic, stopped with --static.
  auto make_scene = [&] {
    Scene s = generate(dist, n, seed);
    if (wraps) make_periodic(s, periodic);
    if (still)
      for (Vec3& v : s.velocity) v = {0, 0, 0};
    return s;
  };
  const auto g0 = Clock::now();
  Scene scene = make_scene();
  const PeriodicCell cell = scene.cell();
  const double gen_s = std::chrono::duration<double>(Clock::now() - g0).count();
  ArrayCaller caller(scene);  // the caller's columns (lab/array_caller.hpp)
  scene = Scene{};            // the caller keeps only its arrays
  std::printf("# %s n=%zu frames=%d threads=%u skin=%g changes=%s generate=%.1fs movers=%zu\n",
              argv[1], n, frames, opt.threads, opt.skin, tell_all ? "all" : "movers", gen_s,
              caller.movers().size());
  const long rss_before = status_kb("VmRSS:");

  std::vector<FrameDigest> digests;
  std::vector<double> call_ms, move_ms, cpu_call_ms;
  PairTracker tracker(opt);
  PeriodicPairTracker wrapping(cell, opt);
  std::size_t rebuilds = 0;
  for (int f = 0; f < frames; ++f) {
    const auto t0 = Clock::now();
    if (f > 0) caller.step();
    const auto t1 = Clock::now();
    const double c1 = cpu_ms();
    FrameDigest d;
    const PairSink digest = [&](std::span<const IndexPair> c) {
      for (const IndexPair& p : c) d.add(p.i, p.j);
      return true;
    };
    const ShiftedPairSink shifted = [&](std::span<const ShiftedPair> c) {
      for (const ShiftedPair& p : c) d.add(p.i, p.j, p.shift);
      return true;
    };
    const Changes changes =
        f == 0 || tell_all ? Changes::everything() : Changes::only(caller.movers());
    const auto stats = wraps ? (one_shot ? find_pairs(caller.objects(), cell, shifted, opt)
                                         : wrapping.find_pairs(caller.objects(), shifted, changes))
                             : (one_shot ? find_pairs(caller.objects(), digest, opt)
                                         : tracker.find_pairs(caller.objects(), digest, changes));
    const auto t2 = Clock::now();
    cpu_call_ms.push_back(cpu_ms() - c1);
    digests.push_back(d);
    rebuilds += stats.rebuilt;
    move_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    call_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
    if (!quiet)
      std::printf(
          "%d %llu %s %.2f ms (cpu %.2f)%s renewed %llu, quiet %llu, tests %llu, own %.1f "
          "B/object\n",
          f, static_cast<unsigned long long>(d.pairs), hex16(d.hash).c_str(), call_ms.back(),
          cpu_call_ms.back(), stats.rebuilt ? " rebuilt" : (stats.compacted ? " compacted" : ""),
          static_cast<unsigned long long>(stats.renewed),
          static_cast<unsigned long long>(stats.quiet),
          static_cast<unsigned long long>(stats.tests),
          static_cast<double>(wraps ? wrapping.memory_bytes() : tracker.memory_bytes()) /
              static_cast<double>(n));
  }
  // The first call builds; the frame figure is the median of the others.
  std::vector<double> later(call_ms.begin() + (frames > 1 ? 1 : 0), call_ms.end());
  std::vector<double> later_move(move_ms.begin() + (frames > 1 ? 1 : 0), move_ms.end());
  std::vector<double> later_cpu(cpu_call_ms.begin() + (frames > 1 ? 1 : 0), cpu_call_ms.end());
  const double own = static_cast<double>(wraps ? wrapping.memory_bytes() : tracker.memory_bytes()) /
                     static_cast<double>(n);
  std::printf(
      "arrays: first call %.1f ms, median call %.3f ms (cpu %.3f, mean cpu %.3f), median move "
      "%.2f ms, frame %.2f ms, rebuilds %zu, own %.1f B/object, scratch kept %.1f B/object, caller "
      "%.1f B/object, VmRSS %ld kB "
      "(before tracker "
      "%ld kB), VmHWM %ld kB\n",
      call_ms[0], median(later), median(later_cpu),
      later_cpu.empty() ? 0.0
                        : std::accumulate(later_cpu.begin(), later_cpu.end(), 0.0) /
                              static_cast<double>(later_cpu.size()),
      median(later_move), median(later) + median(later_move), rebuilds, own,
      static_cast<double>(scratch_bytes()) / static_cast<double>(n),
      static_cast<double>(caller.bytes()) / static_cast<double>(n), status_kb("VmRSS:"), rss_before,
      status_kb("VmHWM:"));

  if (!compare.empty()) {
    Scene fresh = make_scene();
    Config config;
    config.world = {{0, 0, 0}, {fresh.world, fresh.world, fresh.world}};
    config.expected_objects = n;
    auto bp = make_structure(compare, config);
    Replay replay(*bp, std::move(fresh));
    std::vector<double> ms, cms;
    int mismatches = 0;
    std::printf("%s: build %.1f ms\n", compare.c_str(), replay.build_seconds() * 1e3);
    for (int f = 0; f < frames; ++f) {
      const double c0 = cpu_ms();
      const FrameResult r = replay.next();
      if (f == 0) std::printf("%s: first frame %.1f ms\n", compare.c_str(), r.seconds() * 1e3);
      if (f > 0) ms.push_back(r.seconds() * 1e3);
      if (f > 0) cms.push_back(cpu_ms() - c0);
      if (!(r.digest == digests[static_cast<std::size_t>(f)])) ++mismatches;
    }
    std::printf(
        "%s: median frame %.2f ms (cpu %.2f incl. the motion, mean cpu %.2f), memory %.1f "
        "B/object, frames disagreeing: %d\n",
        compare.c_str(), median(ms), median(cms),
        cms.empty()
            ? 0.0
            : std::accumulate(cms.begin(), cms.end(), 0.0) / static_cast<double>(cms.size()),
        static_cast<double>(replay.periodic() != nullptr ? replay.periodic()->memory_bytes()
                                                         : bp->memory_bytes()) /
            static_cast<double>(n),
        mismatches);
    if (mismatches) return 1;
  }
  return 0;
}
