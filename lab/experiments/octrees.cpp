// The octree family's experiments: the k-d tree's rebuild policies, the
// adaptive octree's split threshold, and the memory per object of the three
// octrees. Alternatives are replayed side by side, frame by frame, so that
// the machine's noise hits them alike.
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <broadphase/kdtree.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "experiment.hpp"

namespace broadphase::app {

namespace {

using Clock = std::chrono::steady_clock;

using broadphase::detail::median;

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

void report(const LabContext& ctx, const std::string& what, double fraction) {
  if (ctx.progress) ctx.progress(what, fraction);
}

// One structure replaying one scene.
struct Runner {
  std::string spec;
  std::unique_ptr<AnyBroadPhase> bp;
  std::unique_ptr<Replay> replay;
  std::vector<double> frame_ms;
  double total_ms = 0;
  FrameDigest total;
};

Runner make_runner(const std::string& spec, const Scene& scene) {
  Config config;
  config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  config.expected_objects = scene.size();
  Runner r{spec, make_structure(spec, config), nullptr, {}, 0, {}};
  r.replay = std::make_unique<Replay>(*r.bp, scene);
  return r;
}

// Replays every runner for up to `frames` frames, round-robin, stopping
// early when `seconds` have passed. Returns the frames done.
int run_side_by_side(std::vector<Runner>& runners, int frames, double seconds) {
  const auto t0 = Clock::now();
  int f = 0;
  for (; f < frames; ++f) {
    if (f > 0 && std::chrono::duration<double>(Clock::now() - t0).count() > seconds) break;
    for (Runner& r : runners) {
      const FrameResult fr = r.replay->next();
      r.frame_ms.push_back(fr.seconds() * 1e3);
      r.total_ms += fr.seconds() * 1e3;
      r.total.pairs += fr.digest.pairs;
      r.total.hash += fr.digest.hash;
    }
  }
  return f;
}

bool agree(const std::vector<Runner>& runners) {
  for (const Runner& r : runners)
    if (!(r.total == runners.front().total)) return false;
  return true;
}

std::string rebuild_policies(const LabContext& ctx, double seconds) {
  const std::size_t n = ctx.capped(ctx.quick ? 1600 : 6400);
  const int frames = ctx.quick ? 60 : 300;
  std::ostringstream md;
  std::ofstream csv(ctx.out_dir / "octrees_kdtree_rebuild.csv");
  csv << "dist,n,policy,frames,median_frame_ms,total_ms,rebuilds\n";
  md << "### k-d tree: refit only, rebuild on decay, rebuild every frame\n\n"
     << "Median and total frame time (update + all pairs) over the same frames, " << n
     << " objects, replayed side by side. Rebuilds count the whole run, loading included "
        "(about log2(n / 8) of them happen while the objects are inserted).\n\n"
     << "| scene | policy | frames | median ms | total ms | vs decay | rebuilds |\n"
     << "|---|---|---:|---:|---:|---:|---:|\n";
  const char* policies[] = {"kdtree:rebuild=refit", "kdtree:rebuild=decay",
                            "kdtree:rebuild=always"};
  const Distribution dists[] = {Distribution::even, Distribution::uneven};
  for (int di = 0; di < 2; ++di) {
    report(ctx, "octrees: k-d tree rebuild policies", di / 2.0);
    const Scene scene = generate(dists[di], n, ctx.seed);
    std::vector<Runner> runners;
    for (const char* p : policies) runners.push_back(make_runner(p, scene));
    const int done = run_side_by_side(runners, frames, seconds / 2);
    const double ref = median(runners[1].frame_ms);
    for (const Runner& r : runners) {
      const double med = median(r.frame_ms);
      const auto* kd = dynamic_cast<const Erased<KdTree>*>(r.bp.get());
      const std::uint64_t rebuilds = kd != nullptr ? kd->get().rebuilds() : 0;
      csv << to_string(dists[di]) << ',' << n << ',' << r.spec << ',' << done << ',' << med << ','
          << r.total_ms << ',' << rebuilds << "\n";
      md << "| " << to_string(dists[di]) << " | `" << r.spec << "` | " << done << " | "
         << fixed(med, 3) << " | " << fixed(r.total_ms, 1) << " | "
         << fixed(ref > 0 ? med / ref : 0, 2) << "x | " << rebuilds << " |\n";
    }
    if (!agree(runners)) md << "\n**The policies disagree on the pairs: a bug.**\n";
  }
  md << "\n";
  return md.str();
}

std::string split_sweep(const LabContext& ctx, double seconds) {
  const std::size_t n = ctx.capped(ctx.quick ? 1600 : 6400);
  const int frames = ctx.quick ? 20 : 100;
  const int thresholds[] = {1, 2, 4, 8, 16, 32, 64, 128};
  std::ostringstream md;
  std::ofstream csv(ctx.out_dir / "octrees_split_sweep.csv");
  csv << "dist,n,split,frames,median_frame_ms,tests_per_frame\n";
  md << "### Adaptive octree: split threshold\n\n"
     << "Median frame time of `octree:split=S`, " << n
     << " objects, all thresholds replayed side by side.\n\n| scene |";
  for (int s : thresholds) md << " " << s << " |";
  md << "\n|---|";
  for (std::size_t i = 0; i < std::size(thresholds); ++i) md << "---:|";
  md << "\n";
  const Distribution dists[] = {Distribution::even, Distribution::uneven};
  for (int di = 0; di < 2; ++di) {
    report(ctx, "octrees: split threshold sweep", di / 2.0);
    const Scene scene = generate(dists[di], n, ctx.seed);
    std::vector<Runner> runners;
    for (int s : thresholds)
      runners.push_back(make_runner("octree:split=" + std::to_string(s), scene));
    const int done = run_side_by_side(runners, frames, seconds / 2);
    md << "| " << to_string(dists[di]) << " |";
    for (std::size_t i = 0; i < runners.size(); ++i) {
      const double med = median(runners[i].frame_ms);
      csv << to_string(dists[di]) << ',' << n << ',' << thresholds[i] << ',' << done << ',' << med
          << ",\n";
      md << " " << fixed(med, 2) << " |";
    }
    md << "\n";
    if (!agree(runners)) md << "\n**The thresholds disagree on the pairs: a bug.**\n";
  }
  md << "\n";
  return md.str();
}

std::string memory_per_object(const LabContext& ctx) {
  const std::size_t n = ctx.capped(ctx.quick ? 1600 : 6400);
  const char* specs[] = {"octree", "octree-loose", "octree-linear", "kdtree", "naive"};
  std::ostringstream md;
  std::ofstream csv(ctx.out_dir / "octrees_memory.csv");
  csv << "dist,n,structure,memory_bytes,bytes_per_object\n";
  md << "### Memory per object\n\n"
     << "`memory_bytes()` after inserting " << n
     << " objects, divided by n. Every structure also keeps the same object store (shape, "
        "user data, generation: about 80 bytes per object); `naive` is that store plus two "
        "index arrays, so the difference to `naive` is what the tree itself costs.\n\n"
     << "| scene | structure | bytes/object | tree only (minus naive) |\n|---|---|---:|---:|\n";
  for (Distribution d : {Distribution::even, Distribution::uneven, Distribution::clusters}) {
    const Scene scene = generate(d, n, ctx.seed);
    double naive_per = 0;
    std::vector<std::pair<std::string, double>> rows;
    for (const char* spec : specs) {
      Runner r = make_runner(spec, scene);
      const double per = static_cast<double>(r.bp->memory_bytes()) / static_cast<double>(n);
      if (std::string(spec) == "naive") naive_per = per;
      rows.emplace_back(spec, per);
      csv << to_string(d) << ',' << n << ',' << spec << ',' << r.bp->memory_bytes() << ',' << per
          << '\n';
    }
    for (const auto& [spec, per] : rows)
      if (spec != "naive")
        md << "| " << to_string(d) << " | `" << spec << "` | " << fixed(per, 1) << " | "
           << fixed(per - naive_per, 1) << " |\n";
  }
  md << "\n";
  return md.str();
}

}  // namespace

namespace {

std::string lab_octree_experiments(const LabContext& ctx) {
  const double budget = ctx.quick ? 6 : ctx.budget_seconds;
  std::string md = "## Octrees and the k-d tree\n\n";
  md +=
      "Machine notes apply: frame times are wall-clock medians on whatever the machine was "
      "doing; compare rows of one table (run side by side), not tables of different runs.\n\n";
  md += rebuild_policies(ctx, budget * 0.45);
  md += split_sweep(ctx, budget * 0.45);
  report(ctx, "octrees: memory per object", 0.9);
  md += memory_per_object(ctx);
  report(ctx, "octrees: done", 1.0);
  md += "CSV: `octrees_kdtree_rebuild.csv`, `octrees_split_sweep.csv`, `octrees_memory.csv`.\n";
  return md;
}

const RegisterExperiment kRegistered{
    {"octree experiments", 40, "the octrees' split threshold, memory and the k-d tree's rebuilds",
     lab_octree_experiments}};

}  // namespace

}  // namespace broadphase::app
