// `list`, `run` and `gen`: the structures, the replay contract, and scenes.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <broadphase/detail/median.hpp>
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
};

void run(const RunOptions& o) {
  if (o.arrays) return run_arrays(o.scene, o.frames, o.json);
  Scene scene = read_scene(o.scene);
  Config config;
  config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  config.expected_objects = scene.size();
  auto bp = registry().make(o.algo, config);
  const std::size_t n = scene.size();
  Replay replay(*bp, std::move(scene));

  FrameDigest total;
  std::uint64_t tests = 0;
  std::vector<double> frame_ms;
  double total_ms = 0;
  std::string out;
  for (int f = 0; f < o.frames; ++f) {
    FrameResult r;
    try {
      r = replay.next();
    } catch (...) {
      // The frames done so far are printed before the error.
      if (!o.json) std::fwrite(out.data(), 1, out.size(), stdout);
      throw;
    }
    total.pairs += r.digest.pairs;
    total.hash += r.digest.hash;
    tests += r.tests;
    frame_ms.push_back(r.seconds() * 1e3);
    total_ms += r.seconds() * 1e3;
    if (!o.json) {
      out += std::to_string(f) + ' ' + std::to_string(r.digest.pairs) + ' ' + hex16(r.digest.hash) +
             '\n';
      if (out.size() > (1u << 16)) {
        std::fwrite(out.data(), 1, out.size(), stdout);
        out.clear();
      }
    }
  }
  if (!o.json) {
    std::fwrite(out.data(), 1, out.size(), stdout);
    return;
  }
  nlohmann::ordered_json j;
  j["algo"] = o.algo;
  j["scene"] = o.scene;
  j["n"] = n;
  j["frames"] = o.frames;
  j["pairs_total"] = total.pairs;
  j["hash_total"] = hex16(total.hash);
  j["tests_total"] = tests;
  j["median_frame_ms"] = median(frame_ms);
  j["total_ms"] = total_ms;
  j["build_ms"] = replay.build_seconds() * 1e3;
  j["memory_bytes"] = bp->memory_bytes();
  std::printf("%s\n", j.dump(2).c_str());
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("run", "Replay a scene and print each frame's pair count and hash");
  auto o = std::make_shared<RunOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (docs/scene-format.md)")->required();
  cmd->add_option("--algo", o->algo, "Structure name, optionally with options: name:key=value,...")
      ->default_val("naive");
  cmd->add_option("--frames", o->frames, "Number of frames to evaluate")
      ->default_val(100)
      ->check(CLI::Range(1, 100000000));
  cmd->add_flag("--json", o->json, "Print one JSON summary instead of one line per frame");
  cmd->add_flag("--arrays", o->arrays,
                "Replay through the lean path over arrays (PairTracker, docs/arrays.md) "
                "instead of a structure; --algo is then ignored");
  cmd->callback([o] { run(*o); });
}

void add_gen_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("gen", "Generate one of the study's workloads as a scene file");
  struct GenOptions {
    std::string dist, out;
    std::size_t n = 0;
    std::uint64_t seed = 1;
  };
  auto o = std::make_shared<GenOptions>();
  cmd->add_option("--dist", o->dist,
                  "even | uneven | scaled-even | scaled-uneven (the study); clusters | decades | "
                  "all-moving | explosion | flat | coincident | outside (stress kinds); boxes | "
                  "half-boxes | box-decades | city (box worlds)")
      ->required();
  cmd->add_option("--n", o->n, "Number of objects")
      ->required()
      ->check(whole_number() & CLI::Range(0ul, 100000000ul));
  cmd->add_option("--seed", o->seed, "Random seed")->default_val(1)->check(whole_number());
  cmd->add_option("--out", o->out, "Output scene file")->required();
  cmd->callback([o] {
    Distribution d;
    try {
      d = parse_distribution(o->dist);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--dist: ") + e.what());
    }
    write_scene(o->out, generate(d, o->n, o->seed));
  });
}

}  // namespace broadphase::app
