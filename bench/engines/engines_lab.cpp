// The engines' lab section: Bullet's step and its broad-phase share with
// btDbvtBroadphase, bt32BitAxisSweep3 and ours (BulletBroadphase over its
// default, kdtree, and grid-verlet) on the test worlds and on 10 000 and 100 000
// falling boxes; FCL's update + collide with its dynamic AABB tree, SaP,
// spatial hash and naive managers against ours, 10^3 to 10^5 objects. The
// whole plan runs `--runs` times, one run after the other, so that the
// machine's load falls on every run alike; the tables give medians over the
// runs and ratios taken within each run.
//
//   engines_lab [--quick] [--out DIR] [--runs R] [--parts bullet,fcl] [--seed S]
//
// Writes bullet.csv, fcl.csv (one row per run), engines.json (the machine,
// the plan, the medians, the targets), section.md and the figure
// engines.png/.svg (tools/plot_engines.py) into DIR (default: the current
// folder); progress on stderr. Exit status 0, 1 when FCL's managers and ours
// disagree on a frame's pairs (the outputs are still written), 2 for bad
// options.
//
// Why a runner of its own and not a section of every `broadphase paper`:
// one run of the plan took 13 minutes of wall-clock time on the 2-core
// Intel VM at load 6 to 9 (Bullet's steps 2.5 minutes of CPU of it), more
// than the paper's budget gives any one experiment, and the Bullet and FCL
// measuring code would put Bullet's worlds and FCL's managers into the lab
// that CI builds twice (Release and ASan); here they are compiled only with
// the benchmarks (BROADPHASE_BUILD_BENCH, off in the sanitized stage), as
// rays_lab is for the rays section.
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <broadphase/scenes/output_file.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bullet_measure.hpp"
#include "fcl_measure.hpp"
#include "lab.hpp"
#include "paper_report.hpp"

namespace {

using broadphase::detail::median;
using broadphase::engines::BulletPlan;
using broadphase::engines::BulletRun;
using broadphase::engines::FclPlan;
using broadphase::engines::FclSizeRun;

double sum(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

/// One Bullet world of the plan.
struct BulletCase {
  std::string label;  ///< "falling 3000": the scene and its bodies
  BulletPlan plan;
};

/// One FCL size of the plan.
struct FclCase {
  FclPlan plan;
};

struct Options {
  bool quick = false;
  std::filesystem::path out = ".";
  int runs = 3;
  bool bullet = true, fcl = true;
  std::uint64_t seed = 1;
};

// The plan. Step counts: the falling boxes come to rest after about 120 of
// the 300 steps (docs/bullet.md), so the medians weigh the pile at rest;
// 10 000 and 100 000 bodies take 60 steps (1 s: the boxes land), what fits
// a run in about five minutes on the 2-core Zen 5 host (a step of 100 000
// costs 0.55 s of CPU under btDbvtBroadphase, 0.27 under ours). 100 000
// took 10 steps before: free fall, in which the dbvt moves no leaf and its
// broad phase (4.6 ms a step) is Bullet's own box computation (4.0 ms with
// a broad phase that only stores the boxes), so no broad phase can be 5
// times below it; docs/bullet.md gives both. bt32BitAxisSweep3 is left out at 100 000: its insertions alone
// took minutes there (docs/lab.md, rays). FCL's SaP and spatial hash stop
// at 10^4 (77 and 129 ms a frame there, growing faster than linearly: SaP's
// update walks end-point lists, the hash's collide builds a set per
// object); naive, every pair tested, runs at 10^3 only.
std::vector<BulletCase> bullet_cases(const Options& o) {
  const std::vector<std::string> ours = {broadphase::engines::bullet_default_structure(),
                                         "grid-verlet"};
  struct Row {
    const char* scene;
    int bodies, steps;
    bool sweep;
  };
  const std::vector<Row> full = {{"falling", 3000, 300, true},  {"pyramid", 1000, 300, true},
                                 {"mixed", 1000, 300, true},    {"groups", 1000, 300, true},
                                 {"ghost", 1000, 300, true},    {"falling", 10000, 60, true},
                                 {"falling", 100000, 60, false}};
  const std::vector<Row> quick = {{"falling", 200, 6, true}, {"pyramid", 55, 6, true},
                                  {"mixed", 60, 6, true},    {"groups", 60, 6, true},
                                  {"ghost", 60, 6, true},    {"falling", 400, 3, false}};
  std::vector<BulletCase> cases;
  for (const Row& r : o.quick ? quick : full) {
    BulletCase c;
    c.label = std::string(r.scene) + " " + std::to_string(r.bodies);
    c.plan.scene = r.scene;
    c.plan.bodies = r.bodies;
    c.plan.steps = r.steps;
    c.plan.seed = o.seed;
    c.plan.sweep = r.sweep;
    c.plan.structures = ours;
    cases.push_back(c);
  }
  return cases;
}

std::vector<FclCase> fcl_cases(const Options& o) {
  struct Row {
    std::size_t n;
    int frames;
    bool sap, hash, naive;
  };
  const std::vector<Row> full = {{1000, 10, true, true, true},
                                 {10000, 10, true, true, false},
                                 {100000, 8, false, false, false}};
  const std::vector<Row> quick = {{300, 2, true, true, true}, {1000, 2, false, false, false}};
  std::vector<FclCase> cases;
  for (const Row& r : o.quick ? quick : full) {
    FclCase c;
    c.plan.n = r.n;
    c.plan.frames = r.frames;
    c.plan.warm = o.quick ? 1 : 2;
    c.plan.seed = o.seed;
    c.plan.sap = r.sap;
    c.plan.hash = r.hash;
    c.plan.naive = r.naive;
    cases.push_back(c);
  }
  return cases;
}

/// A Bullet run's row, as bullet.csv has it.
struct BulletRow {
  int run = 0;
  std::string label, scene, name, structure;
  int bodies = 0, steps = 0, pairs = 0;
  double step_ms = 0, broad_ms = 0, aabbs_ms = 0, share = 0, step_total_s = 0, broad_total_s = 0;
};

/// An FCL manager's row, as fcl.csv has it.
struct FclRow {
  int run = 0;
  std::size_t n = 0, pairs = 0;
  int frames = 0;
  std::string name;
  double register_ms = 0, update_ms = 0, collide_ms = 0, total_ms = 0;
};

std::string num(double v, const char* format = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string quoted(const std::string& s) { return "\"" + s + "\""; }

/// The medians over runs of one contender of one case, and its ratios to the
/// reference (btDbvtBroadphase, or ours for FCL) taken within each run.
struct Summary {
  std::string label, name;
  std::size_t size = 0;
  double a = 0, b = 0, c = 0;       ///< Bullet: step, broad, share; FCL: update, collide, total
  double ratio_a = 0, ratio_b = 0;  ///< Bullet: dbvt/this for broad, step; FCL: this/ours total
  int pairs = 0;
};

std::vector<Summary> bullet_summary(const std::vector<BulletRow>& rows) {
  std::vector<Summary> out;
  for (const BulletRow& r : rows) {
    if (r.run != 1) continue;
    Summary s;
    s.label = r.label;
    s.name = r.name;
    s.size = static_cast<std::size_t>(r.bodies);
    std::vector<double> step, broad, share, vs_broad, vs_step;
    std::vector<double> pairs;
    for (const BulletRow& x : rows) {
      if (x.label != r.label || x.name != r.name) continue;
      step.push_back(x.step_ms);
      broad.push_back(x.broad_ms);
      share.push_back(x.share);
      pairs.push_back(x.pairs);
      for (const BulletRow& ref : rows)
        if (ref.run == x.run && ref.label == x.label && ref.name == "btDbvtBroadphase") {
          vs_broad.push_back(ref.broad_ms / x.broad_ms);
          vs_step.push_back(ref.step_ms / x.step_ms);
        }
    }
    s.a = median(step);
    s.b = median(broad);
    s.c = median(share);
    s.ratio_a = median(vs_broad);
    s.ratio_b = median(vs_step);
    s.pairs = static_cast<int>(median(pairs));
    out.push_back(s);
  }
  return out;
}

std::vector<Summary> fcl_summary(const std::vector<FclRow>& rows) {
  std::vector<Summary> out;
  for (const FclRow& r : rows) {
    if (r.run != 1) continue;
    Summary s;
    s.name = r.name;
    s.size = r.n;
    s.label = std::to_string(r.n);
    s.pairs = static_cast<int>(r.pairs);
    std::vector<double> u, c, t, vs;
    for (const FclRow& x : rows) {
      if (x.n != r.n || x.name != r.name) continue;
      u.push_back(x.update_ms);
      c.push_back(x.collide_ms);
      t.push_back(x.total_ms);
      for (const FclRow& ours : rows)
        if (ours.run == x.run && ours.n == x.n && ours.name.rfind("broadphase", 0) == 0)
          vs.push_back(x.total_ms / ours.total_ms);
    }
    s.a = median(u);
    s.b = median(c);
    s.c = median(t);
    s.ratio_a = median(vs);
    out.push_back(s);
  }
  return out;
}

/// An issue target: what it asks, the measured figure, met or not.
struct Target {
  std::string what;
  double measured = 0, goal = 0;
  bool found = false;
  bool met() const { return found && measured >= goal; }
};

const Summary* find(const std::vector<Summary>& s, const std::string& label,
                    const std::string& name) {
  for (const Summary& x : s)
    if (x.label == label && x.name == name) return &x;
  return nullptr;
}

std::vector<Target> targets(const std::vector<Summary>& bullet, const std::vector<Summary>& fcl,
                            const std::string& ours_bullet, const std::string& ours_fcl) {
  std::vector<Target> out;
  auto bullet_target = [&](const std::string& label, const std::string& what, double goal,
                           bool step) {
    Target t{what, 0, goal, false};
    if (const Summary* s = find(bullet, label, ours_bullet)) {
      t.measured = step ? s->ratio_b : s->ratio_a;
      t.found = true;
    }
    out.push_back(t);
  };
  bullet_target("falling 3000", "Bullet, 3 000 falling boxes: broad phase >= 3x lower than dbvt", 3,
                false);
  bullet_target("falling 3000", "Bullet, 3 000 falling boxes: whole step faster than dbvt", 1,
                true);
  bullet_target("falling 100000", "Bullet, 100 000 bodies: broad phase >= 5x lower than dbvt", 5,
                false);
  bullet_target("falling 100000", "Bullet, 100 000 bodies: whole step faster than dbvt", 1, true);
  Target t{"FCL, 10^5 objects: update + collide >= 5x faster than the dynamic AABB tree", 0, 5,
           false};
  const Summary* tree = find(fcl, "100000", "fcl DynamicAABBTree");
  if (tree != nullptr && find(fcl, "100000", ours_fcl) != nullptr) {
    t.measured = tree->ratio_a;
    t.found = true;
  }
  out.push_back(t);
  return out;
}

std::string section(const broadphase::app::RunInfo& info, const Options& o,
                    const std::vector<Summary>& bullet, const std::vector<Summary>& fcl,
                    const std::vector<Target>& goals, const std::vector<std::string>& errors,
                    bool plotted, double wall_s) {
  std::ostringstream md;
  md << "## Engines: Bullet and FCL with their own broad phases and ours\n\n";
  md << "Measured side by side in one process, " << o.runs << " run" << (o.runs > 1 ? "s" : "")
     << " of the whole plan one after the other" << (o.quick ? " (`--quick`: tiny sizes)" : "")
     << ", on " << info.cpu << " (" << info.cores << " cores), " << info.compiler << ", "
     << info.build_type << ", commit " << info.commit << ", " << info.date
     << ". Times are the thread's CPU time (detail/thread_clock.hpp); each figure is the median "
        "over the runs of a run's median per step or frame, and each ratio the median of the "
        "ratios taken within a run. The whole took "
     << num(wall_s / 60, "%.1f") << " min of wall-clock time.\n\n";
  if (!errors.empty()) {
    md << "**Disagreements** (the run exits with status 1):\n\n";
    for (const std::string& e : errors) md << "- " << e << "\n";
    md << "\n";
  }
  if (plotted) md << "![Bullet and FCL](engines.png)\n\n";
  if (!bullet.empty()) {
    md << "### Bullet: step time and the broad phase's share\n\n"
          "The broad phase is what `btCollisionWorld` spends in `updateAabbs` and "
          "`computeOverlappingPairs`; its share is its total over the step's total. Ratios: "
          "btDbvtBroadphase's time over this broad phase's (above 1: faster than the dbvt).\n\n";
    md << "| world | broad phase | step ms | broad phase ms | share | pairs at the end | "
          "broad phase dbvt/this | step dbvt/this |\n";
    md << "|---|---|---:|---:|---:|---:|---:|---:|\n";
    for (const Summary& s : bullet)
      md << "| " << s.label << " | " << s.name << " | " << num(s.a, "%.3g") << " | "
         << num(s.b, "%.3g") << " | " << num(100 * s.c, "%.1f") << " % | " << s.pairs << " | "
         << num(s.ratio_a, "%.2f") << " | " << num(s.ratio_b, "%.2f") << " |\n";
    md << "\n";
  }
  if (!fcl.empty()) {
    md << "### FCL: update + collide per frame\n\n"
          "The study's scaled-even world (a fifth moving), every other sphere an FCL box; each "
          "frame each manager's `update(moved)` and `collide` with a callback that counts the "
          "pairs whose AABBs overlap (the counts agree every frame). Ratio: this manager's "
          "update + collide over ours.\n\n";
    md << "| objects | manager | update ms | collide ms | update + collide ms | vs ours |\n";
    md << "|---:|---|---:|---:|---:|---:|\n";
    for (const Summary& s : fcl)
      md << "| " << s.size << " (" << s.pairs << " pairs) | " << s.name << " | " << num(s.a, "%.3g")
         << " | " << num(s.b, "%.3g") << " | " << num(s.c, "%.3g") << " | "
         << num(s.ratio_a, "%.2f") << "x |\n";
    md << "\n";
  }
  if (!goals.empty()) {
    md << "### The issue's targets\n\n| target | measured | met |\n|---|---:|---|\n";
    for (const Target& t : goals)
      md << "| " << t.what << " | "
         << (t.found ? num(t.measured, "%.2f") + "x" : std::string("not measured")) << " | "
         << (t.found ? (t.met() ? "yes" : "**no**") : "-") << " |\n";
    md << "\n";
  }
  return md.str();
}

Options parse(int argc, char** argv) {
  Options o;
  bool runs_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--quick") {
      o.quick = true;
    } else if (a == "--out") {
      o.out = value();
    } else if (a == "--runs") {
      const std::string v = value();
      char* end = nullptr;
      const long r = std::strtol(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0' || r < 1 || r > 100)
        throw std::invalid_argument("--runs: '" + v + "' is not a count in [1, 100]");
      o.runs = static_cast<int>(r);
      runs_given = true;
    } else if (a == "--seed") {
      const std::string v = value();
      char* end = nullptr;
      const unsigned long long s = std::strtoull(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0' || v[0] == '-')
        throw std::invalid_argument("--seed: '" + v + "' is not a non-negative integer");
      o.seed = s;
    } else if (a == "--parts") {
      const std::string v = value();
      o.bullet = o.fcl = false;
      std::stringstream in(v);
      for (std::string part; std::getline(in, part, ',');) {
        if (part == "bullet")
          o.bullet = true;
        else if (part == "fcl")
          o.fcl = true;
        else
          throw std::invalid_argument("--parts: '" + part + "' is not bullet or fcl");
      }
      if (!o.bullet && !o.fcl) throw std::invalid_argument("--parts: name bullet, fcl or both");
    } else {
      throw std::invalid_argument("unknown option '" + a + "'");
    }
  }
  if (o.quick && !runs_given) o.runs = 2;
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
    std::filesystem::create_directories(o.out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "engines_lab: %s\n", e.what());
    return 2;
  }
  const auto start = std::chrono::steady_clock::now();
  auto wall = [start] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  try {
    broadphase::app::RunInfo info;
    broadphase::app::fill_provenance(info);
    const std::vector<BulletCase> bcases = o.bullet ? bullet_cases(o) : std::vector<BulletCase>{};
    const std::vector<FclCase> fcases = o.fcl ? fcl_cases(o) : std::vector<FclCase>{};
    std::vector<BulletRow> brows;
    std::vector<FclRow> frows;
    std::vector<std::string> errors;
    std::string ours_bullet, ours_fcl;
    for (int run = 1; run <= o.runs; ++run) {
      for (const BulletCase& c : bcases) {
        std::fprintf(stderr, "%8.1f s  run %d/%d: Bullet, %s, %d steps\n", wall(), run, o.runs,
                     c.label.c_str(), c.plan.steps);
        for (const BulletRun& r : broadphase::engines::measure_bullet(c.plan)) {
          BulletRow row;
          row.run = run;
          row.label = c.label;
          row.scene = c.plan.scene;
          row.bodies = c.plan.bodies;
          row.steps = c.plan.steps;
          row.name = r.name;
          row.structure = r.structure;
          row.pairs = r.pairs;
          row.step_ms = median(r.step_ms);
          row.broad_ms = median(r.broad_ms);
          row.aabbs_ms = r.aabbs_ms / c.plan.steps;
          row.share = sum(r.broad_ms) / sum(r.step_ms);
          row.step_total_s = sum(r.step_ms) / 1000;
          row.broad_total_s = sum(r.broad_ms) / 1000;
          if (r.structure == broadphase::engines::bullet_default_structure()) ours_bullet = r.name;
          brows.push_back(row);
        }
      }
      for (const FclCase& c : fcases) {
        std::fprintf(stderr, "%8.1f s  run %d/%d: FCL, %zu objects, %d frames\n", wall(), run,
                     o.runs, c.plan.n, c.plan.frames);
        FclSizeRun r;
        try {
          r = broadphase::engines::measure_fcl(c.plan);
        } catch (const std::runtime_error& e) {
          errors.push_back("run " + std::to_string(run) + ", FCL: " + e.what());
          std::fprintf(stderr, "engines_lab: %s\n", errors.back().c_str());
          continue;
        }
        ours_fcl = r.managers.front().name;
        for (const auto& m : r.managers) {
          FclRow row;
          row.run = run;
          row.n = r.n;
          row.pairs = r.pairs;
          row.frames = static_cast<int>(m.total_ms.size());
          row.name = m.name;
          row.register_ms = m.register_ms;
          row.update_ms = median(m.update_ms);
          row.collide_ms = median(m.collide_ms);
          row.total_ms = median(m.total_ms);
          frows.push_back(row);
        }
      }
    }

    if (o.bullet) {
      broadphase::OutputFile f(o.out / "bullet.csv");
      std::ostream& out = f.stream();
      out << "run,world,scene,bodies,steps,broadphase,structure,step_ms,broad_ms,aabbs_ms,share,"
             "step_total_s,broad_total_s,pairs\n";
      for (const BulletRow& r : brows)
        out << r.run << ',' << quoted(r.label) << ',' << r.scene << ',' << r.bodies << ','
            << r.steps << ',' << quoted(r.name) << ',' << quoted(r.structure) << ','
            << num(r.step_ms) << ',' << num(r.broad_ms) << ',' << num(r.aabbs_ms) << ','
            << num(r.share) << ',' << num(r.step_total_s) << ',' << num(r.broad_total_s) << ','
            << r.pairs << '\n';
      f.commit();
    }
    if (o.fcl) {
      broadphase::OutputFile f(o.out / "fcl.csv");
      std::ostream& out = f.stream();
      out << "run,n,manager,register_ms,update_ms,collide_ms,total_ms,frames,pairs\n";
      for (const FclRow& r : frows)
        out << r.run << ',' << r.n << ',' << quoted(r.name) << ',' << num(r.register_ms) << ','
            << num(r.update_ms) << ',' << num(r.collide_ms) << ',' << num(r.total_ms) << ','
            << r.frames << ',' << r.pairs << '\n';
      f.commit();
    }
    const std::vector<Summary> bsum = bullet_summary(brows);
    const std::vector<Summary> fsum = fcl_summary(frows);
    const std::vector<Target> goals =
        o.quick ? std::vector<Target>{} : targets(bsum, fsum, ours_bullet, ours_fcl);

    std::vector<std::string> plot_args = {"--out", o.out.string()};
    if (o.bullet) plot_args.insert(plot_args.end(), {"--bullet", (o.out / "bullet.csv").string()});
    if (o.fcl) plot_args.insert(plot_args.end(), {"--fcl", (o.out / "fcl.csv").string()});
    const bool plotted = broadphase::app::run_plot_script("plot_engines.py", plot_args);

    const std::string md = section(info, o, bsum, fsum, goals, errors, plotted, wall());
    broadphase::write_file_atomically(o.out / "section.md", md);

    nlohmann::ordered_json j;
    j["machine"] = {{"cpu", info.cpu},
                    {"cores", info.cores},
                    {"memory_gib", info.memory_gib},
                    {"host", info.host},
                    {"compiler", info.compiler},
                    {"flags", info.flags},
                    {"build_type", info.build_type}};
    j["commit"] = info.commit;
    j["date"] = info.date;
    j["command"] = info.command;
    j["clock"] = "thread CPU time (CLOCK_THREAD_CPUTIME_ID), ms";
    j["runs"] = o.runs;
    j["quick"] = o.quick;
    j["seed"] = o.seed;
    j["wall_seconds"] = wall();
    auto& jb = j["bullet"] = nlohmann::ordered_json::array();
    for (const BulletCase& c : bcases) {
      nlohmann::ordered_json w = {{"world", c.label},
                                  {"scene", c.plan.scene},
                                  {"bodies", c.plan.bodies},
                                  {"steps", c.plan.steps},
                                  {"broad_phases", nlohmann::ordered_json::array()}};
      for (const Summary& s : bsum)
        if (s.label == c.label)
          w["broad_phases"].push_back({{"name", s.name},
                                       {"step_ms", s.a},
                                       {"broad_ms", s.b},
                                       {"share", s.c},
                                       {"pairs", s.pairs},
                                       {"broad_dbvt_over_this", s.ratio_a},
                                       {"step_dbvt_over_this", s.ratio_b}});
      jb.push_back(w);
    }
    auto& jf = j["fcl"] = nlohmann::ordered_json::array();
    for (const Summary& s : fsum)
      jf.push_back({{"n", s.size},
                    {"manager", s.name},
                    {"pairs", s.pairs},
                    {"update_ms", s.a},
                    {"collide_ms", s.b},
                    {"total_ms", s.c},
                    {"total_over_ours", s.ratio_a}});
    auto& jt = j["targets"] = nlohmann::ordered_json::array();
    for (const Target& t : goals)
      jt.push_back({{"target", t.what},
                    {"goal", t.goal},
                    {"measured", t.found ? nlohmann::ordered_json(t.measured) : nullptr},
                    {"met", t.met()}});
    j["errors"] = errors;
    broadphase::write_file_atomically(o.out / "engines.json", j.dump(2) + "\n");

    std::cout << md;
    std::fprintf(stderr, "%8.1f s  done: %s\n", wall(), (o.out / "section.md").c_str());
    return errors.empty() ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "engines_lab: %s\n", e.what());
    return 2;
  }
}
