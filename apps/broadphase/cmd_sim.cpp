// `sim`: steps a scene with collision response over any structure, and
// measures the contacts a discrete step misses.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/scenes/sim.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_checks.hpp"
#include "commands.hpp"

namespace broadphase::app {

namespace {

struct SimOptions {
  std::string scene;
  std::string algo = "naive";
  int frames = 100;
  double restitution = 1;
  double dt = 1;
  std::string ccd = "off";
  std::string out;
  bool json = false;
  bool series = false;
  std::string make_tunnel;
  std::string make_billiards;
  bool flat = false;
  std::size_t bullets = 200;
  std::size_t balls = 30;
  std::uint64_t seed = 1;
};

nlohmann::json vec(const Vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }

using broadphase::detail::median;

void run_sim(const SimOptions& o) {
  if (!o.make_tunnel.empty())
    write_scene(o.make_tunnel, make_tunnel_scene(o.bullets, o.seed, o.flat));
  if (!o.make_billiards.empty())
    write_scene(o.make_billiards, make_billiards_scene(o.balls, o.seed));
  if (o.scene.empty() && (!o.make_tunnel.empty() || !o.make_billiards.empty())) return;
  if (o.scene.empty()) throw UsageError("sim: --scene is required");
  SimConfig config;
  try {
    config.ccd = parse_ccd(o.ccd);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--ccd: ") + e.what());
  }
  config.restitution = o.restitution;
  config.dt = o.dt;
  Scene scene = read_scene(o.scene);
  // The response and its brute-force count of true contacts know no
  // filters yet: refuse rather than collide objects that ignore each other.
  // (Rays play no part in a simulation.)
  if (scene.has_filters())
    throw SceneError(o.scene + ": sim does not take filters yet; run this scene with `run`");
  // Its response and contact count know no images: refuse a periodic world.
  if (scene.is_periodic())
    throw SceneError(o.scene +
                     ": sim does not take periodic worlds yet; run this scene with `run`");
  Config bp_config;
  bp_config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  bp_config.expected_objects = scene.size();
  const double e0 = kinetic_energy(scene);
  const Vec3 p0 = momentum(scene);
  const std::size_t n = scene.size();
  Simulation sim(std::move(scene), registry().make(o.algo, bp_config), config);

  StepStats total;
  std::vector<double> frame_ms;
  nlohmann::json series = nlohmann::json::object();
  std::string text = "# frame contacts wall_hits true_contacts missed kinetic_energy\n";
  for (int f = 0; f < o.frames; ++f) {
    StepStats st;
    try {
      st = sim.step();
    } catch (const InvalidShape&) {
      // Only the motion can make a valid scene's shape invalid: name the
      // frame and the object, as `run` does; the steps done are printed.
      if (!o.json) std::fwrite(text.data(), 1, text.size(), stdout);
      const Scene& s = sim.scene();
      for (std::size_t i = 0; i < s.size(); ++i) {
        const Vec3 c = s.objects[i].center, v = s.velocity[i] * o.dt;
        if (!is_valid(s.objects[i]) || !std::isfinite(c.x + v.x) || !std::isfinite(c.y + v.y) ||
            !std::isfinite(c.z + v.z))
          throw SceneError("frame " + std::to_string(f) + ": object " + std::to_string(i) +
                           " moves beyond the range of doubles (its motion overflows)");
      }
      throw;
    }
    total.contacts += st.contacts;
    total.wall_hits += st.wall_hits;
    total.true_contacts += st.true_contacts;
    total.missed += st.missed;
    total.tests += st.tests;
    total.evaluations += st.evaluations;
    total.max_penetration = std::max(total.max_penetration, st.max_penetration);
    frame_ms.push_back(st.seconds * 1e3);
    if (o.json && o.series) {
      series["contacts"].push_back(st.contacts);
      series["missed"].push_back(st.missed);
      series["kinetic_energy"].push_back(st.kinetic_energy);
      series["momentum"].push_back(vec(st.momentum));
    }
    if (!o.json) {
      char line[160];
      std::snprintf(line, sizeof line, "%d %llu %llu %llu %llu %.17g\n", f,
                    static_cast<unsigned long long>(st.contacts),
                    static_cast<unsigned long long>(st.wall_hits),
                    static_cast<unsigned long long>(st.true_contacts),
                    static_cast<unsigned long long>(st.missed), st.kinetic_energy);
      text += line;
    }
  }
  if (!o.out.empty()) write_scene(o.out, sim.scene());
  if (!o.json) {
    std::fwrite(text.data(), 1, text.size(), stdout);
    return;
  }
  double total_ms = 0;
  for (double ms : frame_ms) total_ms += ms;
  nlohmann::ordered_json j;
  j["algo"] = o.algo;
  j["scene"] = o.scene;
  j["n"] = n;
  j["frames"] = o.frames;
  j["ccd"] = o.ccd;
  j["restitution"] = o.restitution;
  j["dt"] = o.dt;
  j["contacts"] = total.contacts;
  j["wall_hits"] = total.wall_hits;
  j["true_contacts"] = total.true_contacts;
  j["missed"] = total.missed;
  j["missed_per_1000_frames"] = 1000.0 * static_cast<double>(total.missed) / o.frames;
  j["kinetic_energy_start"] = e0;
  j["kinetic_energy_end"] = kinetic_energy(sim.scene());
  j["momentum_start"] = vec(p0);
  j["momentum_end"] = vec(momentum(sim.scene()));
  j["max_penetration"] = total.max_penetration;
  j["tests_total"] = total.tests;
  j["evaluations_total"] = total.evaluations;
  j["median_frame_ms"] = median(frame_ms);
  j["total_ms"] = total_ms;
  if (o.series) j["series"] = series;
  std::printf("%s\n", j.dump(2).c_str());
}

}  // namespace

void add_sim_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "sim", "Step a scene with collision response (bounces off walls and each other)");
  auto o = std::make_shared<SimOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (docs/scene-format.md)");
  cmd->add_option("--algo", o->algo, "Broad phase: name or name:key=value,...")
      ->default_val("naive");
  cmd->add_option("--frames", o->frames, "Number of steps")
      ->default_val(100)
      ->check(CLI::Range(1, 100000000));
  cmd->add_option("--restitution", o->restitution, "k in [0, 1]: 1 elastic, 0 plastic")
      ->default_val(1)
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--dt", o->dt, "Step length in frames (velocities are per frame)")
      ->default_val(1)
      ->check(positive_number());
  cmd->add_option("--ccd", o->ccd, "off | substep | swept")->default_val("off");
  cmd->add_option("--out", o->out, "Write the final positions and velocities as a scene file");
  cmd->add_flag("--json", o->json, "Print one JSON summary instead of one line per step");
  cmd->add_flag("--series", o->series, "With --json: add the per-step series");
  cmd->add_option("--make-tunnel-scene", o->make_tunnel,
                  "Write the tunneling scene (small fast bullets, thin static targets) to FILE");
  cmd->add_option("--bullets", o->bullets, "Bullets in the tunneling scene")
      ->default_val(200)
      ->check(whole_number() & CLI::Range(0ul, 10000000ul));
  cmd->add_flag("--flat", o->flat, "Tunneling scene in one plane (z = 100), for side views");
  cmd->add_option("--make-billiards-scene", o->make_billiards,
                  "Write a flat billiards scene (balls in the plane z = 50) to FILE");
  cmd->add_option("--balls", o->balls, "Balls in the billiards scene")
      ->default_val(30)
      ->check(whole_number() & CLI::Range(0ul, 100000ul));
  cmd->add_option("--seed", o->seed, "Seed of the generated scenes")
      ->default_val(1)
      ->check(whole_number());
  cmd->callback([o] { run_sim(*o); });
}

}  // namespace broadphase::app
