// `list`, `run` and `gen`: the structures, the replay contract, and scenes.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <broadphase/detail/median.hpp>
#include <broadphase/scenes/brute_force.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_checks.hpp"
#include "commands.hpp"

namespace broadphase::app {

void add_list_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("list", "List the structures (name, then a one-line description)");
  cmd->callback([] {
    for (const StructureInfo& e : registry().entries())
      std::printf("%-18s %s%s\n", e.name.c_str(), e.peer ? "[peer] " : "", e.description.c_str());
    for (const StructureAlias& a : registry().aliases())
      std::printf("%-18s alias of %s (its former name)\n", a.alias.c_str(), a.name.c_str());
  });
}

namespace {

using broadphase::detail::median;

struct RunOptions {
  std::string scene;
  std::string algo;
  int frames = 100;
  bool json = false;
  bool arrays = false;
  bool oracle = false;
};

// Frame lines, written in blocks of 64 KiB; `flush()` also before an error,
// so that the frames done are printed before it.
class Lines {
 public:
  explicit Lines(bool quiet) : quiet_(quiet) {}
  void add(const std::string& line) {
    if (quiet_) return;
    out_ += line;
    out_ += '\n';
    if (out_.size() > (1u << 16)) flush();
  }
  void flush() {
    std::fwrite(out_.data(), 1, out_.size(), stdout);
    out_.clear();
  }

 private:
  bool quiet_;
  std::string out_;
};

// The contract's totals over a replay, and the JSON fields they make.
struct Totals {
  FrameDigest pairs;
  HitDigest hits;
  void add(const FrameDigest& p, const HitDigest& h) {
    pairs.pairs += p.pairs;
    pairs.hash += p.hash;
    hits.hits += h.hits;
    hits.hash += h.hash;
    hits.closest += h.closest;
  }
  void put(nlohmann::ordered_json& j, bool rays) const {
    j["pairs_total"] = pairs.pairs;
    j["hash_total"] = hex16(pairs.hash);
    if (!rays) return;
    j["hits_total"] = hits.hits;
    j["hits_hash_total"] = hex16(hits.hash);
    j["closest_hash_total"] = hex16(hits.closest);
  }
};

// `run --oracle`: the scene by brute force, straight from the contract.
void run_oracle(const RunOptions& o) {
  BruteForceReplay replay(read_scene(o.scene));
  const bool rays = replay.scene().has_rays();
  const std::size_t n = replay.scene().size();
  Lines lines(o.json);
  Totals total;
  for (int f = 0; f < o.frames; ++f) {
    BruteForceFrame r;
    try {
      r = replay.next();
    } catch (...) {
      lines.flush();
      throw;
    }
    total.add(r.pairs, r.hits);
    lines.add(frame_line(f, r.pairs, rays ? &r.hits : nullptr));
  }
  lines.flush();
  if (!o.json) return;
  nlohmann::ordered_json j;
  j["algo"] = "oracle";
  j["scene"] = o.scene;
  j["n"] = n;
  j["rays"] = replay.scene().rays.size();
  j["frames"] = o.frames;
  total.put(j, rays);
  std::printf("%s\n", j.dump(2).c_str());
}

void run(const RunOptions& o) {
  if (o.arrays) return run_arrays(o.scene, o.frames, o.json);
  if (o.oracle) return run_oracle(o);
  Scene scene = read_scene(o.scene);
  Config config;
  // A periodic scene's structure holds the images too (periodic.hpp), just
  // outside [0, L]; the world box stays the cell: the region most objects
  // live in.
  config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  config.expected_objects = scene.size();
  auto bp = registry().make(o.algo, config);
  const std::size_t n = scene.size();
  const bool rays = scene.has_rays();
  const std::size_t ray_count = scene.rays.size();
  Replay replay(*bp, std::move(scene));

  Totals total;
  std::uint64_t tests = 0;
  std::vector<double> frame_ms;
  double total_ms = 0, rays_ms = 0;
  Lines lines(o.json);
  for (int f = 0; f < o.frames; ++f) {
    FrameResult r;
    try {
      r = replay.next();
    } catch (...) {
      lines.flush();
      throw;
    }
    total.add(r.digest, r.hits);
    tests += r.tests;
    frame_ms.push_back(r.seconds() * 1e3);
    total_ms += r.seconds() * 1e3;
    rays_ms += r.rays_seconds * 1e3;
    lines.add(frame_line(f, r, rays));
  }
  lines.flush();
  if (!o.json) return;
  nlohmann::ordered_json j;
  j["algo"] = o.algo;
  j["scene"] = o.scene;
  j["n"] = n;
  j["frames"] = o.frames;
  total.put(j, rays);
  j["tests_total"] = tests;
  j["median_frame_ms"] = median(frame_ms);
  j["total_ms"] = total_ms;
  if (rays) {
    j["rays"] = ray_count;
    j["rays_total_ms"] = rays_ms;
  }
  j["build_ms"] = replay.build_seconds() * 1e3;
  if (const PeriodicBroadPhase* p = replay.periodic()) {
    j["periodic"] = periodic_axes_text(p->cell().periodic);
    j["images"] = p->image_count();
    j["memory_bytes"] = p->memory_bytes();
  } else {
    j["memory_bytes"] = bp->memory_bytes();
  }
  std::printf("%s\n", j.dump(2).c_str());
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "run",
      "Replay a scene and print one line a frame: 'frame pairs hash', and with rays (version 3) "
      "'frame pairs hash hits hits_hash closest_hash' (docs/scene-format.md)");
  auto o = std::make_shared<RunOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (docs/scene-format.md)")->required();
  cmd->add_option("--algo", o->algo, "Structure name, optionally with options: name:key=value,...")
      ->default_val("naive");
  cmd->add_option("--frames", o->frames, "Number of frames to evaluate")
      ->default_val(100)
      ->check(CLI::Range(1, 100000000));
  cmd->add_flag("--json", o->json, "Print one JSON summary instead of one line per frame");
  auto* arrays =
      cmd->add_flag("--arrays", o->arrays,
                    "Replay through the lean path over arrays (PairTracker, docs/arrays.md) "
                    "instead of a structure; --algo is then ignored");
  cmd->add_flag("--oracle", o->oracle,
                "Replay by brute force straight from the contract (every pair, every ray "
                "against every object), independent of the structures; --algo is then ignored")
      ->excludes(arrays);
  cmd->callback([o] { run(*o); });
}

void add_gen_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "gen", "Generate a workload as a scene file, optionally with filters and rays (version 3)");
  struct GenOptions {
    std::string dist, out, filters, ray_kind = "mixed";
    std::size_t n = 0, rays = 0;
    std::uint64_t seed = 1;
    int layers = 0;
    std::string periodic;
  };
  auto o = std::make_shared<GenOptions>();
  cmd->add_option("--dist", o->dist,
                  "even | uneven | scaled-even | scaled-uneven (the study); clusters | decades | "
                  "all-moving | explosion | flat | coincident | outside (stress kinds); boxes | "
                  "half-boxes | box-decades | city (box worlds); shapes-uneven | shapes-decades | "
                  "shapes-flat (poles, slabs and boxes beside spheres)")
      ->required();
  cmd->add_option("--n", o->n, "Number of objects")
      ->required()
      ->check(whole_number() & CLI::Range(0ul, 100000000ul));
  cmd->add_option("--seed", o->seed, "Random seed")->default_val(1)->check(whole_number());
  cmd->add_option("--out", o->out, "Output scene file")->required();
  cmd->add_option("--filters", o->filters,
                  "Give the objects filters (version 3): layers (see --layers) | random (random "
                  "group and mask bits over 8 groups)")
      ->check(CLI::IsMember({"layers", "random"}));
  cmd->add_option("--layers", o->layers,
                  "Objects in K layers (1 to 32): group 1 << layer, each layer pairing with itself "
                  "and its two neighbours only (implies --filters layers; default 4)")
      ->check(CLI::Range(1, 32));
  cmd->add_option("--rays", o->rays, "Number of rays to add (version 3), cast every frame")
      ->check(whole_number() & CLI::Range(0ul, 100000000ul));
  cmd->add_option("--ray-kind", o->ray_kind,
                  "mixed (a share of each) | random (random points and directions) | lidar (a fan "
                  "from one point) | axis (along cell faces, edges and through corners) | inside "
                  "(starting inside objects) | zero (direction 0); tmax mixes inf, 0 and finite")
      ->default_val("mixed");
  auto* periodic_opt =
      cmd->add_option("--periodic", o->periodic,
                      "Make the world periodic on AXES (version 3; x, y and/or z: xyz bulk, xy a "
                      "slab, x a tube): centres wrapped into [0, L), sizes kept below L/2, motion "
                      "wrapping");
  cmd->callback([o, periodic_opt] {
    std::array<bool, 3> periodic{false, false, false};
    if (periodic_opt->count() > 0) {
      try {
        periodic = parse_periodic_axes(o->periodic);
      } catch (const std::invalid_argument& e) {
        throw UsageError(std::string("--periodic: ") + e.what());
      }
    }
    Distribution d;
    try {
      d = parse_distribution(o->dist);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--dist: ") + e.what());
    }
    RayKind ray_kind;
    try {
      ray_kind = parse_ray_kind(o->ray_kind);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--ray-kind: ") + e.what());
    }
    if (o->layers > 0 && o->filters == "random")
      throw UsageError("--layers gives layered filters; it does not go with --filters random");
    Scene scene = generate(d, o->n, o->seed);
    // Before the rays, which may start anywhere (they do not wrap).
    if (periodic[0] || periodic[1] || periodic[2]) make_periodic(scene, periodic);
    if (o->layers > 0 || o->filters == "layers")
      add_filters(scene, FilterKind::layers, o->layers > 0 ? o->layers : 4, o->seed);
    else if (o->filters == "random")
      add_filters(scene, FilterKind::random, 0, o->seed);
    if (o->rays > 0) add_rays(scene, o->rays, ray_kind, o->seed);
    write_scene(o->out, scene);
  });
}

}  // namespace broadphase::app
