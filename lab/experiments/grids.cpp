// The grids' lab experiment: frame time and work per object against the
// cell size of a uniform grid, on the study's even and uneven workloads,
// with the automatic choice marked.
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <broadphase/grid_hashed.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "experiment.hpp"

namespace broadphase::app {

namespace {

struct SweepPoint {
  std::string workload;
  double cell = 0;
  bool automatic = false;
  double frame_ms = 0;    // median over the measured frames
  double tests = 0;       // exact narrow-phase tests per object per frame
  double candidates = 0;  // object pairs sharing a cell, per object
  double cells_per_object = 0;
  double overflow = 0;  // fraction of objects spanning > 2 cells on an axis
};

// The grid's own work, counted from the scene: how many cells each object
// covers and how many object pairs meet in some cell (the candidates the
// grid has to look at, before any bounds test), per object.
void count_work(const Scene& scene, double cell, SweepPoint& p) {
  struct KeyHash {
    std::size_t operator()(const detail::CellKey& k) const { return detail::hash_cell(k); }
  };
  struct KeyEq {
    bool operator()(const detail::CellKey& a, const detail::CellKey& b) const { return a == b; }
  };
  std::unordered_map<detail::CellKey, std::uint64_t, KeyHash, KeyEq> cells;
  const detail::CellMap map({0, 0, 0}, cell);
  std::uint64_t entries = 0, overflow = 0;
  for (const Shape& s : scene.objects) {
    const detail::CellRange r = map.range(bounds_f(s));
    if (r.span(0) > 2 || r.span(1) > 2 || r.span(2) > 2) ++overflow;
    if (r.cells() > 4096) continue;  // counted as overflow; never enumerated
    detail::CellKey k;
    for (k.c[2] = r.lo[2]; k.c[2] <= r.hi[2]; ++k.c[2])
      for (k.c[1] = r.lo[1]; k.c[1] <= r.hi[1]; ++k.c[1])
        for (k.c[0] = r.lo[0]; k.c[0] <= r.hi[0]; ++k.c[0]) {
          ++cells[k];
          ++entries;
        }
  }
  double pairs = 0;
  for (const auto& [k, n] : cells)
    pairs += 0.5 * static_cast<double>(n) * static_cast<double>(n - 1);
  const double n = static_cast<double>(scene.size());
  p.candidates = pairs / n;
  p.cells_per_object = static_cast<double>(entries) / n;
  p.overflow = static_cast<double>(overflow) / n;
}

using broadphase::detail::median;

// Replays `frames` frames through grid-hashed with cell edge `cell` (0:
// automatic); fills time and tests; returns the cell actually used.
double measure(const Scene& scene, double cell, int frames, SweepPoint& p) {
  Config c;
  c.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  c.expected_objects = scene.size();
  if (cell > 0) c.options["cell"] = std::to_string(cell);
  Erased<GridHashed> grid(c);
  Replay replay(grid, scene);
  std::vector<double> ms;
  std::uint64_t tests = 0;
  for (int f = 0; f < frames; ++f) {
    const FrameResult r = replay.next();
    ms.push_back(r.seconds() * 1e3);
    tests += r.tests;
  }
  p.frame_ms = median(ms);
  p.tests = static_cast<double>(tests) / frames / static_cast<double>(scene.size());
  return grid.get().cell_size();
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace

namespace {

std::string lab_cell_size_sweep(const LabContext& ctx) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = ctx.capped(6400);
  const std::vector<double> cells =
      ctx.quick
          ? std::vector<double>{10, 30, 100, 300}
          : std::vector<double>{3, 5, 8, 12, 18, 25, 35, 50, 70, 100, 140, 200, 300, 500, 1000};
  const std::pair<const char*, Distribution> workloads[] = {{"even", Distribution::even},
                                                            {"uneven", Distribution::uneven}};
  // Frames per point: a first point is timed to fit the whole sweep into
  // the budget (a few seconds with --quick).
  const double budget = ctx.quick ? 4.0 : std::max(5.0, ctx.budget_seconds * 0.8);
  int frames = ctx.quick ? 3 : 5;

  std::vector<SweepPoint> points;
  const std::size_t total = 2 * (cells.size() + 1);
  for (const auto& [name, dist] : workloads) {
    const Scene scene = generate(dist, n, ctx.seed);
    for (std::size_t i = 0; i <= cells.size(); ++i) {
      const bool automatic = i == cells.size();
      SweepPoint p;
      p.workload = name;
      p.automatic = automatic;
      if (ctx.progress)
        ctx.progress("cell-size sweep: " + std::string(name) +
                         (automatic ? " automatic" : " cell " + fixed(cells[i], 0)),
                     static_cast<double>(points.size()) / static_cast<double>(total));
      const auto tp = std::chrono::steady_clock::now();
      p.cell = measure(scene, automatic ? 0 : cells[i], frames, p);
      count_work(scene, p.cell, p);
      points.push_back(p);
      const double spent =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const double point =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - tp).count();
      const double left = budget - spent;
      const double remaining = static_cast<double>(total - points.size());
      if (!ctx.quick && remaining > 0 && point > 0)
        frames = static_cast<int>(std::clamp(frames * left / remaining / point, 1.0, 30.0));
    }
  }

  const std::filesystem::path csv = ctx.out_dir / "cell_size_sweep.csv";
  {
    std::ofstream out(csv);
    out << "workload,cell,automatic,frame_ms,tests_per_object,candidates_per_object,"
           "cells_per_object,overflow_fraction\n";
    for (const SweepPoint& p : points)
      out << p.workload << ',' << p.cell << ',' << (p.automatic ? 1 : 0) << ',' << p.frame_ms << ','
          << p.tests << ',' << p.candidates << ',' << p.cells_per_object << ',' << p.overflow
          << '\n';
  }
  const std::filesystem::path fig = ctx.out_dir / "cell_size_sweep";
  const bool plotted = run_plot_script("plot_cellsize.py", {csv.string(), fig.string()});

  std::string md = "## Cell-size sweep\n\n";
  md += "A uniform grid (`grid-hashed` with `cell=`) on the study's even and uneven workloads, " +
        std::to_string(n) +
        " objects (radii 0.5 to 50 in a 1 km cube, 20% moving). Frame time is the median of " +
        "the measured frames (update + all pairs); *candidates* are the object pairs that share "
        "a cell, the grid's own work before any bounds test; *tests* are exact narrow-phase "
        "tests after the float bounds test. *Overflow* is the fraction of objects spanning more "
        "than two cells on an axis (they leave the grid's cells for a slower list). The row "
        "marked **auto** is the cell size the grid chose itself (cell_size.hpp).\n\n";
  md +=
      "| workload | cell | frame ms | candidates / object | tests / object | cells / object | "
      "overflow |\n|---|---:|---:|---:|---:|---:|---:|\n";
  for (const SweepPoint& p : points)
    md += "| " + p.workload + " | " +
          (p.automatic ? "**auto " + fixed(p.cell, 1) + "**" : fixed(p.cell, 0)) + " | " +
          fixed(p.frame_ms, 2) + " | " + fixed(p.candidates, 1) + " | " + fixed(p.tests, 2) +
          " | " + fixed(p.cells_per_object, 1) + " | " + fixed(100 * p.overflow, 0) + "% |\n";
  md +=
      "\nThe three failure modes: **too fine** (left): objects cover many cells or overflow, "
      "and every overflowing object is tested against the others; **too coarse for the "
      "sizes** (right): each cell holds objects far apart, candidates grow with the cell "
      "volume; **too coarse for the density** (uneven, right): the crowded lowest tenth "
      "fills cells ten times faster, so the uneven curve climbs first.\n\n";
  if (plotted) {
    md += "![cell-size sweep](cell_size_sweep.png)\n";
  } else {
    md +=
        "(Figure not drawn: python3 with matplotlib is needed for tools/plot_cellsize.py; "
        "the data is in cell_size_sweep.csv.)\n";
  }
  return md;
}

const RegisterExperiment kRegistered{{"cell-size sweep", 20,
                                      "frame time of the uniform grids against their cell size",
                                      lab_cell_size_sweep}};

}  // namespace

}  // namespace broadphase::app
