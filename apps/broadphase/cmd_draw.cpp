#include "commands.hpp"

namespace broadphase::app {

void add_draw_command(CLI::App& app) {
  app.add_subcommand("draw", "(not yet available)")->callback([] {
    throw UsageError("'draw' is not available in this build yet");
  });
}

}  // namespace broadphase::app
