// Lab section: pictures of the study's two placements (its figures 2.8 and
// 2.9: side and 3D views) and of how the study's structures divide them.
#include <broadphase/scenes/scene.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "draw.hpp"
#include "experiment.hpp"

namespace broadphase::app {

namespace {

std::string lab_pictures(const LabContext& ctx) {
  std::string md = "## Pictures of the workloads\n\n";
  if (plot_python().empty()) return md + "Skipped: python3-matplotlib is not installed.\n";
  const std::filesystem::path dir = ctx.out_dir / "scenes";
  std::filesystem::create_directories(dir);
  // 400 objects: dense enough to show the placement, sparse enough to see.
  constexpr std::size_t kN = 400;
  struct Picture {
    const char* file;
    const char* dist;
    const char* view;
    const char* cells;  // nullptr: the scene only
    const char* caption;
  };
  std::vector<Picture> pictures = {
      {"scene_uneven_side.png", "uneven", "side", nullptr,
       "uneven placement, side view (the study's figure 2.8)"},
      {"cells_octree_paper.png", "uneven", "side", "octree-paper",
       "octree nodes over the uneven placement"},
  };
  if (!ctx.quick) {
    pictures.insert(
        pictures.end(),
        {{"scene_uneven_3d.png", "uneven", "3d", nullptr,
          "uneven placement, 3D view (the study's figure 2.9)"},
         {"scene_even_side.png", "even", "side", nullptr, "even placement, side view"},
         {"scene_even_3d.png", "even", "3d", nullptr, "even placement, 3D view"},
         {"cells_grid.png", "uneven", "side", "grid-dense",
          "uniform grid cells coloured by object count"},
         {"cells_hgrid.png", "uneven", "side", "hgrid-paper", "hierarchical grid levels"}});
  }
  std::string rows;
  int done = 0;
  for (const Picture& p : pictures) {
    if (ctx.progress)
      ctx.progress(std::string("pictures: ") + p.file, static_cast<double>(done) / pictures.size());
    const std::filesystem::path scene = dir / (std::string(p.dist) + "-400.scene");
    if (!std::filesystem::exists(scene))
      write_scene(scene.string(), generate(parse_distribution(p.dist), kN, ctx.seed));
    DrawOptions o;
    o.scene = scene.string();
    o.out = (ctx.out_dir / p.file).string();
    o.view = p.view;
    if (p.cells != nullptr) {
      o.algo = p.cells;
      o.cells = true;
    }
    try {
      draw(o);
      rows += "| ![" + std::string(p.caption) + "](" + p.file + ") | " + p.caption + " |\n";
    } catch (const std::exception& e) {
      rows += "| (not drawn: " + std::string(e.what()) + ") | " + p.caption + " |\n";
    }
    ++done;
  }
  md +=
      "The study's workloads at N = 400 (seed " + std::to_string(ctx.seed) +
      "; moving objects in blue). Drawn by `broadphase draw`.\n\n| picture | what |\n|---|---|\n" +
      rows;
  return md;
}

const RegisterExperiment kRegistered{
    {"pictures", 10, "pictures of the study's workloads and of how its structures divide them",
     lab_pictures}};

}  // namespace

}  // namespace broadphase::app
