// The lab's ray experiment (rays.cpp) with its sizes open, for the program
// that runs it alone (bench/rays/rays_lab.cpp): `broadphase paper` runs it
// with the defaults.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lab.hpp"

namespace broadphase::app {

/// What the ray experiment runs; empty lists take the defaults.
struct RaysOptions {
  /// Object counts (default 10^3 .. 10^6; --quick: 300 and 1000).
  std::vector<std::size_t> sizes;
  /// Scene kinds by label ("uniform", "clustered", "boxes", "mixed", "city").
  std::vector<std::string> kinds;
  /// Rays per set (default 10^5; --quick 500).
  std::size_t rays = 0;
  bool layers = true;  ///< also the layers part
  /// Further structures (registry specs) measured in every cell beside the
  /// default, each in its own column (rays_lab --structures).
  std::vector<std::string> structures;
};

/// Runs the ray experiment; returns its section of REPORT.md, having written
/// rays.csv and layers.csv into ctx.out_dir
/// (the figure is drawn from rays.csv by tools/plot_paper.py).
std::string lab_rays_with(const LabContext& ctx, const RaysOptions& options);

}  // namespace broadphase::app
