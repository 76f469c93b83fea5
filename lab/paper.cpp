// The lab's main job, `broadphase paper` (paper.hpp): runs the study's six
// tests, memory and the engine frame on every structure, checks that all of
// them agree on every pair, and writes CSV, JSON, figures and REPORT.md.
#include "paper.hpp"

#include <unistd.h>

#include <algorithm>
#include <broadphase/scenes/output_file.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <optional>

#include "budget.hpp"
#include "experiment.hpp"
#include "interrupt.hpp"
#include "lab.hpp"
#include "paper_measure.hpp"
#include "paper_report.hpp"
#include "paper_steps.hpp"
#include "progress.hpp"
#include "structures.hpp"
#include "usage_error.hpp"

namespace broadphase::app {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The options a resumed run reads back from its state file.
nlohmann::json options_json(const PaperOptions& o) {
  return {{"quick", o.quick},
          {"out", o.out},
          {"algos", o.algos},
          {"max_n", o.max_n},
          {"max_n_given", o.max_n_given},
          {"seed", o.seed},
          {"budget", o.budget},
          {"peers", o.peers}};
}

struct Selected {
  std::string spec;
  bool peer = false;
  /// The lean path (kArraysSeries): measured by measure_arrays, never made
  /// through the registry, and only in the frame time and memory.
  bool lean = false;
};

// "--algos a,b:k=1,j=2,c" names a, b (with two options) and c: a piece
// with '=' and no ':' continues the options of the structure before it.
std::vector<std::string> split_specs(const std::vector<std::string>& raw) {
  std::vector<std::string> out;
  for (const std::string& arg : raw) {
    std::size_t start = 0;
    while (start <= arg.size()) {
      std::size_t comma = arg.find(',', start);
      if (comma == std::string::npos) comma = arg.size();
      const std::string piece = arg.substr(start, comma - start);
      const std::size_t eq = piece.find('='), colon = piece.find(':');
      if (!piece.empty() && eq != std::string::npos && colon == std::string::npos && !out.empty() &&
          out.back().find(':') != std::string::npos) {
        out.back() += "," + piece;
      } else if (!piece.empty()) {
        out.push_back(piece);
      }
      start = comma + 1;
    }
  }
  return out;
}

std::vector<Selected> select_structures(const PaperOptions& o) {
  const Registry& reg = registry();
  std::vector<Selected> out;
  if (o.algos.empty()) {
    for (const StructureInfo& e : reg.entries())
      if (!e.peer || o.peers) out.push_back({e.name, e.peer});
    if (out.empty()) throw UsageError("no structure is registered in this build");
    out.push_back({kArraysSeries, false, true});
    return out;
  }
  const std::string valid = reg.names() + ", " + kArraysSeries;
  const std::vector<std::string> specs = split_specs(o.algos);
  if (specs.empty()) throw UsageError("--algos: no structure named; valid: " + valid);
  for (const std::string& spec : specs) {
    const std::string name = spec.substr(0, spec.find(':'));
    if (name == kArraysSeries) {
      if (spec != name)
        throw UsageError("--algos: '" + spec + "': the lean path (" + kArraysSeries +
                         ") takes no options");
      if (std::none_of(out.begin(), out.end(), [](const Selected& s) { return s.lean; }))
        out.push_back({kArraysSeries, false, true});
      continue;
    }
    const StructureInfo* info = reg.find(name);
    if (info == nullptr)
      throw UsageError("--algos: unknown structure '" + name + "'; valid: " + valid);
    try {
      reg.make(spec);  // rejects bad options now rather than an hour into the run
    } catch (const UnknownStructure& e) {
      throw UsageError(std::string("--algos: ") + e.what());
    }
    if (std::none_of(out.begin(), out.end(), [&](const Selected& s) { return s.spec == spec; }))
      out.push_back({spec, info->peer});
  }
  return out;
}

std::string today_and_host() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%d", &tm);
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0) std::snprintf(host, sizeof host, "unknown-host");
  return std::string(date) + "-" + host;
}

// What one structure has cost so far, to project the next size.
struct History {
  std::vector<std::pair<std::size_t, CellCosts>> points;
  double overhead = 1;  // wall time / modelled time at the last size (setup, teardown)
  // Sizes from here on are scaled scenes: the density of the study's largest
  // size is kept, while the study's own sizes crowd one fixed cube.
  std::size_t first_scaled = static_cast<std::size_t>(-1);
  bool skipped = false;
  bool failed = false;
};

// The modelled wall time of one size (both placements) from its parts.
double model(const CellCosts& c, int reps, double min_rep) {
  return c.build + (reps + 1) * c.frame + reps * std::max(2 * min_rep, c.pass) +
         reps * std::max(min_rep, c.churn);
}

// A part of the cost at size n, grown from the last size by the growth
// observed between the last two (an exponent clamped to [1, 3]; 2 when
// there is only one size yet). In the study's fixed cube every object has
// more neighbours as N grows, which the scaled scenes undo by growing the
// cube: stepping from the study's sizes to the first scaled size, one power
// of N of the observed growth is that crowding and is taken off.
double grow(const History& h, double CellCosts::*part, std::size_t n, double* exponent) {
  const auto& [n1, c1] = h.points.back();
  const double x1 = c1.*part;
  double e = 2;
  if (h.points.size() >= 2) {
    const auto& [n0, c0] = h.points[h.points.size() - 2];
    const double x0 = c0.*part;
    if (x0 > 0 && x1 > 0 && n1 > n0) {
      e = std::log(x1 / x0) / std::log(static_cast<double>(n1) / static_cast<double>(n0));
      if (n1 < h.first_scaled && n >= h.first_scaled) e -= 1;
      e = std::clamp(e, 1.0, 3.0);
    }
  }
  if (exponent != nullptr) *exponent = std::max(*exponent, e);
  return x1 * std::pow(static_cast<double>(n) / static_cast<double>(n1), e);
}

double project(const History& h, std::size_t n, int reps, double min_rep,
               double* exponent = nullptr) {
  if (h.points.empty()) return 2e-6 * static_cast<double>(n) * (reps + 2) + 1e-3;
  CellCosts c;
  c.build = grow(h, &CellCosts::build, n, exponent);
  c.frame = grow(h, &CellCosts::frame, n, exponent);
  c.pass = grow(h, &CellCosts::pass, n, exponent);
  c.churn = grow(h, &CellCosts::churn, n, exponent);
  return model(c, reps, min_rep) * h.overhead;
}

std::string seconds_text(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, s >= 10 ? "%.0f s" : "%.2g s", s);
  return buf;
}

// Compares what every structure reported on one scene: frame digests and
// query results. The reference is naive's result when it ran, else the
// most common one.
void compare(const std::vector<Selected>& structures, std::size_t n, const PaperScene& ps,
             const std::vector<std::vector<FrameDigest>>& digests,
             const std::vector<std::vector<std::uint64_t>>& hits, PaperResults& res) {
  SceneSummary summary;
  summary.n = n;
  summary.placement = ps.even ? "even" : "uneven";
  summary.dist = std::string(to_string(ps.dist));
  summary.world = ps.scene.world;
  summary.moving = ps.moving;
  summary.seed = ps.seed;
  std::size_t frames = 0, passes = 0;
  for (std::size_t s = 0; s < structures.size(); ++s) {
    frames = std::max(frames, digests[s].size());
    passes = std::max(passes, hits[s].size());
    summary.structures += digests[s].empty() ? 0 : 1;
  }
  auto check = [&](std::size_t count, auto get, auto text, const std::string& what, auto record) {
    for (std::size_t f = 0; f < count; ++f) {
      std::map<decltype(get(0, 0)), std::vector<std::size_t>> by_value;
      for (std::size_t s = 0; s < structures.size(); ++s)
        if (f < (what == "frame" ? digests[s].size() : hits[s].size()))
          by_value[get(s, f)].push_back(s);
      if (by_value.empty()) continue;
      auto ref = by_value.begin();
      for (auto it = by_value.begin(); it != by_value.end(); ++it) {
        const bool naive_here =
            std::any_of(it->second.begin(), it->second.end(),
                        [&](std::size_t s) { return structures[s].spec == "naive"; });
        if (naive_here) {
          ref = it;
          break;
        }
        if (it->second.size() > ref->second.size()) ref = it;
      }
      std::string names;
      for (std::size_t s : ref->second) names += (names.empty() ? "" : ", ") + structures[s].spec;
      for (const auto& [value, who] : by_value) {
        res.comparisons += who.size();
        if (value == ref->first) continue;
        for (std::size_t s : who)
          res.mismatches.push_back({n, summary.placement, what + " " + std::to_string(f),
                                    structures[s].spec, text(value), text(ref->first), names});
      }
      record(ref->first);
    }
  };
  check(
      frames,
      [&](std::size_t s, std::size_t f) {
        return std::make_pair(digests[s][f].pairs, digests[s][f].hash);
      },
      [](const std::pair<std::uint64_t, std::uint64_t>& v) {
        return std::to_string(v.first) + " pairs, hash " + hex16(v.second);
      },
      "frame",
      [&](const std::pair<std::uint64_t, std::uint64_t>& v) {
        FrameDigest d;
        d.pairs = v.first;
        d.hash = v.second;
        summary.frames.push_back(d);
      });
  check(
      passes, [&](std::size_t s, std::size_t f) { return hits[s][f]; },
      [](std::uint64_t v) { return std::to_string(v) + " objects found"; }, "query pass",
      [](std::uint64_t) {});
  res.scenes.push_back(std::move(summary));
}

struct Hook {
  const char* name;
  std::string (*run)(const LabContext&);
};

// What one run of the lab carries from step to step.
struct Run {
  explicit Run(const PaperOptions& options) : o(options) {}
  const PaperOptions& o;
  std::vector<Selected> structures;
  std::vector<std::size_t> study_sizes, scaled_sizes;
  fs::path out_dir;
  ProgressBar bar;
  Clock::time_point t_start = Clock::now();
  PaperResults res;
  // The time spent, measured as the run goes, against the budget (budget.hpp).
  std::optional<RunBudget> budget;
  double experiment_seconds = 0;  // each registered experiment's share of the budget
  bool experiment_failed = false;
  // The steps done, recorded in out_dir so that --resume can finish the run.
  std::optional<PaperSteps> steps;
  bool study_done = false;  // --resume: the study's tables were read back
  // Lab seconds since the run began (budget.hpp: wall seconds unless scaled).
  double elapsed() const { return lab_seconds_since(t_start); }
  // Records what the run cut or overran, for REPORT.md, and says it now.
  void note(const std::string& text) {
    res.info.budget_notes.push_back(text);
    bar.message(text);
  }
  // Notes a step that took more than a quarter over its plan (and more
  // than `least` seconds over): "budget: the six tests took 20m, 40% over
  // their 14m".
  void note_overrun(const std::string& step, double took, double planned, const std::string& whose,
                    double least = 0) {
    if (planned > 0 && took > 1.25 * planned && took - planned > least)
      note("budget: " + step + " took " + seconds_text(took) + ", " +
           over_text(took / planned, whose + " " + seconds_text(planned)));
  }
  // The least an experiment of `weight` gets: below it a full run's
  // experiment runs with --quick's sizes instead.
  double experiment_floor(double weight) const { return (o.quick ? 2.0 : 15.0) * weight; }
  // The lab seconds planned for the experiments from the k-th on: each its
  // share, never less than its floor (a slow --quick run spends the floors,
  // and an estimate from the shares alone fell short of what remained).
  double experiments_planned(std::size_t k) const {
    double sum = 0;
    for (; k < experiments().size(); ++k)
      sum += std::max(experiment_floor(experiments()[k].weight),
                      experiment_seconds * experiments()[k].weight);
    return sum;
  }
  // The progress line: `what`, with `left` lab seconds estimated to go.
  void show_left(const std::string& what, double left) {
    const double e = elapsed();
    bar.update(what, e / (e + left), left);
  }
};

// Step 1: checks everything the user asked for before any work; chooses the
// sizes, the output folder and the budgets; records the provenance.
void prepare(Run& run) {
  const PaperOptions& o = run.o;
  // Check everything the user asked for before any work.
  if (o.max_n_given && o.max_n < 50)
    throw UsageError("--max-n " + std::to_string(o.max_n) +
                     ": must be at least 50, the study's smallest size");
  if (o.budget < 0 || !std::isfinite(o.budget))
    throw UsageError("--budget: must be a positive number of seconds");
  run.structures = select_structures(o);
  const std::vector<Selected>& structures = run.structures;
  std::vector<std::size_t>& study_sizes = run.study_sizes;
  study_sizes = o.quick ? std::vector<std::size_t>{50, 100, 200, 400, 800, 1600}
                        : std::vector<std::size_t>{50, 100, 200, 400, 800, 1600, 3200, 6400};
  std::vector<std::size_t>& scaled_sizes = run.scaled_sizes;
  scaled_sizes = o.quick ? std::vector<std::size_t>{3200}
                         : std::vector<std::size_t>{25600, 102400, 409600, 1024000};
  if (o.max_n_given) {
    std::erase_if(study_sizes, [&](std::size_t n) { return n > o.max_n; });
    std::erase_if(scaled_sizes, [&](std::size_t n) { return n > o.max_n; });
  }
  run.out_dir = o.out.empty() ? fs::path("results") / today_and_host() : fs::path(o.out);
  const fs::path& out_dir = run.out_dir;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir))
    throw std::runtime_error("--out " + out_dir.string() + ": cannot create the directory" +
                             (ec ? ": " + ec.message() : std::string(": not a directory")));
  // Checks that DIR can be written before any work, and records each step
  // done there, so that an interrupted run can be finished with --resume.
  run.steps.emplace(o.resume.empty() ? PaperSteps::start(out_dir, options_json(o))
                                     : PaperSteps::resume(out_dir));
  set_interrupt_note(
      "broadphase paper: the run in " + out_dir.string() +
      " is incomplete (see RUN-INCOMPLETE); finish it with: " + run.steps->resume_command());

  run.bar.set_plain_interval(o.quick ? 5 : 15);
  RunInfo& info = run.res.info;
  fill_provenance(info);
  info.quick = o.quick;
  info.seed = o.seed;
  info.budget_seconds = o.budget > 0 ? o.budget : (o.quick ? 35 : kDefaultBudget);
  // The six tests took 810-840 s of 1 470 s on quiet 2-core hosts with
  // their floors met; the experiments (the performance experiment above
  // all) took most of the rest.
  info.study_budget_seconds = info.budget_seconds * (o.quick ? 0.6 : 0.55);
  // Most structures stop well short of the cap at most sizes, so a full run
  // affords each up to 1.5 shares of the study's budget at one size; the
  // budget itself still bounds the whole run.
  // The lean path takes no share: it runs only frames, a small part of
  // what a structure's cell costs, so adding it leaves the others' caps.
  const auto shares =
      std::max<std::ptrdiff_t>(1, std::count_if(structures.begin(), structures.end(),
                                                [](const Selected& s) { return !s.lean; }));
  info.cell_cap_seconds =
      std::min(info.study_budget_seconds / static_cast<double>(shares) * (o.quick ? 0.5 : 1.5),
               o.quick ? 5.0 : 60.0);
  info.study_sizes = study_sizes;
  info.scaled_sizes = scaled_sizes;
  for (const Selected& s : structures) {
    info.structures.push_back(s.spec);
    info.peers.push_back(s.peer);
  }
  for (const StructureInfo& e : registry().entries()) info.registered.push_back(e.name);
  info.time_scale = lab_time_scale();
  // The figures and the report come last, in a planned tail of their own.
  const double tail = o.quick ? 15 : 60;
  run.budget.emplace(info.budget_seconds, tail);
  run.experiment_seconds = std::max(0.0, info.budget_seconds - info.study_budget_seconds - tail) /
                           std::max(1.0, experiment_weights());
}

// Thrown from a cell's progress step when the study has run well past its
// budget: the cell stops there and is left out.
struct CellOverBudget {};

// Step 2: the study's six tests, memory and the frame time on every
// structure at every size, skipping what does not fit the budget; compares
// what the structures report.
void run_study(Run& run) {
  const PaperOptions& o = run.o;
  const std::vector<Selected>& structures = run.structures;
  const std::vector<std::size_t>& study_sizes = run.study_sizes;
  const std::vector<std::size_t>& scaled_sizes = run.scaled_sizes;
  ProgressBar& bar = run.bar;
  PaperResults& res = run.res;
  RunInfo& info = res.info;
  RunBudget& budget = *run.budget;
  MeasureOptions mo;
  mo.seed = o.seed;
  mo.min_rep_seconds = o.quick ? 5e-4 : 4e-3;
  mo.cell_cap_seconds = info.cell_cap_seconds;
  info.min_rep_seconds = mo.min_rep_seconds;
  // Repetitions at N: at most `reps_cap`, which the budget lowers when the
  // run falls behind.
  int reps_cap = 5;
  auto reps_at = [&](std::size_t n) {
    return std::min(reps_cap, o.quick ? 3 : (n > 102400 ? 3 : 5));
  };
  info.reps_rule = o.quick ? "3 per measurement" : "5 per measurement up to N = 102 400, 3 above";

  std::vector<std::size_t> sizes = study_sizes;
  sizes.insert(sizes.end(), scaled_sizes.begin(), scaled_sizes.end());
  std::vector<History> hist(structures.size());
  if (!scaled_sizes.empty())
    for (History& h : hist) h.first_scaled = scaled_sizes.front();

  // How much slower than projected the cells measured so far ran, on the
  // lab's clock: their seconds over their projections (at least 1). The
  // projections come from the costs measured, which a busy machine or a
  // scaled clock (budget.hpp) leaves behind the time actually spent.
  double projected_sum = 0, actual_sum = 0;
  auto slowness = [&] {
    return projected_sum > 0 ? std::max(1.0, actual_sum / projected_sum) : 1.0;
  };

  // Seconds left in the six tests: every structure's projected time at the
  // sizes still to come, up to the first it will be skipped at.
  auto study_left = [&](std::size_t size_index, std::size_t next_structure) {
    double left = 0;
    for (std::size_t s = 0; s < structures.size(); ++s) {
      if (hist[s].skipped) continue;
      for (std::size_t k = size_index + (s < next_structure ? 1 : 0); k < sizes.size(); ++k) {
        const double p = project(hist[s], sizes[k], reps_at(sizes[k]), mo.min_rep_seconds);
        if (p > info.cell_cap_seconds) break;
        left += p;
      }
    }
    return left;
  };

  const auto t_study = Clock::now();
  auto study_elapsed = [&] { return lab_seconds_since(t_study); };
  run.study_done = run.steps->load_study(res);  // --resume: the study's tables
  budget.begin("study", run.study_done ? 0 : info.study_budget_seconds);
  for (std::size_t ni = 0; ni < sizes.size() && !run.study_done; ++ni) {
    const std::size_t n = sizes[ni];
    const bool scaled = ni >= study_sizes.size();
    // Behind the plan: when the cells so far ran over a quarter past their
    // projections and the rest, projected at that pace, does not fit what
    // is left of the six tests' budget, fewer repetitions from this size on
    // (5 to 3, then 3 to 2), said in REPORT.md. (A rest that does not fit
    // at the projections' own pace is the plan: the largest sizes are
    // skipped, structure by structure, as below.)
    if (ni > 0 && reps_at(n) > 2 && slowness() > 1.25) {
      const double rest = study_left(ni, 0) * slowness();
      const double left = info.study_budget_seconds - study_elapsed();
      if (rest > left) {
        const int from = reps_at(n), to = from > 3 ? 3 : 2;
        reps_cap = to;
        char why[512];
        std::snprintf(why, sizeof why,
                      "budget: cut repetitions from %d to %d for N >= %zu: after N = %zu the six "
                      "tests had spent %s of their %s, and the rest was projected at %s (the "
                      "cells so far ran %s)",
                      from, to, n, sizes[ni - 1], seconds_text(study_elapsed()).c_str(),
                      seconds_text(info.study_budget_seconds).c_str(), seconds_text(rest).c_str(),
                      over_text(slowness(), "their projections").c_str());
        run.note(why);
        info.reps_rule +=
            "; cut to " + std::to_string(to) + " from N = " + std::to_string(n) + " on (budget)";
      }
    }
    const int reps = reps_at(n);
    mo.reps = reps;
    const double hooks_left = run.experiments_planned(0);
    // The time left: the study's rest at the pace measured (never more
    // than its budget left, which skips enforce, unless the cell under way
    // is over), then the experiments and the tail at the run's pace.
    auto show = [&](const std::string& what, double cell_left, double rest) {
      const double study =
          cell_left + std::min(rest * slowness(), std::max(0.0, info.study_budget_seconds -
                                                                    study_elapsed() - cell_left));
      run.show_left(what, budget.estimate_left(study, hooks_left, slowness(), "experiment"));
    };
    // Decide who is over the cap before generating the scenes: a million
    // objects take seconds to generate, for nobody when all are skipped.
    bool anyone = false;
    for (std::size_t si = 0; si < structures.size(); ++si) {
      History& h = hist[si];
      if (h.skipped) {
        res.skips.push_back({structures[si].spec, n, 0, info.cell_cap_seconds,
                             h.failed ? "failed at a smaller size" : "skipped at a smaller size"});
        continue;
      }
      double exponent = 1;
      const double projected = project(h, n, reps, mo.min_rep_seconds, &exponent);
      if (!h.points.empty() && projected > info.cell_cap_seconds) {
        h.skipped = true;
        char why[256];
        std::snprintf(why, sizeof why,
                      "projected %s (from N=%zu, growth up to N^%.2g) exceeds the cap of %s per "
                      "structure and size",
                      seconds_text(projected).c_str(), h.points.back().first, exponent,
                      seconds_text(info.cell_cap_seconds).c_str());
        res.skips.push_back({structures[si].spec, n, projected, info.cell_cap_seconds, why});
        bar.message("skipping " + structures[si].spec + " at N=" + std::to_string(n) + ": " + why);
        continue;
      }
      anyone = true;
    }
    if (!anyone) continue;
    show("study: generating the scenes of N=" + std::to_string(n), 0, study_left(ni, 0));
    const PaperScene scenes[2] = {make_paper_scene(n, false, scaled, o.seed),
                                  make_paper_scene(n, true, scaled, o.seed)};
    std::vector<std::vector<FrameDigest>> digests[2];
    std::vector<std::vector<std::uint64_t>> hits[2];
    for (int p = 0; p < 2; ++p) {
      digests[p].resize(structures.size());
      hits[p].resize(structures.size());
    }
    std::vector<std::string> budget_skips;  // left out here for the budget
    for (std::size_t si = 0; si < structures.size(); ++si) {
      const Selected& sel = structures[si];
      History& h = hist[si];
      if (h.skipped) continue;  // over the cap, or before this size: recorded above
      const double projected = project(h, n, reps, mo.min_rep_seconds);
      // At the pace measured: a cell projected at 10 s takes 14 where the
      // cells so far ran 40% over their projections.
      const double paced = projected * slowness();
      const double budget_left = info.study_budget_seconds - study_elapsed();
      if (!h.points.empty() && paced > budget_left) {
        h.skipped = true;
        const std::string why =
            "projected " + seconds_text(paced) +
            (paced > projected ? " (" + seconds_text(projected) + " at the pace of the model)"
                               : std::string()) +
            " exceeds the " + seconds_text(std::max(0.0, budget_left)) +
            " left of the study's budget";
        res.skips.push_back({sel.spec, n, paced, info.cell_cap_seconds, why});
        bar.message("skipping " + sel.spec + " at N=" + std::to_string(n) + ": " + why);
        budget_skips.push_back(sel.spec);
        continue;
      }
      const double rest = study_left(ni, si + 1);
      const auto t_cell = Clock::now();
      CellCosts costs;
      std::vector<Row> cell_rows;  // both placements' rows, kept when both ran
      for (int p = 0; p < 2; ++p) {
        const PaperScene& ps = scenes[p];
        mo.churn = ps.even;
        // The second placement gets what the first left of the cap, so a
        // structure much slower than projected stops after one repetition.
        mo.cell_cap_seconds =
            std::max(0.0, info.cell_cap_seconds -
                              std::chrono::duration<double>(Clock::now() - t_cell).count());
        // (The cap is the structure's, in wall seconds: how slow it is, not
        // how busy the machine; the budget above is on the lab's clock.)
        const std::string where = "study: " + sel.spec + " N=" + std::to_string(n) + " " +
                                  (ps.even ? "even" : "uneven") + " ";
        auto tick = [&](const std::string& step) {
          // A cell past its projection is given a quarter of what it has
          // spent again: never "0 s left" while it runs.
          const double cell = lab_seconds_since(t_cell);
          show(where + step, std::max(paced - cell, cell > paced ? 0.25 * cell : 0.0), rest);
          // The projections cannot see a machine that slows down during a
          // cell: one cell of Bullet's dbvt at 102 400 took 14 minutes on
          // a machine whose other programs left this one a twentieth of a
          // core. A cell still running when the study is past its budget
          // by a tenth stops at its next step, and is left out.
          if (study_elapsed() > 1.1 * info.study_budget_seconds + 10) throw CellOverBudget{};
        };
        try {
          SceneResult r = sel.lean ? measure_arrays(ps, mo, tick)
                                   : measure_scene(registry(), sel.spec, sel.peer, ps, mo, tick);
          for (Row& row : r.rows) cell_rows.push_back(std::move(row));
          digests[p][si] = std::move(r.digests);
          hits[p][si] = std::move(r.query_hits);
          costs += r.costs;
        } catch (const CellOverBudget&) {
          const std::string why = "stopped during the cell: the six tests ran past their " +
                                  seconds_text(info.study_budget_seconds) + " budget";
          res.skips.push_back({sel.spec, n, paced, info.cell_cap_seconds, why});
          bar.message("stopping " + sel.spec + " at N=" + std::to_string(n) + ": " + why);
          budget_skips.push_back(sel.spec);
          digests[0][si].clear();
          digests[1][si].clear();
          hits[0][si].clear();
          hits[1][si].clear();
          cell_rows.clear();
          h.skipped = true;
          break;
        } catch (const std::exception& e) {
          res.mismatches.push_back(
              {n, ps.even ? "even" : "uneven", "error", sel.spec, e.what(), "no error", ""});
          bar.message("error: " + sel.spec + " at N=" + std::to_string(n) + ": " + e.what());
          h.skipped = h.failed = true;
          break;
        }
      }
      for (Row& row : cell_rows) res.rows.push_back(std::move(row));
      if (h.skipped) continue;
      if (!h.points.empty()) {
        projected_sum += projected;
        actual_sum += lab_seconds_since(t_cell);
      }
      h.points.push_back({n, costs});
      const double modelled = model(costs, reps, mo.min_rep_seconds);
      h.overhead = modelled > 0 ? std::clamp(costs.total / modelled, 1.0, 3.0) : 1.0;
    }
    if (!budget_skips.empty()) {
      std::string names;
      for (const std::string& b : budget_skips) names += (names.empty() ? "" : ", ") + b;
      run.note("budget: left out " + names + " from N = " + std::to_string(n) +
               " on: projected beyond what was left of the six tests' budget of " +
               seconds_text(info.study_budget_seconds) + " after " + seconds_text(study_elapsed()) +
               " (the cells so far ran " + over_text(slowness(), "their projections") + ")");
    }
    for (int p = 0; p < 2; ++p) compare(structures, n, scenes[p], digests[p], hits[p], res);
  }
  if (!run.study_done) info.study_seconds = study_elapsed();
  const double took = budget.end();
  if (!run.study_done) run.note_overrun("the six tests", took, info.study_budget_seconds, "their");
}

// Step 4: the registered experiments (lab/experiment.hpp), each with its
// share of the budget; a failure is reported in its section.
void run_experiments(Run& run) {
  const PaperOptions& o = run.o;
  const std::vector<Selected>& structures = run.structures;
  const fs::path& out_dir = run.out_dir;
  ProgressBar& bar = run.bar;
  PaperResults& res = run.res;
  RunBudget& budget = *run.budget;
  const std::size_t kExperiments = experiments().size();
  for (std::size_t k = 0; k < kExperiments; ++k) {
    LabContext ctx;
    ctx.out_dir = out_dir;
    ctx.quick = o.quick;
    ctx.seed = o.seed;
    if (o.max_n_given) ctx.max_n = o.max_n;
    if (!o.algos.empty())
      for (const Selected& s : structures)
        if (!s.peer && !s.lean) ctx.algos.push_back(s.spec);
    // Each gets its share of what is actually left (the tail set aside at
    // the pace so far), at most its planned share; below the floor a full
    // run's experiment runs with --quick's sizes instead, said in REPORT.md.
    const std::string name = experiments()[k].name;
    const double weight = experiments()[k].weight;
    double weight_after = 0;  // the weights of the experiments after this one
    for (std::size_t j = k + 1; j < kExperiments; ++j) weight_after += experiments()[j].weight;
    const double least = run.experiment_floor(weight);
    const double left = budget.left() - budget.tail() * budget.pace(1, "experiment");
    const double share = left * weight / (weight + weight_after);
    if (!o.quick && share < least && !run.steps->done(name)) {
      ctx.quick = true;
      const std::size_t count = kExperiments - k;
      const double pace = budget.pace(1, "experiment");
      run.note("budget: cut the sizes of the experiment " + name +
               " to --quick's: " + seconds_text(std::max(0.0, left)) + " were left for " +
               (count == 1 ? std::string("the last experiment")
                           : std::to_string(count) + " experiments") +
               " after " + seconds_text(budget.spent()) + " of the " +
               seconds_text(budget.total()) + " budget" +
               (pace > 1.05 ? " (the steps so far ran " + over_text(pace, "their plan") + ")"
                            : std::string()));
    }
    ctx.budget_seconds = std::max(least, std::min(run.experiment_seconds * weight, share));
    const double after = run.experiments_planned(k + 1);
    budget.begin(name, run.steps->done(name) ? 0 : ctx.budget_seconds, "experiment");
    ctx.progress = [&, name, after](const std::string& what, double f) {
      run.show_left(name + ": " + what,
                    budget.estimate_left(budget.step_left(f), after, 1, "experiment"));
    };
    ctx.progress("starting", 0);
    try {
      res.sections.push_back(run.steps->experiment(name, ctx, experiments()[k].run));
    } catch (const std::exception& e) {
      run.experiment_failed = true;
      res.sections.push_back("## " + name +
                             "\n\n<span style=\"color:red\">**The experiment failed: " +
                             std::string(e.what()) + "**</span>\n");
      bar.message("error: " + name + ": " + e.what());
    }
    const double planned = budget.step_planned(), took = budget.end();
    run.note_overrun("the experiment " + name, took, planned, "its", 1);
  }
}

// Step 5: the figures, by tools/plot_paper.py.
void draw_figures(Run& run) {
  const fs::path& out_dir = run.out_dir;
  ProgressBar& bar = run.bar;
  PaperResults& res = run.res;
  RunInfo& info = res.info;
  RunBudget& budget = *run.budget;
  budget.begin("plots", budget.tail());
  {
    // Said before the script runs (a line of its own in a log), with the
    // tail at the run's pace.
    const double left = std::max(
        budget.step_left(0), budget.tail() * budget.pace(1, "experiment") - budget.step_spent());
    run.show_left("plots: drawing the figures", left);
  }
  // The plot script and its messages write to stderr too: no bar under them.
  bar.clear();
  info.plots = run.steps->plots([&](const fs::path& into) {
    return run_plot_script("plot_paper.py",
                           {"--csv", (out_dir / "results.csv").string(), "--out", into.string()});
  });
  if (info.plots) {
    for (const auto& entry : fs::directory_iterator(out_dir)) {
      const std::string f = entry.path().filename().string();
      if (entry.path().extension() == ".png" &&
          (f.rfind("fig", 0) == 0 || f.rfind("frame", 0) == 0))
        res.figures.push_back(f);
    }
    std::sort(res.figures.begin(), res.figures.end(),
              [](const std::string& a, const std::string& b) {
                // fig3_2 before fig3_10: compare the numbers, not the text.
                auto key = [](const std::string& s) {
                  int major = 99, minor = 99;
                  std::sscanf(s.c_str(), "fig%d_%d", &major, &minor);
                  return std::make_tuple(major, minor, s);
                };
                return key(a) < key(b);
              });
  } else {
    info.plots_note =
        "python3 with matplotlib was not available, or tools/plot_paper.py failed (the reason is "
        "on stderr)";
  }
}

// Step 6: results.json and REPORT.md.
void write_report(Run& run) {
  const fs::path& out_dir = run.out_dir;
  PaperResults& res = run.res;
  RunInfo& info = res.info;
  run.budget->end();  // the figures
  info.elapsed_seconds = run.elapsed();
  write_json(out_dir / "results.json", res);
  write_file_atomically(out_dir / "REPORT.md", report_markdown(res));
  std::vector<std::string> all_steps{"study", "plots"};
  for (const ExperimentInfo& e : experiments()) all_steps.emplace_back(e.name);
  run.steps->finish(all_steps);
}

// Step 7: the summary line; an error when structures disagreed or an
// experiment failed.
void finish(Run& run) {
  const std::vector<Selected>& structures = run.structures;
  const fs::path& out_dir = run.out_dir;
  ProgressBar& bar = run.bar;
  PaperResults& res = run.res;
  RunInfo& info = res.info;
  bar.finish("broadphase paper: done");

  std::printf("%s: %zu structures, %zu results, %zu skips, %zu of %zu results disagree%s\n",
              (out_dir / "REPORT.md").c_str(), structures.size(), res.rows.size(), res.skips.size(),
              res.mismatches.size(), res.comparisons, info.plots ? "" : ", plots skipped");
  std::fflush(stdout);
  if (!res.mismatches.empty()) {
    std::fprintf(
        stderr,
        "\x1b[31mbroadphase paper: %zu results disagree between structures (see %s)\x1b[0m\n",
        res.mismatches.size(), (out_dir / "REPORT.md").c_str());
    throw std::runtime_error("structures disagree on pairs or query results");
  }
  if (run.experiment_failed) throw std::runtime_error("an experiment failed (see REPORT.md)");
}

}  // namespace

void apply_recorded_options(PaperOptions& o, const nlohmann::json& j) {
  try {
    j.at("quick").get_to(o.quick);
    j.at("algos").get_to(o.algos);
    j.at("max_n").get_to(o.max_n);
    j.at("max_n_given").get_to(o.max_n_given);
    j.at("seed").get_to(o.seed);
    j.at("budget").get_to(o.budget);
    j.at("peers").get_to(o.peers);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(o.resume + ": the recorded options are damaged (" + e.what() + ")");
  }
  o.out = o.resume;
}

// The lab, step by step: each step runs in one place, here.
void run_paper(const PaperOptions& o) {
  Run run(o);
  prepare(run);
  run_study(run);
  if (!run.study_done) {  // step 3
    write_csv(run.out_dir / "results.csv", run.res.rows);
    run.steps->save_study(run.res);
  }
  run_experiments(run);
  draw_figures(run);
  write_report(run);
  finish(run);
}

}  // namespace broadphase::app
