// The lab's performance experiment: our fastest structure against every
// peer adapter in the build, on the targets of the performance work, plus
// one thread against two and the query/insert/remove micro-timings.
#include <algorithm>
#include <broadphase/scenes/scene.hpp>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "experiment.hpp"
#include "lab_data.hpp"
#include "structures.hpp"
#include "timing.hpp"

namespace broadphase::app {

namespace {

// Our structure's frames may take this long per run (at least 50 frames;
// a million objects take 55-75 ms per frame here).
constexpr double kOursSeconds = 8;
// `advise`'s default budget (seconds for all its candidates on a scene).
constexpr double kAdviseSeconds = 10;

/// One workload of the targets table.
struct Workload {
  std::string label;
  Distribution dist;
  std::size_t n, n_quick;  // n_quick = 0: skipped with --quick
  double goal_ratio;       // how many times faster than the fastest peer (0: absolute goals)
  double issue_peer_ms;    // the fastest peer's reference figure (NaN: none given)
  double max_frame_ms;     // absolute goals (NaN: none)
  double max_bytes_per_object;
  // The lean path's goals on this workload (NaN / false: none).
  double arrays_max_frame_ms;
  double arrays_max_bytes_per_object;
  bool arrays_no_slower;  // no slower than our handle structure
  bool advise;            // also time the structure `advise` recommends on it
};

// Frames of a short run (the first frames from the start, warm-up
// included): as many as a fresh run measured independently on the issue.
constexpr std::size_t kShortRun = 6;

std::string fmt(double v, int digits = 3) {
  if (!std::isfinite(v)) return "–";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

struct Row {
  std::string workload;
  StructureTiming ours;
  StructureTiming ours2;    // on two threads (empty spec: not run)
  StructureTiming arrays;   // the lean path (arrays.hpp) on the same frames
  StructureTiming advised;  // the structure `advise` recommends (empty spec: not run)
  std::vector<StructureTiming> peers;
  bool agree = true;
};

}  // namespace

namespace {

std::string lab_performance(const LabContext& ctx) {
  const Registry& reg = registry();
  std::vector<std::string> peers;
  for (const StructureInfo& e : reg.entries())
    if (e.peer) peers.push_back(e.name);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // The goals and the reference figures are data: lab/goals.json.
  const nlohmann::json& g = goals();
  const std::string ours = g.at("structure");
  std::vector<Workload> workloads;
  for (const nlohmann::json& w : g.at("workloads"))
    workloads.push_back({w.at("label"), parse_distribution(w.at("dist").get<std::string>()),
                         w.at("n"), w.at("n_quick"), w.value("speedup_over_fastest_peer", 0.0),
                         w.value("reference_peer_ms", nan), w.value("max_frame_ms", nan),
                         w.value("max_bytes_per_object", nan), w.value("arrays_max_frame_ms", nan),
                         w.value("arrays_max_bytes_per_object", nan),
                         w.value("arrays_no_slower", false), w.value("advise", false)});
  std::erase_if(workloads, [&](const Workload& w) { return ctx.quick && w.n_quick == 0; });
  // Peers are slow to build at 100 000 objects and more (Bullet's sweep
  // takes minutes): they run there only with a generous budget.
  const bool big_peers = ctx.budget_seconds >= 600;
  // Our structure runs on one thread and, where there are two cores, on two.
  const bool two_cores = std::thread::hardware_concurrency() >= 2;
  const std::string ours2_spec = g.at("two_threads_spec");
  const std::size_t runs = workloads.size() * (2 + (two_cores ? 1 : 0) + peers.size()) + 2;
  const double per_run =
      std::max(ctx.quick ? 0.1 : 0.2, 0.6 * ctx.budget_seconds / static_cast<double>(runs));
  std::size_t done = 0;
  auto progress = [&](const std::string& what) {
    if (ctx.progress) ctx.progress("performance: " + what, static_cast<double>(done) / runs);
  };

  std::vector<Row> rows;
  std::ofstream csv(ctx.out_dir / "performance.csv");
  csv << "workload,structure,objects,frames,median_frame_ms,mean_frame_ms,build_ms,query_us,"
         "insert_us,remove_us,bytes_per_object,pairs_agree,caller_bytes_per_object,"
         "first_six_frames_ms\n";
  auto write_csv = [&](const std::string& w, std::size_t n, const StructureTiming& t, bool ok) {
    csv << w << ',' << t.spec << ',' << n << ',' << t.frame_ms.size() << ',' << t.median_frame_ms()
        << ',' << t.mean_frame_ms() << ',' << t.build_ms << ',' << t.query_us << ',' << t.insert_us
        << ',' << t.remove_us << ','
        << (n ? static_cast<double>(t.memory_bytes) / static_cast<double>(n) : 0.0) << ','
        << (ok ? "yes" : "no") << ','
        << (n ? static_cast<double>(t.caller_bytes) / static_cast<double>(n) : 0.0) << ','
        << t.first_frames_ms(kShortRun) << '\n';
  };

  std::size_t n_micro = 0;
  for (const Workload& w : workloads) {
    const std::size_t n = ctx.quick ? w.n_quick : w.n;
    progress(w.label);
    const Scene scene = generate(w.dist, n, ctx.seed);
    TimingLimits lim;
    lim.max_frames = ctx.quick ? 10 : 100;
    lim.min_frames = 8;  // two warm-up frames, then a median of at least six
    lim.budget_seconds = per_run;
    lim.micro = w.dist == Distribution::uneven;
    Row row;
    row.workload = w.label + " " + std::to_string(n);
    // Our structure gets its six measured frames even where its warm-up
    // (the first bulk update builds the fixed pair cache: seconds at a
    // million objects) is longer than a peer's share of the budget.
    TimingLimits ours_lim = lim;
    ours_lim.warmup_seconds = 120;
    // Movers renew their candidate lists in waves (about every twelve
    // frames at first, spreading out later): our structure runs at least
    // half the scene's hundred frames, so that its median and mean cover
    // the waves, not only the quiet frames after the inserts.
    if (!ctx.quick) {
      ours_lim.min_frames = 50;
      ours_lim.budget_seconds = std::max(per_run, kOursSeconds);
    }
    row.ours = time_structure(reg, ours, scene, ours_lim);
    ++done;
    if (two_cores) {
      TimingLimits lim2 = ours_lim;
      lim2.micro = false;
      row.ours2 = time_structure(reg, ours2_spec, scene, lim2);
      ++done;
    }
    // The lean path over the caller's arrays, on the same frames, and as
    // many of them as ours: its movers renew their lists in waves too
    // (with six frames its median at a million fell in the first one).
    progress(w.label + " arrays");
    TimingLimits arrays_lim = ours_lim;
    row.arrays = time_arrays("arrays", scene, arrays_lim);
    ++done;
    if (n <= 20000 || big_peers) {
      for (const std::string& p : peers) {
        progress(w.label + " " + p);
        row.peers.push_back(time_structure(reg, p, scene, lim));
        ++done;
      }
    }
    // What a user of these kinds would run: the structure `advise`
    // recommends among ours (its default budget), timed as the peers are.
    if (w.advise && !row.peers.empty()) {
      progress(w.label + " advise");
      const std::vector<std::string> candidates = advise_candidates(reg, n, false);
      const Advice advice =
          advise_on(reg, candidates, scene,
                    advise_limits(100, ctx.quick ? 1 : kAdviseSeconds, candidates.size()),
                    [](std::size_t, const StructureTiming&) {});
      if (advice.best < advice.results.size())
        row.advised = candidates[advice.best] == ours
                          ? row.ours
                          : time_structure(reg, candidates[advice.best], scene, lim);
    }
    row.agree = row.ours.error.empty();
    if (!row.ours2.spec.empty() && row.ours2.error.empty() &&
        first_disagreement(row.ours2, row.ours) >= 0)
      row.agree = false;
    for (const StructureTiming& p : row.peers)
      if (p.error.empty() && first_disagreement(p, row.ours) >= 0) row.agree = false;
    write_csv(row.workload, n, row.ours, row.agree);
    write_csv(row.workload, n, row.arrays,
              row.arrays.error.empty() && first_disagreement(row.arrays, row.ours) < 0);
    if (!row.ours2.spec.empty()) write_csv(row.workload, n, row.ours2, row.agree);
    for (const StructureTiming& p : row.peers)
      write_csv(row.workload, n, p, p.error.empty() && first_disagreement(p, row.ours) < 0);
    if (!row.advised.spec.empty() && row.advised.spec != ours)
      write_csv(row.workload, n, row.advised,
                row.advised.error.empty() && first_disagreement(row.advised, row.ours) < 0);
    if (lim.micro) n_micro = rows.size();
    rows.push_back(std::move(row));
  }

  // One thread against two on the scaled even scene.
  const nlohmann::json& gt = g.at("threads");
  const std::size_t n_threads = ctx.quick ? gt.at("n_quick") : gt.at("n");
  progress("threads");
  const Scene scaled =
      generate(parse_distribution(gt.at("dist").get<std::string>()), n_threads, ctx.seed);
  TimingLimits lim;
  lim.max_frames = ctx.quick ? 10 : 100;
  lim.min_frames = ctx.quick ? 6 : 50;
  lim.warmup_seconds = 120;
  lim.budget_seconds = ctx.quick ? per_run : std::max(per_run, kOursSeconds);
  lim.micro = false;
  // One and two threads alternated three times: the machine's speed drifts
  // between runs by more than the difference measured. Each keeps the run
  // with its middle median.
  std::vector<StructureTiming> ones, twos;
  bool same = true;
  for (int round = 0; round < 3; ++round) {
    ones.push_back(time_structure(reg, ours + ":threads=1", scaled, lim));
    twos.push_back(time_structure(reg, ours2_spec, scaled, lim));
    same = same && ones.back().error.empty() && twos.back().error.empty() &&
           first_disagreement(ones.back(), twos.back()) < 0;
  }
  done += 2;
  auto middle = [](std::vector<StructureTiming>& v) {
    std::sort(v.begin(), v.end(), [](const StructureTiming& a, const StructureTiming& b) {
      return a.median_frame_ms() < b.median_frame_ms();
    });
    return v[v.size() / 2];
  };
  const StructureTiming one = middle(ones);
  const StructureTiming two = middle(twos);
  write_csv("threads scaled-even " + std::to_string(n_threads), n_threads, one, same);
  write_csv("threads scaled-even " + std::to_string(n_threads), n_threads, two, same);

  // The report.
  std::ostringstream md;
  md << "## Performance\n\n";
  md << "Our fastest structure, `" << ours << "`, against ";
  if (peers.empty())
    md << "no peer: this build has no peer adapter, so the ratios below use the fastest peer's "
          "reference figure of `lab/goals.json` (measured on the same kind of machine, not in "
          "this run) and are marked *(issue)*.";
  else
    md << "every peer adapter of this build, measured in the same run.";
  md << " Frame = the structure's bulk update of the moving objects plus finding all pairs; "
        "medians of wall time over the frames run (frames 0 and 1, the warm-up after the inserts, "
        "left out; six frames or more where the budget allows, fifty or more for ours, the count "
        "is in the CSV); the mean of ours is shown too (frames where many movers renew their "
        "lists cost several times the median one); hardware threads here: "
     << std::thread::hardware_concurrency() << (ctx.quick ? "; **quick run: small sizes**" : "")
     << ". CSV: `performance.csv`.\n\n";
  md << "The speed-up and the goal are judged on one thread, as the peers run; the two-thread "
        "figures (`"
     << ours2_spec
     << "`, the same pairs in the same order) are shown beside them, and a goal met only "
        "with both cores is marked so.\n\n";
  md << "Goals and reference figures: `lab/goals.json`.\n\n";
  md << "| workload | " << ours << " ms | mean ms | 2 threads ms | fastest peer | peer ms | "
     << "speed-up | speed-up, 2 threads | goal | met |\n";
  md << "|---|---:|---:|---:|---|---:|---:|---:|---:|:-:|\n";
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const Row& row = rows[r];
    const Workload& w = workloads[r];
    const double ours_ms = row.ours.median_frame_ms();
    const double ours2 =
        !row.ours2.spec.empty() && row.ours2.error.empty() && !row.ours2.frame_ms.empty()
            ? row.ours2.median_frame_ms()
            : nan;
    const StructureTiming* best = nullptr;
    for (const StructureTiming& p : row.peers)
      if (p.error.empty() && !p.frame_ms.empty() &&
          (best == nullptr || p.median_frame_ms() < best->median_frame_ms()))
        best = &p;
    md << "| " << row.workload << (row.agree ? "" : " **pairs differ**") << " | "
       << (row.ours.error.empty() ? fmt(ours_ms) : "failed: " + row.ours.error) << " | "
       << (row.ours.error.empty() ? fmt(row.ours.mean_frame_ms()) : "–") << " | " << fmt(ours2)
       << " | ";
    if (w.goal_ratio == 0 && !std::isfinite(w.max_frame_ms) &&
        !std::isfinite(w.max_bytes_per_object)) {
      md << "– | – | – | – | – | – |\n";  // measured, no goal for ours
      continue;
    }
    if (w.goal_ratio == 0) {
      // The million-object row has absolute goals.
      const double n = static_cast<double>(w.n);
      const double bpo = static_cast<double>(row.ours.memory_bytes) / n;
      const double bpo2 =
          std::isfinite(ours2) ? static_cast<double>(row.ours2.memory_bytes) / n : nan;
      const bool met1 = ours_ms <= w.max_frame_ms && bpo <= w.max_bytes_per_object && row.agree;
      const bool met2 = ours2 <= w.max_frame_ms && bpo2 <= w.max_bytes_per_object && row.agree;
      md << "– | – | – | – | ≤ " << fmt(w.max_frame_ms, 0) << " ms, ≤ "
         << fmt(w.max_bytes_per_object, 0) << " B/object (" << fmt(bpo, 0) << " B; 2 threads "
         << fmt(bpo2, 0) << " B) | "
         << (met1   ? "✓"
             : met2 ? "✓ (2 threads)"
                    : "✗")
         << " |\n";
      continue;
    }
    double peer_ms = nan;
    std::string peer_name;
    if (best != nullptr) {
      peer_ms = best->median_frame_ms();
      peer_name = best->spec;
    } else if (std::isfinite(w.issue_peer_ms) && !ctx.quick) {
      peer_ms = w.issue_peer_ms;
      peer_name = "*(issue)*";
    }
    const double ratio = peer_ms / ours_ms;
    const double ratio2 = peer_ms / ours2;
    auto times = [](double v) { return std::isfinite(v) ? fmt(v, 2) + "×" : std::string("–"); };
    const char* met = !std::isfinite(ratio)                             ? "–"
                      : !row.agree                                      ? "✗"
                      : ratio >= w.goal_ratio                           ? "✓"
                      : std::isfinite(ratio2) && ratio2 >= w.goal_ratio ? "✓ (2 threads)"
                                                                        : "✗";
    md << (peer_name.empty() ? "–" : peer_name) << " | " << fmt(peer_ms) << " | " << times(ratio)
       << " | " << times(ratio2) << " | ≥ " << fmt(w.goal_ratio, 0) << "× | " << met << " |\n";
  }
  // The lean path on the same workloads.
  md << "\n**The lean path** (`arrays.hpp`: pairs over the caller's own arrays, one "
        "`PairTracker` call per frame told which objects moved; docs/arrays.md), one thread, on "
        "the same frames as `"
     << ours
     << "` (pair counts and hashes compared frame by frame). A frame is the caller moving its "
        "movers in place plus the call. Bytes per object: the tracker's own (everything it keeps "
        "between calls), and its own plus the caller's columns that it reads.\n\n";
  md << "| workload | arrays ms | mean ms | " << ours << " ms | arrays / " << ours
     << " | own B/object | own + caller B/object | goal | met |\n";
  md << "|---|---:|---:|---:|---:|---:|---:|---|:-:|\n";
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const Row& row = rows[r];
    const Workload& w = workloads[r];
    const StructureTiming& a = row.arrays;
    const double n = static_cast<double>(ctx.quick ? w.n_quick : w.n);
    const bool agree = a.error.empty() && first_disagreement(a, row.ours) < 0;
    if (!a.error.empty()) {
      md << "| " << row.workload << " | failed: " << a.error << " | | | | | | | ✗ |\n";
      continue;
    }
    const double ms = a.median_frame_ms(), ours_ms = row.ours.median_frame_ms();
    const double own = static_cast<double>(a.memory_bytes) / n;
    const double with_caller = static_cast<double>(a.memory_bytes + a.caller_bytes) / n;
    std::string goal;
    bool met = agree;
    auto add_goal = [&](const std::string& text, bool ok) {
      goal += (goal.empty() ? "" : ", ") + text;
      met = met && ok;
    };
    if (std::isfinite(w.arrays_max_frame_ms))
      add_goal("≤ " + fmt(w.arrays_max_frame_ms, 0) + " ms", ms <= w.arrays_max_frame_ms);
    if (std::isfinite(w.arrays_max_bytes_per_object))
      add_goal("≤ " + fmt(w.arrays_max_bytes_per_object, 0) + " B/object",
               own <= w.arrays_max_bytes_per_object);
    if (w.arrays_no_slower) add_goal("≤ " + ours, ms <= ours_ms);
    md << "| " << row.workload << (agree ? "" : " **pairs differ**") << " | " << fmt(ms) << " | "
       << fmt(a.mean_frame_ms()) << " | " << fmt(ours_ms) << " | " << fmt(ms / ours_ms, 2) << " | "
       << fmt(own, 1) << " | " << fmt(with_caller, 1) << " | " << (goal.empty() ? "–" : goal)
       << " | "
       << (goal.empty() ? (agree ? "" : "✗")
           : met        ? "✓"
                        : "✗")
       << " |\n";
  }

  // A short run: the first frames, where work is set up, count.
  md << "\n**A short run**: the mean of the first " << kShortRun
     << " frames from the start, warm-up included (the medians above leave out frames 0 and 1). "
        "The lean path builds on its first call (frame 0), and makes its movers' lists on the "
        "second, the first told which objects moved; `"
     << ours
     << "` is built by inserting the objects, shown on its own and added to the frames. This "
        "process has run other work before; a fresh one also pays for the first touch of every "
        "page (docs/arrays.md).\n\n";
  md << "| workload | arrays: first call ms | second call ms | " << kShortRun
     << " frames, ms a frame | " << ours << ": inserts ms | " << kShortRun
     << " frames, ms a frame | with the inserts, ms a frame |\n";
  md << "|---|---:|---:|---:|---:|---:|---:|\n";
  for (const Row& row : rows) {
    const StructureTiming& a = row.arrays;
    const StructureTiming& o = row.ours;
    if (!a.error.empty() || !o.error.empty() || a.warm_ms.size() < 2) continue;
    const double ours_short = o.first_frames_ms(kShortRun);
    md << "| " << row.workload << " | " << fmt(a.warm_ms[0]) << " | " << fmt(a.warm_ms[1]) << " | "
       << fmt(a.first_frames_ms(kShortRun)) << " | " << fmt(o.build_ms) << " | " << fmt(ours_short)
       << " | " << fmt(ours_short + o.build_ms / static_cast<double>(kShortRun)) << " |\n";
  }

  // The structure `advise` recommends, against the fastest peer.
  const nlohmann::json& ga = g.at("advised");
  const double advised_goal = ga.at("speedup_over_fastest_peer");
  const double advised_quiet = ga.at("quiet_speedup_over_fastest_peer");
  bool any_advised = false;
  for (const Row& row : rows) any_advised = any_advised || !row.advised.spec.empty();
  if (any_advised) {
    md << "\n**Where the lead is thin**: on each kind, the structure that `broadphase advise` "
          "recommends among ours (its default budget of "
       << fmt(ctx.quick ? 1 : kAdviseSeconds, 0)
       << " s, on this scene), timed again as the peers are, against the fastest peer; one "
          "thread. Goal: ≥ "
       << fmt(advised_goal, 0) << "× in every run, ≥ " << fmt(advised_quiet, 1)
       << "× on a quiet machine.\n\n";
    md << "| workload | advise's pick | ms | " << ours
       << " ms | fastest peer | peer ms | speed-up | goal | met |\n";
    md << "|---|---|---:|---:|---|---:|---:|---|:-:|\n";
    for (const Row& row : rows) {
      if (row.advised.spec.empty()) continue;
      const StructureTiming& a = row.advised;
      const StructureTiming* best = nullptr;
      for (const StructureTiming& p : row.peers)
        if (p.error.empty() && !p.frame_ms.empty() &&
            (best == nullptr || p.median_frame_ms() < best->median_frame_ms()))
          best = &p;
      const bool agree = a.error.empty() && first_disagreement(a, row.ours) < 0;
      const double ms = a.error.empty() ? a.median_frame_ms() : nan;
      const double peer_ms = best != nullptr ? best->median_frame_ms() : nan;
      const double ratio = peer_ms / ms;
      md << "| " << row.workload << (agree ? "" : " **pairs differ**") << " | " << a.spec << " | "
         << (a.error.empty() ? fmt(ms) : "failed: " + a.error) << " | "
         << fmt(row.ours.median_frame_ms()) << " | " << (best ? best->spec : "–") << " | "
         << fmt(peer_ms) << " | " << (std::isfinite(ratio) ? fmt(ratio, 2) + "×" : "–") << " | ≥ "
         << fmt(advised_goal, 0) << "× (" << fmt(advised_quiet, 1) << "× quiet) | "
         << (!std::isfinite(ratio)            ? "–"
             : !agree || ratio < advised_goal ? "✗"
             : ratio < advised_quiet          ? "✓ (not the quiet goal)"
                                              : "✓")
         << " |\n";
    }
  }

  const double speedup = one.median_frame_ms() / two.median_frame_ms();
  const double min_speedup = gt.at("min_speedup");
  md << "\n**Threads** (scaled-even " << n_threads
     << ", the middle of three alternated runs each): 1 thread " << fmt(one.median_frame_ms())
     << " ms, 2 threads " << fmt(two.median_frame_ms()) << " ms: " << fmt(speedup, 2)
     << "× (goal ≥ " << fmt(min_speedup, 1) << "×), pair hashes "
     << (same ? "identical" : "**differ**") << ": " << (speedup >= min_speedup && same ? "✓" : "✗")
     << "\n\n";

  if (!rows.empty() && rows.size() > n_micro && rows[n_micro].ours.query_us > 0) {
    const Row& m = rows[n_micro];
    md << "**Micro-timings** on " << m.workload << " (µs per operation, medians of batches; "
       << "insert and remove hold the scene's objects):\n\n";
    md << "| structure | query | insert | remove |\n|---|---:|---:|---:|\n";
    md << "| " << ours << " | " << fmt(m.ours.query_us) << " | " << fmt(m.ours.insert_us) << " | "
       << fmt(m.ours.remove_us) << " |\n";
    const nlohmann::json& gq = g.at("query");
    double best_q = ctx.quick ? nan : gq.at("reference_peer_us").get<double>();
    std::string best_q_name =
        ctx.quick ? "" : "*(issue: " + gq.at("reference_peer").get<std::string>() + ")*";
    for (const StructureTiming& p : m.peers) {
      if (!p.error.empty()) continue;
      md << "| " << p.spec << " | " << fmt(p.query_us) << " | " << fmt(p.insert_us) << " | "
         << fmt(p.remove_us) << " |\n";
      if (best_q_name.empty() || best_q_name[0] == '*' || p.query_us < best_q) {
        best_q = p.query_us;
        best_q_name = p.spec;
      }
    }
    const double q_ratio = best_q / m.ours.query_us;
    const double goal_q = gq.at("speedup_over_fastest_peer");
    const double max_us = g.at("insert_remove_max_us");
    md << "\nQuery: " << fmt(q_ratio, 2) << "× faster than "
       << (best_q_name.empty() ? "–" : best_q_name) << " (goal ≥ " << fmt(goal_q, 0)
       << "×): " << (std::isfinite(q_ratio) ? (q_ratio >= goal_q ? "✓" : "✗") : "–")
       << ". Insert and remove ≤ " << fmt(max_us, 2)
       << " µs: " << (m.ours.insert_us <= max_us && m.ours.remove_us <= max_us ? "✓" : "✗")
       << ".\n";
  }
  return md.str();
}

const RegisterExperiment kRegistered{
    {"performance", 60, "the default structure against every peer on the goals of lab/goals.json",
     lab_performance}};

}  // namespace

}  // namespace broadphase::app
