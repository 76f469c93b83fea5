#include "commands.hpp"

namespace broadphase::app {

void add_paper_command(CLI::App& app) {
  app.add_subcommand("paper", "(not yet available)")->callback([] {
    throw UsageError("'paper' is not available in this build yet");
  });
}

}  // namespace broadphase::app
