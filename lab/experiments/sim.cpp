// Lab experiment: tunneling. Contacts a discrete step misses per 1000
// frames, and the cost of a frame, for the three ways of finding contacts,
// on a scene made to tunnel and on the study's workload.
#include <algorithm>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/scenes/sim.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "experiment.hpp"
#include "structures.hpp"

namespace broadphase::app {

namespace {

struct Row {
  std::string scene;
  std::size_t n = 0;
  std::string ccd;
  int frames = 0;
  std::uint64_t true_contacts = 0, missed = 0, contacts = 0;
  double median_ms = 0;
  double energy_drift = 0;  // relative, |E_end − E_0| / E_0
};

/// The structure the experiment runs on: the first of --algos, else the
/// first library structure that is not the brute-force oracle.
std::string pick_structure(const LabContext& ctx) {
  if (!ctx.algos.empty()) return ctx.algos.front();
  for (const StructureInfo& e : registry().entries())
    if (!e.peer && e.name != "naive") return e.name;
  return "naive";
}

Row measure(const std::string& name, const Scene& scene, const std::string& algo, Ccd ccd,
            int max_frames, double seconds) {
  SimConfig c;
  c.ccd = ccd;
  Config bc;
  bc.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  bc.expected_objects = scene.size();
  Simulation sim(scene, registry().make(algo, bc), c);
  Row r;
  r.scene = name;
  r.n = scene.size();
  r.ccd = std::string(to_string(ccd));
  std::vector<double> ms;
  const auto start = std::chrono::steady_clock::now();
  // At least two frames, then as many as the time share allows.
  while (r.frames < max_frames) {
    const StepStats st = sim.step();
    ++r.frames;
    r.true_contacts += st.true_contacts;
    r.missed += st.missed;
    r.contacts += st.contacts;
    ms.push_back(st.seconds * 1e3);
    const double spent =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (r.frames >= 2 && spent > seconds) break;
  }
  std::sort(ms.begin(), ms.end());
  r.median_ms =
      ms.size() % 2 ? ms[ms.size() / 2] : 0.5 * (ms[ms.size() / 2 - 1] + ms[ms.size() / 2]);
  const double e0 = kinetic_energy(scene);
  r.energy_drift = e0 > 0 ? std::fabs(kinetic_energy(sim.scene()) - e0) / e0 : 0;
  return r;
}

}  // namespace

namespace {

std::string lab_tunneling(const LabContext& ctx) {
  const std::string algo = pick_structure(ctx);
  struct Case {
    std::string name;
    Scene scene;
    int frames;
  };
  const std::size_t n_tunnel = ctx.capped(200), n_even = ctx.capped(6400);
  const std::vector<Case> cases = {
      {"tunnel-" + std::to_string(n_tunnel), make_tunnel_scene(n_tunnel, ctx.seed),
       ctx.quick ? 200 : 1000},
      {"even-" + std::to_string(n_even), generate(Distribution::even, n_even, ctx.seed),
       ctx.quick ? 3 : 200},
  };
  const Ccd modes[] = {Ccd::off, Ccd::substep, Ccd::swept};
  const double share = (ctx.quick ? std::min(ctx.budget_seconds, 6.0) : ctx.budget_seconds) / 6;
  std::vector<Row> rows;
  int done = 0;
  for (const Case& c : cases)
    for (const Ccd m : modes) {
      if (ctx.progress)
        ctx.progress("tunneling: " + c.name + " " + std::string(to_string(m)), done / 6.0);
      rows.push_back(measure(c.name, c.scene, algo, m, c.frames, share));
      ++done;
    }

  const auto csv_path = ctx.out_dir / "tunneling.csv";
  std::ofstream csv(csv_path);
  csv << "scene,n,algo,ccd,frames,true_contacts,missed,missed_per_1000_frames,contacts,"
         "median_frame_ms,energy_drift\n";
  std::string md =
      "## Tunneling\n\n"
      "A fast small object can cross another between two frames. Missed contacts are counted "
      "against the exact swept-sphere ground truth (time of first contact on straight paths "
      "within each step); cost is the median time of a step without that measurement. "
      "Structure: `" +
      algo +
      "`, restitution 1, dt 1 (docs/simulation.md).\n\n"
      "| scene | objects | ccd | frames | true contacts | missed | missed / 1000 frames | "
      "median ms / frame | × off |\n"
      "|---|---:|---|---:|---:|---:|---:|---:|---:|\n";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    const Row& off = rows[i - i % 3];
    const double per_1000 = 1000.0 * static_cast<double>(r.missed) / r.frames;
    char line[512];
    std::snprintf(line, sizeof line, "%s,%zu,%s,%s,%d,%llu,%llu,%.3f,%llu,%.4f,%.3g\n",
                  r.scene.c_str(), r.n, algo.c_str(), r.ccd.c_str(), r.frames,
                  static_cast<unsigned long long>(r.true_contacts),
                  static_cast<unsigned long long>(r.missed), per_1000,
                  static_cast<unsigned long long>(r.contacts), r.median_ms, r.energy_drift);
    csv << line;
    std::snprintf(line, sizeof line, "| %s | %zu | %s | %d | %llu | %llu | %.1f | %.3f | %.1f |\n",
                  r.scene.c_str(), r.n, r.ccd.c_str(), r.frames,
                  static_cast<unsigned long long>(r.true_contacts),
                  static_cast<unsigned long long>(r.missed), per_1000, r.median_ms,
                  off.median_ms > 0 ? r.median_ms / off.median_ms : 0.0);
    md += line;
  }
  md +=
      "\n`swept` registers every contact of the ground truth by construction; `substep` "
      "misses the grazing ones that fall between two of an object's substeps; `off` misses "
      "whatever a frame boundary does not catch inside. Data: `tunneling.csv`.\n";
  if (ctx.progress) ctx.progress("tunneling", 1.0);
  return md;
}

const RegisterExperiment kRegistered{
    {"tunneling", 50, "tunneling with and without continuous collision detection", lab_tunneling}};

}  // namespace

}  // namespace broadphase::app
