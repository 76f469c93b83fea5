// Runs the lab's ray experiment alone (the "Rays" section of `broadphase
// paper`, lab/experiments/rays.cpp), for quick iteration on its sizes:
//   rays_lab [--quick] [--budget S] [--out DIR] [--seed S] [--sizes 1000,100000]
//            [--kinds uniform,city] [--rays N] [--no-layers]
//            [--structures hgrid,sap]  (measured beside the default)
// Writes rays.csv, layers.csv, the figure and section.md into DIR (default
// the current folder); progress on stderr.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "experiments/rays.hpp"

namespace {

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string part; std::getline(in, part, ',');)
    if (!part.empty()) out.push_back(part);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace broadphase::app;
  LabContext ctx;
  ctx.out_dir = ".";
  RaysOptions options;
  bool budget_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "rays_lab: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--quick") {
      ctx.quick = true;
    } else if (a == "--budget") {
      ctx.budget_seconds = std::stod(value());
      budget_given = true;
    } else if (a == "--out") {
      ctx.out_dir = value();
    } else if (a == "--seed") {
      ctx.seed = std::stoull(value());
    } else if (a == "--sizes") {
      for (const std::string& s : split(value())) options.sizes.push_back(std::stoull(s));
    } else if (a == "--kinds") {
      options.kinds = split(value());
    } else if (a == "--rays") {
      options.rays = std::stoull(value());
    } else if (a == "--structures") {
      options.structures = split(value());
    } else if (a == "--no-layers") {
      options.layers = false;
    } else {
      std::fprintf(stderr, "rays_lab: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (!budget_given) ctx.budget_seconds = ctx.quick ? 10 : 300;
  // The CSVs are written before the section: the directory first.
  std::error_code made;
  std::filesystem::create_directories(ctx.out_dir, made);
  if (made) {
    std::fprintf(stderr, "rays_lab: cannot create %s: %s\n", ctx.out_dir.string().c_str(),
                 made.message().c_str());
    return 2;
  }
  const auto start = std::chrono::steady_clock::now();
  ctx.progress = [start](const std::string& what, double fraction) {
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::fprintf(stderr, "%7.2f s [%3.0f%%] %s\n", s, 100 * fraction, what.c_str());
  };
  const std::string md = lab_rays_with(ctx, options);
  run_plot_script("plot_paper.py",
                  {"--rays", (ctx.out_dir / "rays.csv").string(), "--out", ctx.out_dir.string()});
  std::ofstream(ctx.out_dir / "section.md") << md;
  std::cout << md;
  return 0;
}
