#include "commands.hpp"

namespace broadphase::app {

void add_advise_command(CLI::App& app) {
  app.add_subcommand("advise", "(not yet available)")->callback([] {
    throw UsageError("'advise' is not available in this build yet");
  });
}

}  // namespace broadphase::app
