#include "commands.hpp"

namespace broadphase::app {

void add_sim_command(CLI::App& app) {
  app.add_subcommand("sim", "(not yet available)")->callback([] {
    throw UsageError("'sim' is not available in this build yet");
  });
}

}  // namespace broadphase::app
