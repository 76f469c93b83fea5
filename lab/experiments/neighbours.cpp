// Lab experiment: what particle and point-cloud codes ask of the library
// besides pairs (docs/neighbours.md, docs/knn.md). A periodic neighbour list
// at liquid density, one-shot on one and two threads and kept over the
// frames of a moving system; and the k nearest neighbours of points queried
// by themselves against nanoflann's k-d tree (libnanoflann-dev, when the
// build found it). The Python peers (cKDTree, MDAnalysis, ASE, pykdtree)
// are measured by python/bench/neighbours.py and python/bench/knn.py.
#include <algorithm>
#include <broadphase/knn.hpp>
#include <broadphase/moving_neighbours.hpp>
#include <broadphase/neighbours.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "experiment.hpp"
#include "knn_peer.hpp"

namespace broadphase::app {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

/// Runs `call` up to `runs` times (at least once), stopping when `seconds`
/// have passed; the median wall time.
template <class F>
double timed(int runs, double seconds, F&& call) {
  std::vector<double> t;
  const auto start = Clock::now();
  for (int r = 0; r < runs; ++r) {
    const auto t0 = Clock::now();
    call();
    t.push_back(since(t0));
    if (since(start) > seconds) break;
  }
  return median_of(t);
}

bool same_list(const NeighbourList& a, const NeighbourList& b) {
  return a.first == b.first && a.second == b.second && a.shifts == b.shifts;
}

/// One line of neighbours.csv and of the section's tables.
struct Row {
  std::string part, set;
  std::size_t n = 0, k = 0, pairs = 0;
  unsigned threads = 1;
  double ours_s = 0;
  std::string peer;
  double peer_s = 0;
  std::string check;
};

Row row(std::string part, std::string set, std::size_t n, std::size_t k, unsigned threads) {
  Row r;
  r.part = std::move(part);
  r.set = std::move(set);
  r.n = n;
  r.k = k;
  r.threads = threads;
  return r;
}

std::vector<Row> measure_lists(std::size_t n, int frames, std::uint64_t seed, double share,
                               int runs) {
  const double side = std::cbrt(static_cast<double>(n) / 0.1);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, side);
  std::normal_distribution<double> g(0, 1);
  std::vector<double> x(3 * n), v(3 * n);
  for (double& a : x) a = u(rng);
  const double step = 0.015;  // Å a frame per axis, as python/bench/neighbours.py
  for (double& a : v) a = step * g(rng);
  const NeighbourCell cell = NeighbourCell::orthorhombic({side, side, side});
  NeighbourOptions opt;
  opt.rule = CutoffRule::strict;
  const auto points = NeighbourPoints::rows(x.data(), n);
  std::vector<Row> rows;
  NeighbourList one;
  for (const unsigned threads : {1u, 2u}) {
    opt.threads = threads;
    NeighbourList l;
    Row r = row("neighbour list", "cube", n, 0, threads);
    r.ours_s = timed(runs, share / 8, [&] { l = neighbour_list(points, cell, 3.0, opt); });
    r.pairs = l.size();
    if (threads == 1) {
      one = std::move(l);
    } else {
      r.check = same_list(l, one) ? "the one-thread list" : "DIFFERS from one thread";
    }
    rows.push_back(r);
  }
  // The moving list over `frames` frames of thermal-like motion, against
  // the one-shot list on every frame (timed on each, and compared).
  for (const unsigned threads : {1u, 2u}) {
    opt.threads = threads;
    std::vector<double> y = x, w = v;
    std::mt19937_64 walk(seed + 1);
    MovingNeighbourList moving(cell, 3.0, -1, opt);
    double total = 0;
    std::vector<double> rebuild;
    bool same = true;
    int done = 0;
    const auto start = Clock::now();
    for (; done < frames; ++done) {
      if (done > 0)
        for (std::size_t i = 0; i < 3 * n; ++i) {
          w[i] = 0.9 * w[i] + 0.44 * step * g(walk);
          y[i] += w[i];
          y[i] -= side * std::floor(y[i] / side);
        }
      const auto pts = NeighbourPoints::rows(y.data(), n);
      auto t0 = Clock::now();
      const NeighbourList got = moving.update(pts);
      total += since(t0);
      t0 = Clock::now();
      const NeighbourList want = neighbour_list(pts, cell, 3.0, opt);
      rebuild.push_back(since(t0));
      same = same && same_list(got, want);
      if (done >= 2 && since(start) > share / 3) {
        ++done;
        break;
      }
    }
    Row r = row("moving list, " + std::to_string(done) + " frames", "cube", n, 0, threads);
    r.ours_s = total / done;
    r.peer = "one-shot list each frame";
    r.peer_s = median_of(rebuild);
    r.pairs = one.size();
    r.check = (same ? "the one-shot list on every frame; " : "DIFFERS from the one-shot list; ") +
              std::to_string(moving.rebuilds()) + " rebuilds";
    rows.push_back(r);
  }
  return rows;
}

/// knn of `small` points, k = 1, 8 and 32, uniform and clustered; then, when
/// `big` is not 0, k = 8 on `big` uniform points (the size the issue's
/// target names, where nanoflann's tree no longer fits the caches).
std::vector<Row> measure_knn(std::size_t small, std::size_t big, std::uint64_t seed, double share,
                             int runs) {
  struct Case {
    bool clustered;
    std::size_t n;
    std::vector<std::size_t> ks;
  };
  std::vector<Case> cases = {{false, small, {1, 8, 32}}, {true, small, {1, 8, 32}}};
  if (big != 0) cases.push_back({false, big, {8}});
  std::vector<Row> rows;
  for (const Case& c : cases) {
    const bool clustered = c.clustered;
    const std::size_t n = c.n;
    const std::vector<double> xyz = knn_points(clustered, n, seed);
    const Points pts = Points::rows(xyz.data(), n);
    for (const std::size_t k : c.ks) {
      Row r = row("knn", clustered ? "clustered" : "uniform", n, k, 1);
      std::vector<double> d2(n * k);
      std::vector<std::int64_t> index(n * k);
      r.ours_s = timed(runs, share / 14, [&] {
        const KnnIndex grid(pts);
        grid.knn_self(k, false, d2, index, 1);
      });
#if defined(BROADPHASE_HAVE_NANOFLANN)
      std::vector<double> nd2(n * k);
      std::vector<std::uint32_t> nindex(n * k);
      r.peer = "nanoflann k-d tree";
      r.peer_s = timed(runs, share / 14, [&] {
        const NanoflannCloud cloud{&xyz};
        NanoflannTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
        tree.buildIndex();
        for (std::size_t i = 0; i < n; ++i)
          tree.knnSearch(&xyz[3 * i], k, &nindex[i * k], &nd2[i * k]);
      });
      std::size_t equal = 0;
      for (std::size_t i = 0; i < n; ++i) equal += d2[i * k + k - 1] == nd2[i * k + k - 1];
      char text[96];
      std::snprintf(text, sizeof text, "k-th distances equal for %.2f %% of the points",
                    100.0 * static_cast<double>(equal) / static_cast<double>(n));
      r.check = text;
#endif
      rows.push_back(r);
    }
  }
  return rows;
}

std::string lab_neighbours(const LabContext& ctx) {
  const std::size_t n_lists = ctx.capped(ctx.quick ? 3000 : 200000);
  const std::size_t n_knn = ctx.capped(ctx.quick ? 3000 : 200000);
  const double budget = ctx.quick ? std::min(ctx.budget_seconds, 3.0) : ctx.budget_seconds;
  const int runs = ctx.quick ? 1 : 5;
  if (ctx.progress) ctx.progress("neighbour lists", 0.0);
  std::vector<Row> rows = measure_lists(n_lists, ctx.quick ? 4 : 50, ctx.seed, budget / 2, runs);
  if (ctx.progress) ctx.progress("knn", 0.5);
  const std::size_t n_big = ctx.quick ? 0 : ctx.capped(1000000);
  for (Row& r : measure_knn(n_knn, n_big == n_knn ? 0 : n_big, ctx.seed, budget / 2, runs))
    rows.push_back(std::move(r));

  std::ofstream csv(ctx.out_dir / "neighbours.csv");
  csv << "part,set,n,k,threads,pairs,ours_s,peer,peer_s,check\n";
  std::string md =
      "## Neighbour lists and nearest neighbours\n\n"
      "A periodic neighbour list of points uniform in a cube at 0.1 a unit volume, cutoff 3 "
      "(half list with shifts, `<` at the cutoff; docs/neighbours.md): one-shot on one and on "
      "two threads (`NeighbourOptions::threads`), and the moving list with the default skin over "
      "frames of thermal-like motion (0.015 a frame per axis, wrapped; its mean time a frame, "
      "rebuilds included) against the one-shot list on each frame. Then the k nearest neighbours "
      "of points queried by themselves, uniform in the unit cube and in 1 000 blobs, one thread, "
      "build included (docs/knn.md), against nanoflann's k-d tree where the build found it; and "
      "k = 8 on 10^6 uniform points, where nanoflann's tree no longer fits the caches. Wall "
      "times, medians (one run each where the budget is short). Python's peers (cKDTree, "
      "MDAnalysis, ASE, pykdtree): "
      "python/bench/neighbours.py and python/bench/knn.py.\n\n"
      "| what | points | k | threads | pairs | ours s | against | its s | × | checked |\n"
      "|---|---|---:|---:|---:|---:|---|---:|---:|---|\n";
  for (const Row& r : rows) {
    char line[512];
    std::snprintf(line, sizeof line, "%s,%s,%zu,%zu,%u,%zu,%.6f,%s,%.6f,%s\n", r.part.c_str(),
                  r.set.c_str(), r.n, r.k, r.threads, r.pairs, r.ours_s, r.peer.c_str(), r.peer_s,
                  r.check.c_str());
    csv << line;
    char ratio[32] = "—", peer_s[32] = "—";
    if (r.peer_s > 0 && r.ours_s > 0) {
      std::snprintf(ratio, sizeof ratio, "%.2f", r.peer_s / r.ours_s);
      std::snprintf(peer_s, sizeof peer_s, "%.4g", r.peer_s);
    }
    const std::string k = r.k ? std::to_string(r.k) : "";
    const std::string pairs = r.pairs ? std::to_string(r.pairs) : "";
    std::snprintf(line, sizeof line, "| %s | %zu %s | %s | %u | %s | %.4g | %s | %s | %s | %s |\n",
                  r.part.c_str(), r.n, r.set.c_str(), k.c_str(), r.threads, pairs.c_str(), r.ours_s,
                  r.peer.empty() ? "—" : r.peer.c_str(), peer_s, ratio, r.check.c_str());
    md += line;
  }
#if !defined(BROADPHASE_HAVE_NANOFLANN)
  md +=
      "\nnanoflann was not found when the lab was built (libnanoflann-dev): knn is timed "
      "alone.\n";
#endif
  md += "\nData: `neighbours.csv`.\n";
  if (ctx.progress) ctx.progress("neighbours", 1.0);
  return md;
}

const RegisterExperiment kRegistered{
    {"neighbours", 70,
     "periodic neighbour lists (one-shot, threads, moving) and knn against nanoflann",
     lab_neighbours,
     // About 10 s of a full run's budget on the 2-core hosts: a third of
     // the smallest experiment's share.
     0.3}};

}  // namespace

}  // namespace broadphase::app
