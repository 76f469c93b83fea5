// `draw`: the command line of the lab's drawing (lab/draw.cpp): pictures of
// a scene, of a structure's cells, or of a simulation.
#include <CLI/CLI.hpp>
#include <memory>

#include "commands.hpp"
#include "draw.hpp"

namespace broadphase::app {

void add_draw_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "draw",
      "Draw a scene, a structure's cells, or a simulation (PNG, SVG or GIF via matplotlib)");
  auto o = std::make_shared<DrawOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (docs/scene-format.md)")->required();
  cmd->add_option("--out", o->out, "Picture to write: .png or .svg (.gif with --gif)")->required();
  cmd->add_option("--view", o->view, "side (x, y: y is up) | top (x, z) | 3d")->default_val("side");
  cmd->add_option("--algo", o->algo,
                  "Structure (with options: octree:split=16) whose cells or nodes --cells "
                  "draws as it builds them over the scene; also the broad phase of --sim")
      ->default_val("naive");
  cmd->add_flag("--cells", o->cells, "Overlay the cells or nodes of --algo");
  cmd->add_option("--sim", o->sim_frames, "Simulate FRAMES steps and draw a strip of them")
      ->check(CLI::Range(1, 100000));
  cmd->add_flag("--gif", o->gif, "With --sim: an animated GIF instead of a strip");
  cmd->add_flag("--compare", o->compare,
                "With --sim: trails with --ccd off beside trails with the remedy (--ccd, "
                "default swept)");
  cmd->add_option("--ccd", o->ccd, "off | substep | swept")->default_val("off");
  cmd->add_option("--restitution", o->restitution, "k in [0, 1] for --sim")
      ->default_val(1)
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--title", o->title, "Title of the picture (a default names the scene)");
  cmd->add_option("--data", o->data,
                  "Write what would be drawn as JSON to this file instead of drawing it "
                  "(render it later with tools/draw.py FILE)");
  cmd->callback([o] { draw(*o); });
}

}  // namespace broadphase::app
