// The CLI's subcommands. Each lives in its own file and adds itself to the
// CLI11 app; `main.cpp` only wires them together and reports errors.
#pragma once

#include <broadphase/registry.hpp>
#include <string>

// What the commands share with the lab (lab/, a library below the CLI):
// the structures by name, registry(), and UsageError.
#include "structures.hpp"
#include "usage_error.hpp"

// (CLI11 is declared, not included: its header is about 12 s of every
// compile that includes it. A file that adds a command includes
// <CLI/CLI.hpp> itself.)
namespace CLI {
class App;
}  // namespace CLI

namespace broadphase::app {

void add_list_command(CLI::App& app);    // cmd_run.cpp
void add_run_command(CLI::App& app);     // cmd_run.cpp
void add_gen_command(CLI::App& app);     // cmd_run.cpp
void add_paper_command(CLI::App& app);   // cmd_paper.cpp (the lab: lab/paper.cpp)
void add_sim_command(CLI::App& app);     // cmd_sim.cpp
void add_draw_command(CLI::App& app);    // cmd_draw.cpp (lab/draw.cpp)
void add_advise_command(CLI::App& app);  // cmd_advise.cpp

/// `run --arrays`: replays a scene through PairTracker (arrays.hpp) and
/// prints what `run` prints. Throws SceneError as `run` does.
void run_arrays(const std::string& scene, int frames, bool json);  // run_arrays.cpp

}  // namespace broadphase::app
