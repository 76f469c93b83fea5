// The CLI's subcommands. Each lives in its own file and adds itself to the
// CLI11 app; `main.cpp` only wires them together and reports errors.
#pragma once

#include <broadphase/registry.hpp>
#include <stdexcept>
#include <string>

// (CLI11 is declared, not included: its header is about 12 s of every
// compile that includes it, and the lab's files that include this one for
// registry() and UsageError use none of it. A file that adds a command
// includes <CLI/CLI.hpp> itself.)
namespace CLI {
class App;
}  // namespace CLI

namespace broadphase::app {

/// Every library structure plus the peer adapters that were built.
const Registry& registry();

/// An error in what the user asked for: printed without a stack of causes,
/// exit status 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What `broadphase draw` draws (see its --help for each field).
struct DrawOptions {
  std::string scene;
  std::string out;
  std::string view = "side";
  std::string algo = "naive";
  bool cells = false;
  int sim_frames = 0;
  bool gif = false;
  bool compare = false;
  std::string ccd = "off";
  double restitution = 1;
  std::string title;
  std::string data;  ///< when set: write the drawing's JSON here instead of rendering it
};

/// Renders one picture through tools/draw.py. Throws UsageError for bad
/// options and std::runtime_error when no picture could be written.
void draw(const DrawOptions& o);  // lab/draw.cpp

void add_list_command(CLI::App& app);    // cmd_run.cpp
void add_run_command(CLI::App& app);     // cmd_run.cpp
void add_gen_command(CLI::App& app);     // cmd_run.cpp
void add_paper_command(CLI::App& app);   // lab/paper.cpp (the lab)
void add_sim_command(CLI::App& app);     // cmd_sim.cpp
void add_draw_command(CLI::App& app);    // lab/draw.cpp
void add_advise_command(CLI::App& app);  // cmd_advise.cpp

/// `run --arrays`: replays a scene through PairTracker (arrays.hpp) and
/// prints what `run` prints. Throws SceneError as `run` does.
void run_arrays(const std::string& scene, int frames, bool json);  // run_arrays.cpp

}  // namespace broadphase::app
