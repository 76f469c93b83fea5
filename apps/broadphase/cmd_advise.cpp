// `advise`: times the candidate structures briefly on the user's scene and
// recommends the fastest one whose pairs agree with the others.
#include <CLI/CLI.hpp>
#include <broadphase/scenes/scene.hpp>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "timing.hpp"

namespace broadphase::app {

namespace {

struct AdviseOptions {
  std::string scene;
  int frames = 100;
  std::string algos;
  double seconds = 10;
  bool json = false;
};

std::vector<std::string> split_list(const std::string& list) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(list);
  while (std::getline(in, item, ';')) {
    // Commas separate structures, except inside one structure's options
    // (`grid-verlet:threads=2,cell=3`): a piece with '=' and no ':' continues
    // the previous structure.
    std::string cur;
    std::istringstream parts(item);
    std::string piece;
    while (std::getline(parts, piece, ',')) {
      if (!cur.empty() && piece.find('=') != std::string::npos &&
          piece.find(':') == std::string::npos) {
        cur += ',' + piece;
        continue;
      }
      if (!cur.empty()) out.push_back(cur);
      cur = piece;
    }
    if (!cur.empty()) out.push_back(cur);
  }
  return out;
}

void advise(const AdviseOptions& o) {
  Scene scene = read_scene(o.scene);
  const Registry& reg = registry();
  std::vector<std::string> specs;
  if (o.algos.empty()) {
    specs = advise_candidates(reg, scene.size(), true);
  } else {
    specs = split_list(o.algos);
    if (specs.empty()) throw UsageError("--algos: empty list");
    for (const std::string& s : specs) {
      const std::string name = s.substr(0, s.find(':'));
      if (reg.find(name) == nullptr)
        throw UsageError("--algos: unknown structure '" + name + "'; valid: " + reg.names());
      try {
        reg.make(s);  // rejects bad options before any timing starts
      } catch (const InvalidConfig& e) {
        throw UsageError(std::string("--algos: ") + e.what());
      }
    }
  }
  const TimingLimits limits = advise_limits(o.frames, o.seconds, specs.size());
  const Advice a =
      advise_on(reg, specs, scene, limits, [&](std::size_t k, const StructureTiming& t) {
        if (!t.error.empty())
          std::fprintf(stderr, "advise: [%zu/%zu] %s failed: %s\n", k + 1, specs.size(),
                       specs[k].c_str(), t.error.c_str());
        else
          std::fprintf(stderr, "advise: [%zu/%zu] %s: %zu frames, median %.3f ms, mean %.3f ms\n",
                       k + 1, specs.size(), specs[k].c_str(), t.frame_ms.size(),
                       t.median_frame_ms(), t.mean_frame_ms());
      });
  const std::vector<StructureTiming>& results = a.results;
  const std::vector<bool>& agrees = a.agrees;
  const std::size_t ref = a.ref, best = a.best;
  if (ref < results.size() && 2 * a.agreeing() <= results.size() && results.size() > 2)
    std::fprintf(stderr,
                 "advise: warning: fewer than half the structures agree with %s on the pairs\n",
                 results[ref].spec.c_str());

  const double n = static_cast<double>(scene.size());
  if (o.json) {
    nlohmann::ordered_json j;
    j["scene"] = o.scene;
    j["objects"] = scene.size();
    j["recommended"] = best < results.size() ? results[best].spec : "";
    j["structures"] = nlohmann::json::array();
    for (std::size_t k = 0; k < results.size(); ++k) {
      const StructureTiming& t = results[k];
      nlohmann::ordered_json s;
      s["structure"] = t.spec;
      s["frames"] = t.frame_ms.size();
      s["median_frame_ms"] = t.median_frame_ms();
      s["mean_frame_ms"] = t.mean_frame_ms();
      s["build_ms"] = t.build_ms;
      s["query_us"] = t.query_us;
      s["insert_us"] = t.insert_us;
      s["remove_us"] = t.remove_us;
      s["bytes_per_object"] = n > 0 ? static_cast<double>(t.memory_bytes) / n : 0;
      s["pairs_agree"] = static_cast<bool>(agrees[k]);
      if (!t.error.empty()) s["error"] = t.error;
      j["structures"].push_back(s);
    }
    std::printf("%s\n", j.dump(2).c_str());
    if (ref == results.size()) throw std::runtime_error("advise: no structure could run the scene");
    return;
  }
  std::printf("scene %s: %zu objects\n\n", o.scene.c_str(), scene.size());
  std::printf("%-24s %7s %11s %10s %10s %9s %9s %9s %8s %s\n", "structure", "frames", "frame ms",
              "mean ms", "build ms", "query us", "insert us", "remove us", "B/object", "pairs");
  for (std::size_t k = 0; k < results.size(); ++k) {
    const StructureTiming& t = results[k];
    if (!t.error.empty()) {
      std::printf("%-24s failed: %s\n", t.spec.c_str(), t.error.c_str());
      continue;
    }
    std::printf("%-24s %7zu %11.3f %10.3f %10.1f %9.3f %9.3f %9.3f %8.0f %s%s\n", t.spec.c_str(),
                t.frame_ms.size(), t.median_frame_ms(), t.mean_frame_ms(), t.build_ms, t.query_us,
                t.insert_us, t.remove_us, n > 0 ? static_cast<double>(t.memory_bytes) / n : 0.0,
                agrees[k] ? "agree" : "DIFFER", k == best ? "  <- recommended" : "");
  }
  if (best < results.size())
    std::printf("\nrecommended: %s (median frame %.3f ms, pairs agree with %s)\n",
                results[best].spec.c_str(), results[best].median_frame_ms(),
                results[ref].spec.c_str());
  else
    std::printf("\nno recommendation: no structure finished with agreeing pairs\n");
  if (ref == results.size()) throw std::runtime_error("advise: no structure could run the scene");
}

}  // namespace

void add_advise_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "advise", "Time the structures briefly on a scene and recommend the fastest exact one");
  auto o = std::make_shared<AdviseOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (docs/scene-format.md)")->required();
  cmd->add_option("--frames", o->frames, "Frames per structure at most")
      ->default_val(100)
      ->check(CLI::Range(1, 100000000));
  cmd->add_option("--algos", o->algos,
                  "Structures to compare, comma-separated (default: every structure built)");
  cmd->add_option("--seconds", o->seconds, "Rough total time budget in seconds")
      ->default_val(10)
      ->check(CLI::Range(0.1, 86400.0));
  cmd->add_flag("--json", o->json, "Print JSON instead of a table");
  cmd->callback([o] { advise(*o); });
}

}  // namespace broadphase::app
